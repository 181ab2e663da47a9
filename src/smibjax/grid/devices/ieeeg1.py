"""IEEEG1: the IEEE type 1 steam turbine-governor (PSS/E `IEEEG1`, ICONs JBUS, M;
CONs K, T1, T2, T3, UO, UC, PMAX, PMIN, T4, K1, K2, T5, K3, K4, T6, K5, K6, T7, K7,
K8; ANDES `IEEEG1`).

    x_ll: T1 dx_ll/dt = K omega - x_ll,
          y_ll = x_ll + (T2/T1)(K omega - x_ll)          speed lead-lag K (1 + s T2)/(1 + s T1)
    GV:   dGV/dt = clip((P0 - y_ll - GV)/T3, UC, UO)     valve servo: rate limits UC <= 0 <= UO
                                                         (pu/s), non-windup position limits
                                                         [PMIN, PMAX] on the integrator
    x4:   T4 dx4/dt = GV - x4                            steam chest
    x5:   T5 dx5/dt = x4 - x5                            reheater
    x6:   T6 dx6/dt = x5 - x6                            crossover / second reheater
    x7:   T7 dx7/dt = x6 - x7                            crossover
    PMECH_HP = K1 x4 + K3 x5 + K5 x6 + K7 x7             to the machine of the record
    PMECH_LP = K2 x4 + K4 x5 + K6 x6 + K8 x7             to the machine JBUS, M

with omega the speed deviation (pu), K the gain 1/R (pu power / pu speed) and the
powers in pu of the machine base. A zero T4..T7 makes its stage algebraic (x = its
input); T1 = 0 (then T2 = 0) makes the lead-lag the gain K. T3 must be > 0.

The low-pressure machine: smibjax reads JBUS and M and supports only JBUS = 0 (no
second machine; a cross-compound unit is refused). Then PMECH_LP drives nothing
(PSS/E connects it to no machine): the K2, K4, K6, K8 fractions of the steam power
are dropped, and the machine receives PMECH_HP alone. At rest every stage equals
GV0 = Pm0 / (K1 + K3 + K5 + K7), so K1 + K3 + K5 + K7 must be > 0, and P0 = GV0
(PSS/E's load reference), returned as `ref`. ANDES 2.0 differs when K1..K8 do not
sum to 1: it divides every K by their sum (and likewise drops PMECH_LP without a
second machine).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete
from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    lag,
    leadlag,
    nonneg,
    nonwindup,
    ordered,
    positive,
    proper,
    require_at_rest,
    v,
)
from .base import AbstractController, f64, i64

__all__ = ["IEEEG1"]

_CONS = DYR_MODELS["IEEEG1"][2:]  # the CONs after the ICONs JBUS, M


_HP_RULE = (
    "K1",
    lambda o: (v(o, "K1") + v(o, "K3") + v(o, "K5") + v(o, "K7")) > 0,
    "K1 + K3 + K5 + K7 must be > 0 (the machine's share of the power)",
)


class IEEEG1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    JBUS: np.ndarray = eqx.field(converter=i64)  # low-pressure machine's bus (0 only)
    M: np.ndarray = eqx.field(converter=i64)  # its machine id (unused with JBUS = 0)
    K: np.ndarray = eqx.field(converter=f64)  # gain 1/R (pu/pu)
    T1: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    T2: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    T3: np.ndarray = eqx.field(converter=f64)  # valve servo (s)
    UO: np.ndarray = eqx.field(converter=f64)  # valve opening rate limit (pu/s)
    UC: np.ndarray = eqx.field(converter=f64)  # valve closing rate limit (pu/s, <= 0)
    PMAX: np.ndarray = eqx.field(converter=f64)  # valve limits (pu machine base)
    PMIN: np.ndarray = eqx.field(converter=f64)
    T4: np.ndarray = eqx.field(converter=f64)  # stage time constants (s)
    K1: np.ndarray = eqx.field(converter=f64)  # HP / LP fractions of each stage
    K2: np.ndarray = eqx.field(converter=f64)
    T5: np.ndarray = eqx.field(converter=f64)
    K3: np.ndarray = eqx.field(converter=f64)
    K4: np.ndarray = eqx.field(converter=f64)
    T6: np.ndarray = eqx.field(converter=f64)
    K5: np.ndarray = eqx.field(converter=f64)
    K6: np.ndarray = eqx.field(converter=f64)
    T7: np.ndarray = eqx.field(converter=f64)
    K7: np.ndarray = eqx.field(converter=f64)
    K8: np.ndarray = eqx.field(converter=f64)

    inputs = ("omega",)
    output = "Pm"
    state_names = ("x_ll", "GV", "x4", "x5", "x6", "x7")
    con_names = _CONS

    def __check_init__(self):
        if is_concrete(self.JBUS):
            jb = np.asarray(self.JBUS)
            if (jb != 0).any():
                raise ParameterError(
                    f"IEEEG1.JBUS = {int(jb[jb != 0][0])} is not supported: only 0 "
                    "(no low-pressure machine; cross-compound units are not modelled)"
                )
        check(
            self,
            [
                *nonneg("K", "T4", "T5", "T6", "T7"),
                proper("T2", "T1"),
                *positive("T3"),
                ("UO", lambda o: v(o, "UO") >= 0, "must be >= 0 (an opening rate)"),
                ("UC", lambda o: v(o, "UC") <= 0, "must be <= 0 (a closing rate)"),
                ordered("PMIN", "PMAX"),
                *nonneg("K1", "K2", "K3", "K4", "K5", "K6", "K7", "K8"),
            ],
        )
        if is_concrete(self.K1, self.K3, self.K5, self.K7):  # a rule reading four
            check(self, [_HP_RULE])

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` holds JBUS and M (the ICONs) and the CONs."""
        return build_group(
            cls,
            gen_positions,
            [{**p, "JBUS": p.get("JBUS", 0), "M": p.get("M", 0)} for p in params],
            ("JBUS", "M", *cls.con_names),
        )

    def _hp(self):
        return self.K1 + self.K3 + self.K5 + self.K7

    def _f(self, x, meas, ref):
        w = meas["omega"]
        y_ll, d_ll = leadlag(x[0], self.K * w, self.T2, self.T1)
        gv = x[1]
        rate = jnp.clip((ref - y_ll - gv) / self.T3, self.UC, self.UO)
        d_gv = nonwindup(gv, rate, self.PMIN, self.PMAX)
        y4, d4 = lag(x[2], gv, 1.0, self.T4)
        y5, d5 = lag(x[3], y4, 1.0, self.T5)
        y6, d6 = lag(x[4], y5, 1.0, self.T6)
        y7, d7 = lag(x[5], y6, 1.0, self.T7)
        pm = self.K1 * y4 + self.K3 * y5 + self.K5 * y6 + self.K7 * y7
        return pm, jnp.stack([d_ll, d_gv, d4, d5, d6, d7])

    def init(self, y0, meas):
        w = meas["omega"]
        gv = y0 / self._hp()
        require_at_rest(
            (gv >= self.PMIN) & (gv <= self.PMAX),
            "IEEEG1",
            "Pm0",
            y0,
            "the operating point's valve position Pm0/(K1 + K3 + K5 + K7) must lie "
            "within [PMIN, PMAX]",
        )
        kw = self.K * w
        ref = gv + kw  # P0: the reference that holds GV at this speed
        return jnp.stack([kw, gv, gv, gv, gv, gv]), ref

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
