"""IEESGO: the IEEE standard turbine-governor (PSS/E `IEESGO`, CONs T1, T2, T3, T4,
T5, T6, K1, K2, K3, PMAX, PMIN; ANDES `IEESGO`).

    x1: T1 dx1/dt = K1 omega - x1                        governor lag K1/(1 + s T1)
    x2: T3 dx2/dt = x1 - x2,
        y2 = x2 + (T2/T3)(x1 - x2)                       lead-lag (1 + s T2)/(1 + s T3)
    P1  = clip(P0 - y2, PMIN, PMAX)                      valve limits (windup: an algebraic
                                                         clip before the servo lag)
    x4: T4 dx4/dt = P1 - x4                              servo / steam chest
    x5: T5 dx5/dt = K2 x4 - x5                           reheater
    x6: T6 dx6/dt = K3 x5 - x6                           low-pressure stage
    Pm = (1 - K2) x4 + (1 - K3) x5 + x6                  pu machine base

with omega the speed deviation (pu) and K1 the gain 1/R (pu/pu). Zero time
constants make their blocks algebraic (T1 = 0: x1 = K1 omega; T3 = 0 with T2 = 0:
no lead-lag; T4, T5, T6 = 0: the stage follows its input). The DC gain from x4 to
Pm is 1 (x5 = K2 x4, x6 = K3 K2 x4 at rest). At rest every stage is at P1 = Pm0
and P0 = Pm0 + K1 omega0 (PSS/E's load reference), returned as `ref`.
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
    leadlag,
    nonneg,
    ordered,
    proper,
    require_at_rest,
)
from .base import AbstractController, f64, i64

__all__ = ["IEESGO"]


class IEESGO(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    T1: np.ndarray = eqx.field(converter=f64)  # governor lag (s)
    T2: np.ndarray = eqx.field(converter=f64)  # lead (s)
    T3: np.ndarray = eqx.field(converter=f64)  # lag (s)
    T4: np.ndarray = eqx.field(converter=f64)  # servo / steam chest (s)
    T5: np.ndarray = eqx.field(converter=f64)  # reheater (s)
    T6: np.ndarray = eqx.field(converter=f64)  # low-pressure stage (s)
    K1: np.ndarray = eqx.field(converter=f64)  # gain 1/R (pu/pu)
    K2: np.ndarray = eqx.field(converter=f64)  # fraction after the reheater
    K3: np.ndarray = eqx.field(converter=f64)  # fraction after the LP stage
    PMAX: np.ndarray = eqx.field(converter=f64)  # valve limits (pu machine base)
    PMIN: np.ndarray = eqx.field(converter=f64)

    inputs = ("omega",)
    output = "Pm"
    state_names = ("x1", "x2", "x4", "x5", "x6")
    con_names = DYR_MODELS["IEESGO"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("T1", "T4", "T5", "T6", "K1"),
                proper("T2", "T3"),
                ordered("PMIN", "PMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _f(self, x, meas, ref):
        w = meas["omega"]
        y1, d1 = lag(x[0], w, self.K1, self.T1)
        y2, d2 = leadlag(x[1], y1, self.T2, self.T3)
        p1 = jnp.clip(ref - y2, self.PMIN, self.PMAX)
        y4, d4 = lag(x[2], p1, 1.0, self.T4)
        y5, d5 = lag(x[3], y4, self.K2, self.T5)
        y6, d6 = lag(x[4], y5, self.K3, self.T6)
        pm = (1.0 - self.K2) * y4 + (1.0 - self.K3) * y5 + y6
        return pm, jnp.stack([d1, d2, d4, d5, d6])

    def init(self, y0, meas):
        w = meas["omega"]
        require_at_rest(
            (y0 >= self.PMIN) & (y0 <= self.PMAX),
            "IEESGO",
            "Pm0",
            y0,
            "the operating point's Pm0 must lie within [PMIN, PMAX]",
        )
        kw = self.K1 * w
        x5 = self.K2 * y0
        return jnp.stack([kw, kw, y0, x5, self.K3 * x5]), y0 + kw

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
