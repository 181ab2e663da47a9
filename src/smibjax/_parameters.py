"""Parameter sets of the closed loop, as equinox Modules (pytrees of float arrays).

Every field is converted to a floating-point JAX array when the Module is built, so a
parameter set can be jitted without recompiling for new values, vmapped (give fields a
leading batch axis) and differentiated. Values are validated when built from concrete
numbers (`__check_init__`); a bad value raises `ParameterError` with one line naming the
value and what is allowed.

Names follow `docs/model.md` (sections 1-2); `Xdp` is the transient reactance X'_d.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace
from typing import Literal

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._names import PRESETS as _PRESETS
from ._validate import (
    ParameterError,
    concrete_value,
    require,
    require_finite,
)

__all__ = [
    "Plant",
    "Fault",
    "OperatingPoint",
    "InitialEstimates",
    "ParameterError",
    "PRESETS",
    "PLANT_NAMES",
    "FAULT_NAMES",
]

Scalar = Float[Array, "*batch"]


def _f(x) -> Array:
    return jnp.asarray(x, dtype=float)


def _field(default: float):
    return eqx.field(default=default, converter=_f)


def _values(module: eqx.Module) -> SimpleNamespace | None:
    """The fields of a parameter set as NumPy arrays, for validation; None when any is
    a tracer (inside jit or vmap, where validation is skipped). NumPy, not jax.numpy:
    each eager jax.numpy comparison compiles a kernel on first use (~17 ms each, a
    quarter of a second per process before the first simulation)."""
    names = [f.name for f in dataclasses.fields(module)]
    values = [concrete_value(getattr(module, n)) for n in names]
    if any(v is None for v in values):
        return None
    return SimpleNamespace(**dict(zip(names, values, strict=True)))


class Plant(eqx.Module):
    """Physical parameters of the SMIB + SVC plant (per unit unless stated).

    Paper defaults (docs/model.md section 1). The input limits default to none (the paper);
    `Plant.preset("realistic")` bounds u_f to [-5, 5] and u_r to [-1, 1]. Every value
    must be finite with |value| <= 1e6 (`MAX_MAGNITUDE`: beyond it the model's products
    overflow), except the input limits, which may be +-inf (no limit).
    """

    H: Scalar = _field(5.0)  # inertia constant (s)
    D: Scalar = _field(0.2)  # damping
    T0: Scalar = _field(4.0)  # d-axis transient open-circuit time constant T'_0 (s)
    V: Scalar = _field(1.0)  # infinite-bus voltage
    Xd: Scalar = _field(1.1)  # d-axis reactance
    Xdp: Scalar = _field(0.2)  # d-axis transient reactance X'_d
    XT: Scalar = _field(0.1)  # transformer reactance
    XL: Scalar = _field(0.2)  # line reactance (two circuits of 2 XL in parallel)
    Tr: Scalar = _field(1.0)  # SVC time constant (s)
    Pm: Scalar = _field(1.0)  # true mechanical power
    f: Scalar = _field(60.0)  # frequency (Hz)
    B0: Scalar = _field(0.0)  # SVC susceptance reference
    uf_min: Scalar = _field(-math.inf)  # field-voltage limits applied at the plant
    uf_max: Scalar = _field(math.inf)
    ur_min: Scalar = _field(-math.inf)  # SVC-command limits applied at the plant
    ur_max: Scalar = _field(math.inf)

    def __check_init__(self):
        p = _values(self)
        if p is None:
            return
        o = "Plant"
        limits = ("uf_min", "uf_max", "ur_min", "ur_max")
        require_finite(p, o, [n for n in _names(Plant) if n not in limits])
        require_finite(p, o, limits, bound=None, allow_inf=limits)
        for name in ("H", "T0", "V", "Xdp", "XL", "Tr", "Pm", "f"):
            v = getattr(p, name)
            require(v > 0, o, name, v, "must be > 0")
        for name in ("D", "XT"):
            v = getattr(p, name)
            require(v >= 0, o, name, v, "must be >= 0")
        require(p.Xd > p.Xdp, o, "Xd", p.Xd, "must be > Xdp = {}", p.Xdp)
        require(
            p.uf_min < p.uf_max,
            o,
            "uf_min",
            p.uf_min,
            "must be < uf_max = {}",
            p.uf_max,
        )
        require(
            p.ur_min < p.ur_max,
            o,
            "ur_min",
            p.ur_min,
            "must be < ur_max = {}",
            p.ur_max,
        )

    @property
    def ws(self) -> Scalar:
        """Synchronous speed 2 pi f (rad/s)."""
        return 2 * jnp.pi * self.f

    @property
    def M(self) -> Scalar:
        """Inertia coefficient M = 2H/ws (s^2/rad)."""
        return 2 * self.H / self.ws

    @property
    def X1(self) -> Scalar:
        """Generator-side reactance X'_d + X_T up to the SVC bus."""
        return self.Xdp + self.XT

    @classmethod
    def preset(cls, name: Literal["paper", "realistic"] = "paper", **overrides):
        """The `paper` plant (no input limits) or the `realistic` one (u_f in [-5, 5],
        u_r in [-1, 1]), with any field overridden by keyword."""
        if name not in PRESETS:
            raise ParameterError(
                f"preset = {name!r} is not allowed: must be one of {sorted(PRESETS)}"
            )
        return cls(**{**PRESETS[name], **overrides})


