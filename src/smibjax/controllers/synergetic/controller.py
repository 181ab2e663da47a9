"""`aftsc` / `asc`: the paper's adaptive synergetic law as a controller.

The law itself (eqs. 21-22, 36-37, in the paper's coordinates) is in `law`; this
module makes it a controller of the closed loop, with its options (all off by
default, docs/model.md section 2):

- weighted macro-variables phi_i = c_i e1 + e2 + beta_i e_(i+2): `Gains.c1`, `c2`;
- a smooth projection of the estimates onto a known box [th_min, th_max]
  (`EstimateBox`), the standard anti-windup of adaptive control;
- the evolution law's boundary layer `phi_layer`.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete
from ..base import AbstractController, ControllerOutput
from .gains import GAIN_NAMES, Gains
from .law import adaptation_rate, control_law, static_alpha
from .options import OPTION_NAMES, EstimateBox, project, synergetic_options
from .transforms import GAIN_KINDS

__all__ = ["Synergetic"]


class Synergetic(AbstractController):
    """The adaptive synergetic controller: AFTSC for alpha < 1, ASC for alpha = 1.

    `oracle`: the paper's update law, whose k-terms read the true theta (True), or the
    realizable certainty-equivalence law without them (False). `projection`: an
    `EstimateBox` (None: no projection, the paper). `phi_layer` (units of phi): the
    boundary-layer width of the evolution law (`law.evolution`; 0, the
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
    has_adaptation = True
    option_names = OPTION_NAMES
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
        `projection` ([[th1_min, th1_max], [th2_min, th2_max]] or an `EstimateBox`;
        [], None or absent: off) and `phi_layer` (absent: 0, the exact law)."""
        options = options or {}
        box = options.get("projection") or []
        if not isinstance(box, EstimateBox):
            box = EstimateBox(*zip(*box, strict=True)) if box else None
        return cls(
            gains,
            oracle=adaptation != "realizable",
            projection=box,
            phi_layer=float(options.get("phi_layer", 0.0)),
        )

    @classmethod
    def parameter_set(cls, name: str, values: dict[str, float]) -> Gains:
        """The paper's gains of `name` (aftsc: alpha = 5/7, asc: 1) with `values`."""
        return Gains.paper(name, **values)

    @classmethod
    def parameter_type(cls) -> type:
        return Gains

    @classmethod
    def required_parameters(cls) -> tuple[str, ...]:
        """Every gain but c1, c2 (1: the paper's form)."""
        return tuple(g for g in GAIN_NAMES if g not in ("c1", "c2"))

    @classmethod
    def check_options(cls, name: str, options: dict) -> dict:
        return synergetic_options(name, options)

    @classmethod
    def options_for_file(cls, name: str, values: dict, options: dict) -> tuple:
        """asc where the tuned alpha is 1 (a logit can round up to 1.0, the ASC law
        whatever the start), and the projection box and boundary layer."""
        name = "asc" if values["alpha"] == 1.0 else name
        return name, {
            "projection": options["projection"],
            "phi_layer": float(options["phi_layer"]),
        }

    @classmethod
    def from_parameters(
        cls, params, adaptation: str = "oracle", options: dict | None = None
    ) -> Synergetic:
        return cls.from_options(params, adaptation, options)

    def with_adaptation(self, adaptation: str | None) -> Synergetic:
        if adaptation is None:
            return self
        return Synergetic(
            self.gains, adaptation == "oracle", self.projection, self.phi_layer
        )

    def specialized(self) -> Synergetic:
        """alpha compiled as the constant 1 where it is concretely 1 (ASC)."""
        return self.with_static_alpha()

    def placeholder_internal(self, z0, plant, op, init):
        """The initial estimates, or the projection box's centre: inside any box."""
        zero = jnp.zeros_like(z0[0])
        box = self.projection
        if box is not None:
            return 0.5 * (box.lo + box.hi) + zero
        return jnp.stack([init.th1 + zero, init.th2 + zero])

    def check_estimates(self, init) -> None:
        """The initial estimates (any batch shape) must lie in the projection box."""
        box = self.projection
        if box is None or not is_concrete(init.th1, init.th2, box.lo, box.hi):
            return
        th0 = np.stack(
            np.broadcast_arrays(np.asarray(init.th1), np.asarray(init.th2)), -1
        )
        if not box.contains(th0):
            raise ParameterError(
                f"initial estimates (th1, th2) = ({np.asarray(init.th1)}, "
                f"{np.asarray(init.th2)}) are not allowed: must lie in the projection "
                f"box [{np.asarray(box.lo).tolist()}, {np.asarray(box.hi).tolist()}]"
            )

    def label(self) -> str:
        """'AFTSC: beta = (-1, -1), alpha = 0.714' (ASC where alpha = 1)."""
        g = self.gains
        a = float(g.alpha)
        return (
            f"{'AFTSC' if a < 1 else 'ASC'}: beta = ({float(g.beta1):g}, "
            f"{float(g.beta2):g}), alpha = {a:.3g}"
        )

    def with_static_alpha(self, alpha_one: bool | None = None) -> Synergetic:
        """The same controller with alpha compiled as the constant 1 where it is 1
        (`law.static_alpha`)."""
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
