"""GAST: the gas turbine-governor (PSS/E `GAST`, CONs R, T1, T2, T3, AT, KT, VMAX,
VMIN, Dturb; ANDES `GAST`).

    u_s = Pref - omega / R                               speed governor (droop R)
    u_l = AT + KT (AT - x3)                              load limit (ambient temperature
                                                         load limit AT, gain KT)
    x1: T1 dx1/dt = min(u_s, u_l) - x1                   fuel valve: low-value gate, lag
                                                         with non-windup limits [VMIN, VMAX]
    x2: T2 dx2/dt = x1 - x2                              fuel system / turbine
    x3: T3 dx3/dt = x2 - x3                              exhaust temperature measurement
    Pm  = x2 - Dturb omega                               pu machine base

with omega the speed deviation (pu). T1, T2, T3 and R must be > 0. At rest every
state is at Pm0 + Dturb omega0 (within [VMIN, VMAX]), Pref = x0 + omega0 / R
(returned as `ref`), and the speed governor must be the lower input of the gate
(x0 <= AT: an operating point above the load limit is refused).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    lag,
    lag_nonwindup,
    ordered,
    positive,
    require_at_rest,
)
from .base import AbstractController, f64, i64

__all__ = ["GAST"]


class GAST(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    R: np.ndarray = eqx.field(converter=f64)  # droop (pu/pu)
    T1: np.ndarray = eqx.field(converter=f64)  # fuel valve (s)
    T2: np.ndarray = eqx.field(converter=f64)  # fuel system (s)
    T3: np.ndarray = eqx.field(converter=f64)  # load-limit measurement (s)
    AT: np.ndarray = eqx.field(converter=f64)  # ambient temperature load limit (pu)
    KT: np.ndarray = eqx.field(converter=f64)  # load-limit feedback gain (pu/pu)
    VMAX: np.ndarray = eqx.field(converter=f64)  # valve limits (pu machine base)
    VMIN: np.ndarray = eqx.field(converter=f64)
    Dturb: np.ndarray = eqx.field(converter=f64)  # turbine damping (pu/pu)

    inputs = ("omega",)
    output = "Pm"
    state_names = ("x1", "x2", "x3")
    con_names = DYR_MODELS["GAST"]

    def __check_init__(self):
        check(self, [*positive("R", "T1", "T2", "T3"), ordered("VMIN", "VMAX")])

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _f(self, x, meas, ref):
        w = meas["omega"]
        u_s = ref - w / self.R
        u_l = self.AT + self.KT * (self.AT - x[2])
        y1, d1 = lag_nonwindup(
            x[0], jnp.minimum(u_s, u_l), 1.0, self.T1, self.VMIN, self.VMAX
        )
        y2, d2 = lag(x[1], y1, 1.0, self.T2)
        _, d3 = lag(x[2], y2, 1.0, self.T3)
        return y2 - self.Dturb * w, jnp.stack([d1, d2, d3])

    def init(self, y0, meas):
        w = meas["omega"]
        x0 = y0 + self.Dturb * w
        require_at_rest(
            (x0 >= self.VMIN) & (x0 <= self.VMAX) & (x0 <= self.AT),
            "GAST",
            "Pm0",
            y0,
            "the operating point's fuel valve must lie within [VMIN, VMAX] and at "
            "most AT (below the load limit)",
        )
        return jnp.stack([x0, x0, x0]), x0 + w / self.R

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