PRESETS: dict[str, dict[str, float]] = _PRESETS  # (defined jax-free in _names)


class Fault(eqx.Module):
    """One fault scenario: a three-phase fault on circuit 1 at fraction `lam` of its
    length from the SVC bus, through reactance `Xf`, at `t_fault`; circuit 1 is opened at
    `t_clear` and reclosed at `t_reclose` (all times in s)."""

    t_fault: Scalar = _field(0.5)
    t_clear: Scalar = _field(0.7)
    t_reclose: Scalar = _field(2.0)
    lam: Scalar = _field(0.5)
    Xf: Scalar = _field(0.0)

    def __check_init__(self):
        p = _values(self)
        if p is None:
            return
        o = "Fault"
        require_finite(p, o, _names(Fault), bound=None)
        require(
            (p.t_fault >= 0) & np.isfinite(p.t_fault),
            o,
            "t_fault",
            p.t_fault,
            "must be >= 0",
        )
        require(
            p.t_clear > p.t_fault,
            o,
            "t_clear",
            p.t_clear,
            "must be > t_fault = {}",
            p.t_fault,
        )
        require(
            p.t_reclose >= p.t_clear,
            o,
            "t_reclose",
            p.t_reclose,
            "must be >= t_clear = {}",
            p.t_clear,
        )
        require((p.lam > 0) & (p.lam < 1), o, "lam", p.lam, "must be in (0, 1)")
        require((p.Xf >= 0) & np.isfinite(p.Xf), o, "Xf", p.Xf, "must be >= 0")


class OperatingPoint(eqx.Module):
    """The controller's operating point (delta_e in rad, Pm_ref in pu). The plant starts
    there: delta = delta_e, domega = 0, B = B0, E = Pm_ref Xs / (V sin delta_e)."""

    delta_e: Scalar = _field(0.4964)
    Pm_ref: Scalar = _field(1.0)

    def __check_init__(self):
        p = _values(self)
        if p is None:
            return
        o = "OperatingPoint"
        require_finite(p, o, ("delta_e", "Pm_ref"))
        require(
            (p.delta_e > 0) & (p.delta_e < np.pi / 2),
            o,
            "delta_e",
            p.delta_e,
            "must be in (0, pi/2)",
        )
        require(p.Pm_ref > 0, o, "Pm_ref", p.Pm_ref, "must be > 0")


class InitialEstimates(eqx.Module):
    """Initial parameter estimates th_hat(0) = (th1, th2) of theta = (-D, Pm)."""

    th1: Scalar = _field(-0.5)
    th2: Scalar = _field(0.0)
    # Both finite with |th| <= 1e6 (`MAX_MAGNITUDE`): theta = (-D, Pm) is O(1) per unit,
    # and 1e308 overflows the control law to NaN.

    def __check_init__(self):
        p = _values(self)
        if p is None:
            return
        require_finite(p, "InitialEstimates", ("th1", "th2"))


def _names(cls) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


PLANT_NAMES: tuple[str, ...] = _names(Plant)
FAULT_NAMES: tuple[str, ...] = _names(Fault)
