"""STAB2A: the ASEA power-sensitive stabilizer (PSS/E `STAB2A`, CONs K2, T2, K3, T3,
K4, K5, T5, HLIM; not in ANDES).

    u  = Pe                                              electrical power (pu machine base)
    W(s) = K2 s T2 / (1 + s T2)                          washout
    y_w = -W(s)^3 u                                      three washouts in cascade, the
                                                         first with a negative sign
    y_s = K3/(1 + s T3) y_w + K4 y_w                     lag plus proportional path
    Vs  = clip(K5^2/(1 + s T5)^2 y_s, -HLIM, HLIM)       two output lags K5/(1 + s T5),
                                                         output limiter (windup: an
                                                         algebraic clip)

Transfer function inside the limits:
Vs/Pe = -(K2 s T2/(1 + s T2))^3 (K3/(1 + s T3) + K4) K5^2/(1 + s T5)^2.
States: the three washouts (x_w1, x_w2, x_w3; T2 dx/dt = input - x, output K2 (input
- x)), the lag (x_3) and the two output lags (x_51, x_52). T2 must be > 0; T3 = 0 or
T5 = 0 makes its lags algebraic. Reference: the PSS/E Model Library's STAB2A block
diagram, as written out in OpenIPSL's PSS/E library
(OpenIPSL/Electrical/Controls/PSSE/PSS/STAB2A.mo: three K2 T2 s/(1 + T2 s) blocks,
the first negated, K3/(1 + T3 s) in parallel with K4, two K5/(1 + T5 s), limiter
+-HLIM). At rest every washout output is zero, so Vs0 = 0: `init` refuses another
y0. `ref` is zeros (k,).
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
    nonneg,
    positive,
    require_at_rest,
    washout,
)
from .base import AbstractController, f64, i64

__all__ = ["STAB2A"]


class STAB2A(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    K2: np.ndarray = eqx.field(converter=f64)  # washout gain (pu/pu)
    T2: np.ndarray = eqx.field(converter=f64)  # washout time constant (s)
    K3: np.ndarray = eqx.field(converter=f64)  # lag gain
    T3: np.ndarray = eqx.field(converter=f64)  # lag time constant (s)
    K4: np.ndarray = eqx.field(converter=f64)  # proportional gain
    K5: np.ndarray = eqx.field(converter=f64)  # output lag gain
    T5: np.ndarray = eqx.field(converter=f64)  # output lag time constant (s)
    HLIM: np.ndarray = eqx.field(converter=f64)  # output limit (pu)

    inputs = ("Pe",)
    output = "Vs"
    state_names = ("x_w1", "x_w2", "x_w3", "x_3", "x_51", "x_52")
    con_names = DYR_MODELS["STAB2A"]

    def __check_init__(self):
        check(self, [*positive("T2"), *nonneg("T3", "T5", "HLIM")])

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _f(self, x, meas):
        u = meas["Pe"]
        k = self.K2 * self.T2
        y1, d1 = washout(x[0], -u, k, self.T2)
        y2, d2 = washout(x[1], y1, k, self.T2)
        y3, d3 = washout(x[2], y2, k, self.T2)
        y4, d4 = lag(x[3], y3, self.K3, self.T3)
        ys = y4 + self.K4 * y3
        y5, d5 = lag(x[4], ys, self.K5, self.T5)
        y6, d6 = lag(x[5], y5, self.K5, self.T5)
        vs = jnp.clip(y6, -self.HLIM, self.HLIM)
        return vs, jnp.stack([d1, d2, d3, d4, d5, d6])

    def init(self, y0, meas):
        require_at_rest(
            y0 == 0, "STAB2A", "Vs0", y0, "a stabilizer with a washout rests at 0"
        )
        u = meas["Pe"] + 0.0 * y0
        zero = 0.0 * u
        return jnp.stack([-u, zero, zero, zero, zero, zero]), zero

    def rhs(self, x, meas, ref):
        return self._f(x, meas)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas)[0]
