"""TGOV1: the steam turbine-governor (PSS/E `TGOV1`, CONs R, T1, VMAX, VMIN, T2, T3,
Dt; ANDES `TGOV1`).

    u   = (Pref - omega) / R                             droop on the speed deviation
    x_v: T1 dx_v/dt = u - x_v                            valve, non-windup limits [VMIN, VMAX]
    x_t: T3 dx_t/dt = x_v - x_t,  y_t = x_t + (T2/T3)(x_v - x_t)   turbine (1 + s T2)/(1 + s T3)
    Pm  = y_t - Dt omega                                 mechanical power (pu machine base)

with omega the speed deviation (pu), R the droop (pu speed / pu power), VMAX, VMIN
the valve limits and Pm on the machine base. The valve limits are non-windup
(PSS/E draws them on the 1/(1 + s T1) block; ANDES `LagAntiWindup`). T1 = 0 makes
the valve algebraic (x_v = clip(u)); T3 = 0 (with T2 = 0) drops the lead-lag.

Static gain: dPm/domega = -(1/R + Dt) inside the limits. At rest: x_v = x_t = Pm0
and Pref = R Pm0 (PSS/E's reference, in pu speed), returned as `ref`.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    lag_nonwindup,
    leadlag,
    nonneg,
    ordered,
    positive,
    proper,
    require_at_rest,
)
from .base import AbstractController, f64, i64

__all__ = ["TGOV1"]


class TGOV1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    R: np.ndarray = eqx.field(converter=f64)  # droop (pu/pu)
    T1: np.ndarray = eqx.field(converter=f64)  # valve time constant (s)
    VMAX: np.ndarray = eqx.field(converter=f64)  # valve limits (pu machine base)
    VMIN: np.ndarray = eqx.field(converter=f64)
    T2: np.ndarray = eqx.field(converter=f64)  # turbine lead (s)
    T3: np.ndarray = eqx.field(converter=f64)  # turbine lag (s)
    Dt: np.ndarray = eqx.field(converter=f64)  # turbine damping (pu/pu)

    inputs = ("omega",)
    output = "Pm"
    state_names = ("x_v", "x_t")
    con_names = DYR_MODELS["TGOV1"]

    def __check_init__(self):
        check(
            self,
            [
                *positive("R"),
                *nonneg("T1"),
                proper("T2", "T3"),
                ordered("VMIN", "VMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _f(self, x, meas, ref):
        w = meas["omega"]
        u = (ref - w) / self.R
        xv, dv = lag_nonwindup(x[0], u, 1.0, self.T1, self.VMIN, self.VMAX)
        yt, dt = leadlag(x[1], xv, self.T2, self.T3)
        return yt - self.Dt * w, jnp.stack([dv, dt])

    def init(self, y0, meas):
        w = meas["omega"]
        pv = y0 + self.Dt * w  # the valve position that gives Pm0 at this speed
        require_at_rest(
            (pv >= self.VMIN) & (pv <= self.VMAX),
            "TGOV1",
            "Pm0",
            y0,
            "the operating point's valve position must lie within [VMIN, VMAX]",
        )
        ref = self.R * pv + w
        return jnp.stack([pv, pv]), ref

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
