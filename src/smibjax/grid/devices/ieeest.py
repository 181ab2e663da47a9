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

States (always 7): the filter as two cascaded second-order sections in
controllable form, 1/(1 + b1 s + b2 s^2) in (f1, f2) and (1 + A5 s + A6 s^2)/(1 +
a3 s + a4 s^2) in (f3, f4), then the lead-lags (x_ll1, x_ll2) and the washout (x_w).
PSS/E draws (b1, b2) = (A1, A2), (a3, a4) = (A3, A4); where that second factor is of
too low a degree for the numerator (A3 = A4 = 0 with A5 or A6 != 0, valid PSS/E data
when the first factor carries the poles) the factors are swapped, and where each
factor is of degree 1 under a numerator of degree 2 the numerator goes over their
product (`filter_sections`): the transfer function is F(s) in every case. Zero
coefficients lower a section's order (b2 = 0: a first-order lag; b1 = b2 = 0: a
pass-through) and leave its unused states as placeholders with zero derivative, so
the state count is fixed per group. An improper F (numerator of higher degree than
the whole denominator), T2 = 0 with T1 != 0, T4 = 0 with T3 != 0, or T6 = 0 is
refused. ANDES splits the filter as `Lag2ndOrd` then `LeadLag2ndOrd` without the
swap, so it cannot run A3 = A4 = 0 with A6 != 0.

Only ICS 1 and 3 are supported (the others need bus frequency, accelerating power
or voltage derivatives from other models). IB, the remote bus, is read and ignored:
PSS/E uses it only for the bus signals (ICS 2, 5, 6). At rest the washout's output
is zero, so Vs0 = 0: `init` refuses another y0. `ref` is zeros (k,).
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


def _degree(a, b):
    """The degree of 1 + a s + b s^2 (a, b >= 0; NumPy or JAX)."""
    return jnp.where(b != 0, 2, jnp.where(a != 0, 1, 0))


def _den_degree(o):
    """The degree of the filter's denominator (NumPy, for the checks)."""

    def deg(a, b):
        return np.where(v(o, b) != 0, 2, np.where(v(o, a) != 0, 1, 0))

    return deg("A1", "A2") + deg("A3", "A4")


FILTER_RULES = [
    (
        "A6",
        lambda o: (v(o, "A6") == 0) | (_den_degree(o) >= 2),
        "must be 0 where the filter's denominator (1 + A1 s + A2 s^2)"
        "(1 + A3 s + A4 s^2) is of degree < 2 (the filter would be "
        "improper)",
    ),
    (
        "A5",
        lambda o: (v(o, "A5") == 0) | (_den_degree(o) >= 1),
        "must be 0 where A1 = A2 = A3 = A4 = 0 (the filter would be improper)",
    ),
]


def filter_sections(A1, A2, A3, A4, A5, A6):
    """The filter F(s) split into two proper second-order sections, 1/(1 + b1 s + b2
    s^2) then (1 + A5 s + A6 s^2)/(1 + a3 s + a4 s^2): returns (b1, b2, a3, a4).

    The numerator goes over the denominator factor (1 + A3 s + A4 s^2) when that is
    of high enough degree (PSS/E's drawing), else over (1 + A1 s + A2 s^2) (the
    factors commute), else, when each factor is of degree 1 and the numerator of
    degree 2 (A2 = A4 = 0, A6 != 0), over their product 1 + (A1 + A3) s + A1 A3 s^2
    with a pass-through first section. The transfer function is F(s) in every case.
    """
    n = jnp.where(A6 != 0, 2, jnp.where(A5 != 0, 1, 0))
    d1, d2 = _degree(A1, A2), _degree(A3, A4)
    keep = d2 >= n
    swap = ~keep & (d1 >= n)
    zero = 0.0 * A1
    b1 = jnp.where(keep, A1, jnp.where(swap, A3, zero))
    b2 = jnp.where(keep, A2, jnp.where(swap, A4, zero))
    a3 = jnp.where(keep, A3, jnp.where(swap, A1, A1 + A3))
    a4 = jnp.where(keep, A4, jnp.where(swap, A2, A1 * A3))
    return b1, b2, a3, a4


class IEEEST(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    ICS: np.ndarray = eqx.field(converter=i64)  # input code: 1 speed, 3 Pe
    IB: np.ndarray = eqx.field(converter=i64)  # remote bus (unused for ICS 1, 3)
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
            ics = np.asarray(self.ICS)
            bad = ~np.isin(ics, (1, 3))
            if bad.any():
                raise ParameterError(
                    f"IEEEST.ICS = {int(ics[bad][0])} is not supported: only 1 (speed "
                    "deviation) and 3 (electrical power)"
                )
        check(
            self,
            [
                *nonneg("A1", "A2", "A3", "A4", "A5", "A6", "T5"),
                *positive("T6"),
                proper("T1", "T2"),
                proper("T3", "T4"),
                ordered("LSMIN", "LSMAX"),
            ],
        )
        if is_concrete(*(getattr(self, f"A{i}") for i in range(1, 7))):
            check(self, FILTER_RULES)  # rules that read every A: all concrete

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` holds ICS and IB (the ICONs) and the CONs."""
        return build_group(
            cls,
            gen_positions,
            [{**p, "ICS": p.get("ICS"), "IB": p.get("IB", 0)} for p in params],
            ("ICS", "IB", *cls.con_names),
        )

    def _sections(self):
        return filter_sections(self.A1, self.A2, self.A3, self.A4, self.A5, self.A6)

    def signal(self, meas):
        """The stabilizer's input: speed deviation (ICS 1) or Pe (ICS 3)."""
        return jnp.where(self.ICS == 1, meas["omega"], meas["Pe"])

    def _f(self, x, meas):
        u = self.signal(meas)
        b1, b2, a3, a4 = self._sections()
        y1, d1, d2 = second_order_lag(x[0], x[1], u, b1, b2)
        y2, d3, d4 = second_order_leadlag(x[2], x[3], y1, a3, a4, self.A5, self.A6)
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
        b1, b2, a3, a4 = self._sections()
        y1, _, _ = second_order_lag(x[0], x[1], u, b1, b2)
        y2, _, _ = second_order_leadlag(x[2], x[3], y1, a3, a4, self.A5, self.A6)
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
