"""IEEEST: the IEEE standard stabilizer (PSS/E `IEEEST`, ICONs ICS, IB; CONs A1-A6,
T1-T6, KS, LSMAX, LSMIN, VCU, VCL; ANDES `IEEEST`).

    u   = omega (ICS = 1, speed deviation, pu) or Pe (ICS = 3, electrical power, pu
          machine base)
    F(s)  = (1 + A5 s + A6 s^2) / ((1 + A1 s + A2 s^2)(1 + A3 s + A4 s^2))   filter
    LL(s) = (1 + s T1)/(1 + s T2) * (1 + s T3)/(1 + s T4)                   lead-lags
    W(s)  = KS s T5 / (1 + s T6)                                            gain, washout
    Vss = clip(W LL F u, LSMIN, LSMAX)                   output limiter (windup: an
                                                         algebraic clip after the washout)
    Vs  = Vss if VCL < Vt < VCU, else 0                  voltage cutoff; VCU = 0 (VCL = 0)
                                                         means no upper (lower) cutoff

States (always 8): the filter as two cascaded second-order sections,
1/(1 + A1 s + A2 s^2) in (f1, f2) and (1 + A5 s + A6 s^2)/(1 + A3 s + A4 s^2) in
(f3, f4), each in controllable form; then the lead-lags (x_ll1, x_ll2) and the
washout (x_w). Zero coefficients lower a section's order (A2 = 0: a first-order lag
1/(1 + A1 s); A1 = A2 = 0: a pass-through) and leave its unused states as
placeholders with zero derivative, so the state count is fixed per group. An
improper combination (A4 = 0 with A6 != 0; A3 = A4 = 0 with A5 != 0; T2 = 0 with
T1 != 0; T4 = 0 with T3 != 0; T6 = 0) is refused. ANDES splits the same filter as
`Lag2ndOrd` then `LeadLag2ndOrd`: the same transfer function.

Only ICS 1 and 3 are supported (the others need bus frequency, accelerating power
or voltage derivatives from other models), and only IB = 0 (the generator's own
terminal). At rest the washout's output is zero, so Vs0 = 0: `init` refuses
another y0. `ref` is zeros (k,).
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
    leadlag,
    nonneg,
    ordered,
    positive,
    proper,
    require_at_rest,
    second_order_lag,
    second_order_leadlag,
    v,
    washout,
)
from .base import AbstractController, f64, i64

__all__ = ["IEEEST"]

_CONS = DYR_MODELS["IEEEST"][2:]  # the CONs after the ICONs ICS, IB


class IEEEST(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    ICS: np.ndarray = eqx.field(converter=i64)  # input code: 1 speed, 3 Pe
    IB: np.ndarray = eqx.field(converter=i64)  # remote bus (0 only)
    A1: np.ndarray = eqx.field(converter=f64)  # filter coefficients (s, s^2)
    A2: np.ndarray = eqx.field(converter=f64)
    A3: np.ndarray = eqx.field(converter=f64)
    A4: np.ndarray = eqx.field(converter=f64)
    A5: np.ndarray = eqx.field(converter=f64)
    A6: np.ndarray = eqx.field(converter=f64)
    T1: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 (s)
    T2: np.ndarray = eqx.field(converter=f64)
    T3: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 (s)
    T4: np.ndarray = eqx.field(converter=f64)
    T5: np.ndarray = eqx.field(converter=f64)  # washout numerator (s)
    T6: np.ndarray = eqx.field(converter=f64)  # washout denominator (s)
    KS: np.ndarray = eqx.field(converter=f64)  # gain (pu/pu)
    LSMAX: np.ndarray = eqx.field(converter=f64)  # output limits (pu)
    LSMIN: np.ndarray = eqx.field(converter=f64)
    VCU: np.ndarray = eqx.field(converter=f64)  # voltage cutoff (pu; 0 = none)
    VCL: np.ndarray = eqx.field(converter=f64)

    inputs = ("omega", "Pe", "Vt")
    output = "Vs"
    state_names = ("f1", "f2", "f3", "f4", "x_ll1", "x_ll2", "x_w")
    con_names = _CONS

    def __check_init__(self):
        if is_concrete(self.ICS, self.IB):
            ics, ib = np.asarray(self.ICS), np.asarray(self.IB)
            bad = ~np.isin(ics, (1, 3))
            if bad.any():
                raise ParameterError(
                    f"IEEEST.ICS = {int(ics[bad][0])} is not supported: only 1 (speed "
                    "deviation) and 3 (electrical power)"
                )
            if (ib != 0).any():
                raise ParameterError(
                    f"IEEEST.IB = {int(ib[ib != 0][0])} is not supported: only 0 (the "
                    "generator's own terminal)"
                )
        check(
            self,
            [
                *nonneg("A1", "A2", "A3", "A4", "A5", "A6", "T5"),
                *positive("T6"),
                proper("T1", "T2"),
                proper("T3", "T4"),
                (
                    "A4",
                    lambda o: (v(o, "A4") > 0) | (v(o, "A6") == 0),
                    "must be > 0 where A6 != 0 (the filter would be improper)",
                ),
                (
                    "A3",
                    lambda o: (v(o, "A3") > 0) | (v(o, "A4") > 0) | (v(o, "A5") == 0),
                    "must be > 0 where A4 = 0 and A5 != 0 (the filter would be "
                    "improper)",
                ),
                ordered("LSMIN", "LSMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` holds ICS and IB (the ICONs) and the CONs."""
        return build_group(
            cls,
            gen_positions,
            [{**p, "ICS": p.get("ICS"), "IB": p.get("IB", 0)} for p in params],
            ("ICS", "IB", *cls.con_names),
        )

    def signal(self, meas):
        """The stabilizer's input: speed deviation (ICS 1) or Pe (ICS 3)."""
        return jnp.where(self.ICS == 1, meas["omega"], meas["Pe"])

    def _f(self, x, meas):
        u = self.signal(meas)
        y1, d1, d2 = second_order_lag(x[0], x[1], u, self.A1, self.A2)
        y2, d3, d4 = second_order_leadlag(
            x[2], x[3], y1, self.A3, self.A4, self.A5, self.A6
        )
        y3, d5 = leadlag(x[4], y2, self.T1, self.T2)
        y4, d6 = leadlag(x[5], y3, self.T3, self.T4)
        yw, d7 = washout(x[6], self.KS * y4, self.T5, self.T6)
        vss = jnp.clip(yw, self.LSMIN, self.LSMAX)
        vt = meas["Vt"]
        on = ((self.VCU == 0) | (vt < self.VCU)) & ((self.VCL == 0) | (vt > self.VCL))
        return jnp.where(on, vss, 0.0), jnp.stack([d1, d2, d3, d4, d5, d6, d7])

    def filter_output(self, x, meas):
        """W LL F u before the output limiter and the cutoff (pu)."""
        u = self.signal(meas)
        y1, _, _ = second_order_lag(x[0], x[1], u, self.A1, self.A2)
        y2, _, _ = second_order_leadlag(
            x[2], x[3], y1, self.A3, self.A4, self.A5, self.A6
        )
        y3, _ = leadlag(x[4], y2, self.T1, self.T2)
        y4, _ = leadlag(x[5], y3, self.T3, self.T4)
        return washout(x[6], self.KS * y4, self.T5, self.T6)[0]

    def init(self, y0, meas):
        require_at_rest(
            y0 == 0, "IEEEST", "Vs0", y0, "a stabilizer with a washout rests at 0"
        )
        u = self.signal(meas) + 0.0 * y0
        zero = 0.0 * u
        # every section rests at its input (unity DC gain), derivatives zero
        x0 = jnp.stack([u, zero, u, zero, u, u, self.KS * u])
        return x0, zero

    def rhs(self, x, meas, ref):
        return self._f(x, meas)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas)[0]
