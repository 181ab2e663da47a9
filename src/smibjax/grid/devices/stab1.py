"""STAB1: the speed-sensitive stabilizer (PSS/E `STAB1`, CONs K/T, T, T1/T3, T3,
T2/T4, T4, HLIM; not in ANDES).

    u  = omega                                           speed deviation (pu)
    x_w: T dx_w/dt = u - x_w,     y_w = K_T (u - x_w)    washout s K/(1 + s T), K = K_T T
    x_1: T3 dx_1/dt = y_w - x_1,  y_1 = x_1 + T1_T3 (y_w - x_1)   (1 + s T1)/(1 + s T3)
    x_2: T4 dx_2/dt = y_1 - x_2,  y_2 = x_2 + T2_T4 (y_1 - x_2)   (1 + s T2)/(1 + s T4)
    Vs = clip(y_2, -HLIM, HLIM)                          output limiter (windup: an
                                                         algebraic clip)

PSS/E gives the high-frequency gains K/T, T1/T3, T2/T4 as data (so T1 = T1_T3 T3,
T2 = T2_T4 T4). This is the smibjax SMIB's PSS (`smibjax.controllers.avr_pss`:
K_pss s T_w/(1 + s T_w) (1 + s T1)/(1 + s T2) (1 + s T3)/(1 + s T4), clipped) with
K_T = K_pss, T = T_w, T1_T3 = T1/T2, T3 = T2, T2_T4 = T3/T4, T4 = T4 (the SMIB's
names). T, T3, T4 must be > 0. At rest Vs0 = 0; `ref` is zeros (k,).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import build_group, check, nonneg, positive, require_at_rest
from .base import AbstractController, f64, i64

__all__ = ["STAB1"]


class STAB1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    K_T: np.ndarray = eqx.field(converter=f64)  # K/T: high-frequency gain (pu/pu)
    T: np.ndarray = eqx.field(converter=f64)  # washout time constant (s)
    T1_T3: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 high-frequency gain
    T3: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 lag (s)
    T2_T4: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 high-frequency gain
    T4: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 lag (s)
    HLIM: np.ndarray = eqx.field(converter=f64)  # output limit (pu)

    inputs = ("omega",)
    output = "Vs"
    state_names = ("x_w", "x_1", "x_2")
    con_names = DYR_MODELS["STAB1"]

    def __check_init__(self):
        check(self, [*positive("T", "T3", "T4"), *nonneg("T1_T3", "T2_T4", "HLIM")])

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _f(self, x, meas):
        u = meas["omega"]
        y_w = self.K_T * (u - x[0])
        y_1 = x[1] + self.T1_T3 * (y_w - x[1])
        y_2 = x[2] + self.T2_T4 * (y_1 - x[2])
        dx = jnp.stack(
            [(u - x[0]) / self.T, (y_w - x[1]) / self.T3, (y_1 - x[2]) / self.T4]
        )
        return jnp.clip(y_2, -self.HLIM, self.HLIM), dx

    def init(self, y0, meas):
        require_at_rest(y0 == 0, "STAB1", "Vs0", y0, "a washout stabilizer rests at 0")
        u = meas["omega"] + 0.0 * y0
        zero = 0.0 * u
        return jnp.stack([u, zero, zero]), zero

    def rhs(self, x, meas, ref):
        return self._f(x, meas)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas)[0]
