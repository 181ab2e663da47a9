"""The options of the paper's law, both off by default (docs/model.md section 2):

- a smooth projection of the estimates onto a known box [th_min, th_max]
  (`EstimateBox`, `project`), the standard anti-windup of adaptive control;
- `phi_layer`, the boundary layer of the evolution law (`law.evolution`).

`synergetic_options` validates them as a gains file or Monte Carlo spec writes them.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..._parameters import _f
from ..._validate import ParameterError, is_concrete

__all__ = ["EstimateBox", "project", "synergetic_options", "OPTION_NAMES"]

OPTION_NAMES = ("projection", "phi_layer")


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


def synergetic_options(controller: str, options: dict) -> dict:
    """The options of the paper's law, those given (absent: off): `projection` ([]
    or [[th1_min, th1_max], [th2_min, th2_max]], finite, each lo < hi, containing the
    initial estimates (-0.5, 0)) and `phi_layer` (a finite number >= 0, the evolution
    law's boundary layer; 0: exact)."""
    allowed = ("projection", "phi_layer")
    out = dict(options)
    for name in options:
        if name not in allowed:
            raise ParameterError(
                f"option {name!r} is not allowed for controller {controller!r}: "
                "allowed are projection, phi_layer"
            )
    box = out.get("projection", [])
    if "projection" not in out:
        pass
    elif box not in ([], None):
        try:
            (a, b), (c, d) = box
            lo, hi = [float(a), float(c)], [float(b), float(d)]
        except (TypeError, ValueError):
            raise ParameterError(
                f"projection = {box!r} is not allowed: must be [[th1_min, th1_max], "
                "[th2_min, th2_max]] or [] (off)"
            ) from None
        if not all(math.isfinite(x) for x in lo + hi) or not (
            lo[0] < hi[0] and lo[1] < hi[1]
        ):
            raise ParameterError(
                f"projection = {box!r} is not allowed: must be finite and non-empty "
                "(each min < max)"
            )
        if not (lo[0] <= -0.5 <= hi[0] and lo[1] <= 0.0 <= hi[1]):
            raise ParameterError(
                f"projection = {box!r} is not allowed: it must contain the initial "
                "estimates (th1, th2) = (-0.5, 0)"
            )
        out["projection"] = [[lo[0], hi[0]], [lo[1], hi[1]]]
    else:
        out["projection"] = []
    if "phi_layer" not in out:
        return out
    layer = out["phi_layer"]
    if (
        isinstance(layer, bool)
        or not isinstance(layer, (int, float))
        or not (math.isfinite(layer) and layer >= 0)
    ):
        raise ParameterError(
            f"phi_layer = {layer!r} is not allowed: must be a finite number >= 0 "
            "(0: the exact finite-time law)"
        )
    out["phi_layer"] = float(layer)
    return out
