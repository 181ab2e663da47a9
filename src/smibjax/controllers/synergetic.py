"""`aftsc` / `asc`: the paper's adaptive synergetic law as a controller.

The law itself (eqs. 21-22, 36-37, in the paper's coordinates) is in
`smibjax.controller`; this module makes it a controller of the closed loop, with its
two options (both off by default, MODEL.md section 2):

- weighted macro-variables phi_i = c_i e1 + e2 + beta_i e_(i+2): `Gains.c1`, `c2`;
- a smooth projection of the estimates onto a known box [th_min, th_max]
  (`EstimateBox`), the standard anti-windup of adaptive control.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._validate import ParameterError, is_concrete
from ..controller import adaptation_rate, control_law, static_alpha
from ..parameters import GAIN_NAMES, Gains, _f
from .base import AbstractController, ControllerOutput

__all__ = ["EstimateBox", "Synergetic", "project", "GAIN_KINDS"]

# The tuner's transforms of the synergetic gains (tuning/params.py).
GAIN_KINDS = {
    "beta1": "inverse",
    "beta2": "inverse",
    "T1": "log",
    "T2": "log",
    "alpha": "alpha",
    "gamma1": "log",
    "gamma2": "log",
    "k1": "softplus",
    "k2": "softplus",
    "c1": "log",
    "c2": "log",
}
assert tuple(GAIN_KINDS) == GAIN_NAMES


class EstimateBox(eqx.Module):
    """The known box of theta = (-D, Pm): th1 in [th1_min, th1_max] and th2 in
    [th2_min, th2_max] (pu). `layer` (a fraction of each half-width) is the boundary
    layer in which the projection phases in."""

    lo: Float[Array, 2] = eqx.field(converter=_f)
    hi: Float[Array, 2] = eqx.field(converter=_f)
    layer: float = eqx.field(static=True, default=0.1)

    def __check_init__(self):
        if not is_concrete(self.lo, self.hi):
            return
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        if lo.shape[-1:] != (2,) or hi.shape[-1:] != (2,):
            raise ParameterError("projection box must give [lo, hi] for th1 and th2")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ParameterError(
                f"projection box lo = {lo.tolist()}, hi = {hi.tolist()} is not "
                "allowed: must be finite"
            )
        if not np.all(lo < hi):
            raise ParameterError(
                f"projection box lo = {lo.tolist()}, hi = {hi.tolist()} is not "
                "allowed: empty (each lo must be < hi)"
            )
        if not 0 < self.layer <= 1:
            raise ParameterError(
                f"projection layer = {self.layer:g} is not allowed: must be in (0, 1]"
            )

    def contains(self, th) -> bool:
        """True when the concrete estimates `th` lie in the box."""
        th = np.asarray(th)
        return bool(np.all((th >= np.asarray(self.lo)) & (th <= np.asarray(self.hi))))


def project(
    th: Float[Array, 2], rate: Float[Array, 2], box: EstimateBox
) -> Float[Array, 2]:
    """Smooth projection of the estimate rate onto `box` (per component):
    rate (1 - w) where the rate points outwards, rate elsewhere, with w rising from 0
    to 1 (smoothstep, C1) across the boundary layer just inside the box. At the
    boundary w = 1: no estimate leaves the box, and inside the layer-free interior
    the law is unchanged. Continuous and Lipschitz in (th, rate), so the closed loop
    stays differentiable."""
    c = 0.5 * (box.lo + box.hi)
    r = 0.5 * (box.hi - box.lo)
    rho = jnp.clip((jnp.abs(th - c) - (1 - box.layer) * r) / (box.layer * r), 0.0, 1.0)
    w = rho * rho * (3 - 2 * rho)
    outward = rate * (th - c) > 0
    return jnp.where(outward, rate * (1 - w), rate)


class Synergetic(AbstractController):
    """The adaptive synergetic controller: AFTSC for alpha < 1, ASC for alpha = 1.

    `oracle`: the paper's update law, whose k-terms read the true theta (True), or the
    realizable certainty-equivalence law without them (False). `projection`: an
    `EstimateBox` (None: no projection, the paper). `phi_layer` (units of phi): the
    boundary-layer width of the evolution law (`smibjax.controller.evolution`; 0, the
    default: the exact finite-time law).
    """

    gains: Gains
    oracle: bool = eqx.field(static=True, default=True)
    projection: EstimateBox | None = None
    phi_layer: float = eqx.field(static=True, default=0.0)

    def __check_init__(self):
        v = self.phi_layer
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise ParameterError(
                f"phi_layer = {v!r} is not allowed: must be a finite number >= 0 "
                "(0: the exact finite-time law)"
            )

    n_internal = 2
    has_estimates = True
    angle_range = (0.0, math.pi)  # cot x1 and 1/g31 are singular at 0 and pi
    diagnostic_names = ("phi1", "phi2")

    @classmethod
    def parameter_kinds(cls) -> dict[str, str]:
        return dict(GAIN_KINDS)

    @classmethod
    def from_options(
        cls, gains: Gains, adaptation: str = "oracle", options: dict | None = None
    ) -> Synergetic:
        """The controller with `gains`, the `adaptation` mode ("oracle" or
        "realizable") and the options of a gains file or Monte Carlo spec:
        `projection` ([[th1_min, th1_max], [th2_min, th2_max]]; [] or absent: off) and
        `phi_layer` (absent: 0, the exact law)."""
        options = options or {}
        box = options.get("projection") or []
        return cls(
            gains,
            oracle=adaptation != "realizable",
            projection=EstimateBox(*zip(*box, strict=True)) if box else None,
            phi_layer=float(options.get("phi_layer", 0.0)),
        )

    def with_static_alpha(self, alpha_one: bool | None = None) -> Synergetic:
        """The same controller with alpha compiled as the constant 1 where it is 1
        (`smibjax.controller.static_alpha`)."""
        gains = static_alpha(self.gains, alpha_one)
        return Synergetic(gains, self.oracle, self.projection, self.phi_layer)

    def parameters(self) -> dict[str, float]:
        return {n: float(getattr(self.gains, n)) for n in GAIN_NAMES}

    def tunable(self) -> Gains:
        """The gains; adaptation mode, projection box and boundary layer are
        structure."""
        return self.gains

    def with_tunable(self, tunable: Gains) -> Synergetic:
        return Synergetic(tunable, self.oracle, self.projection, self.phi_layer)

    def structure(self) -> tuple:
        box = self.projection
        if box is not None:
            box = (
                tuple(np.asarray(box.lo, dtype=float).ravel().tolist()),
                tuple(np.asarray(box.hi, dtype=float).ravel().tolist()),
                box.layer,
            )
        return (self.oracle, box, float(self.phi_layer))

    def initial_internal(self, z0, plant, op, init):
        th0 = jnp.stack([init.th1, init.th2]) + jnp.zeros_like(z0[0])
        box = self.projection
        if box is not None and is_concrete(th0, box.lo, box.hi):
            if not box.contains(th0):
                raise ParameterError(
                    f"initial estimates (th1, th2) = ({float(th0[0]):g}, "
                    f"{float(th0[1]):g}) are not allowed: must lie in the projection "
                    f"box [{np.asarray(box.lo).tolist()}, {np.asarray(box.hi).tolist()}]"
                )
        return th0

    def __call__(self, t, z, s, stage, plant, op, trig=None):
        out = control_law(z, s, self.gains, plant, op, self.phi_layer, trig)
        rate = adaptation_rate(out, s, self.gains, plant, self.oracle)
        if self.projection is not None:
            rate = project(s, rate, self.projection)
        return ControllerOutput(out.u_f, out.u_r, rate, out.phi)
