"""PSS2A and PSS2B: the IEEE dual-input stabilizers (PSS/E `PSS2A`, ICONs ICS1,
IB1, ICS2, IB2, M, N; CONs TW1, TW2, T6, TW3, TW4, T7, KS2, KS3, T8, T9, KS1, T1,
T2, T3, T4, VSTMAX, VSTMIN; `PSS2B` adds T10, T11 and the input limits VS1MAX,
VS1MIN, VS2MAX, VS2MIN before VSTMAX, VSTMIN; not in ANDES).

    u_i  = the signal of code ICSi (0 none, 1 omega, 3 Pe, 5 Vt; as ST2CUT)
           PSS2B: u_i clipped to [VSiMIN, VSiMAX] (windup: an algebraic clip)
    y1 = sTW1/(1 + sTW1) sTW2/(1 + sTW2) 1/(1 + sT6) u1        channel 1
    y2 = sTW3/(1 + sTW3) sTW4/(1 + sTW4) KS2/(1 + sT7) u2      channel 2
    z  = [(1 + sT8)/(1 + sT9)^M]^N (y1 + KS3 y2)              ramp-tracking filter
    v  = KS1 (z - y2) (1 + sT1)/(1 + sT2) (1 + sT3)/(1 + sT4)
         PSS2B: times (1 + sT10)/(1 + sT11)
    Vs = clip(v, VSTMIN, VSTMAX)                               (windup: an algebraic clip)

(IEEE Std 421.5-2005, section 9, types PSS2A and PSS2B; PSS/E Model Library.)
The ramp-tracking filter is realized as N * M first-order blocks, the first of each
of the N stages the lead-lag (1 + sT8)/(1 + sT9) and the other M - 1 the lag
1/(1 + sT9); M * N must be at most 8 (the states are fixed per group: 8 filter
states, unused ones placeholders with zero derivative), M = 0 or N = 0 bypasses the
filter. TW1 and TW3 must be > 0; TW2 = 0 (TW4 = 0) bypasses the second washout of
its channel, T6, T7 = 0 make their lags algebraic, T9 > 0 where the filter is used.
IBi is ignored for codes 0, 1, 3 and must be 0 for code 5. At rest every washout's
output is zero: Vs0 = 0, and `ref` is zeros (k,).
"""

from __future__ import annotations

from typing import ClassVar

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
    ordered,
    positive,
    proper,
    require_at_rest,
    v,
)
from .base import AbstractController, f64, i64
from .st2cut import check_signals, stabilizer_signal

__all__ = ["PSS2A", "PSS2B"]

RAMP = 8  # ramp-tracking filter states (M * N <= 8)


def _washout_or_bypass(x, u, T):
    """sT/(1 + sT) (T dx/dt = u - x, y = u - x); T = 0: y = u (bypassed)."""
    on = T > 0
    y = jnp.where(on, u - x, u)
    return y, jnp.where(on, (u - x) / jnp.where(on, T, 1.0), 0.0)


def _ramp_filter(xs, u, T8, T9, M, N):
    """[(1 + sT8)/(1 + sT9)^M]^N as RAMP first-order blocks; returns (y, [dx])."""
    Ms = jnp.maximum(M, 1)
    used = M * N
    y, dxs = u, []
    for j in range(RAMP):
        active = j < used
        lead = jnp.where(j % Ms == 0, T8, 0.0)
        yj, dj = leadlag(xs[j], y, lead, T9)
        y = jnp.where(active, yj, y)
        dxs.append(jnp.where(active, dj, 0.0))
    return y, dxs


class PSS2A(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    ICS1: np.ndarray = eqx.field(converter=i64)  # input codes and remote buses
    IB1: np.ndarray = eqx.field(converter=i64)
    ICS2: np.ndarray = eqx.field(converter=i64)
    IB2: np.ndarray = eqx.field(converter=i64)
    M: np.ndarray = eqx.field(converter=i64)  # ramp-tracking filter orders
    N: np.ndarray = eqx.field(converter=i64)
    TW1: np.ndarray = eqx.field(converter=f64)  # washouts, channel 1 (s)
    TW2: np.ndarray = eqx.field(converter=f64)
    T6: np.ndarray = eqx.field(converter=f64)  # channel 1 lag (s)
    TW3: np.ndarray = eqx.field(converter=f64)  # washouts, channel 2 (s)
    TW4: np.ndarray = eqx.field(converter=f64)
    T7: np.ndarray = eqx.field(converter=f64)  # channel 2 lag (s)
    KS2: np.ndarray = eqx.field(converter=f64)  # channel 2 gain
    KS3: np.ndarray = eqx.field(converter=f64)  # channel 2 gain into the filter
    T8: np.ndarray = eqx.field(converter=f64)  # ramp-tracking filter (s)
    T9: np.ndarray = eqx.field(converter=f64)
    KS1: np.ndarray = eqx.field(converter=f64)  # stabilizer gain
    T1: np.ndarray = eqx.field(converter=f64)  # lead-lags (s)
    T2: np.ndarray = eqx.field(converter=f64)
    T3: np.ndarray = eqx.field(converter=f64)
    T4: np.ndarray = eqx.field(converter=f64)
    VSTMAX: np.ndarray = eqx.field(converter=f64)  # output limits (pu)
    VSTMIN: np.ndarray = eqx.field(converter=f64)

    inputs = ("omega", "Pe", "Vt")
    output = "Vs"
    state_names: ClassVar[tuple[str, ...]] = (
        "x_w1",
        "x_w2",
        "x_6",
        "x_w3",
        "x_w4",
        "x_7",
        *(f"x_r{j + 1}" for j in range(RAMP)),
        "x_ll1",
        "x_ll2",
    )
    con_names = DYR_MODELS["PSS2A"][6:]
    icons: ClassVar[tuple[str, ...]] = ("ICS1", "IB1", "ICS2", "IB2", "M", "N")

    def _rules(self):
        return [
            *positive("TW1", "TW3"),
            *nonneg("TW2", "TW4", "T6", "T7", "T8", "T9"),
            proper("T1", "T2"),
            proper("T3", "T4"),
            ordered("VSTMIN", "VSTMAX"),
        ]

    def __check_init__(self):
        name = type(self).__name__
        check_signals(
            name,
            [("ICS1", "IB1"), ("ICS2", "IB2")],
            [(self.ICS1, self.IB1), (self.ICS2, self.IB2)],
        )
        if is_concrete(self.M, self.N):
            m, n = np.asarray(self.M), np.asarray(self.N)
            bad = (m < 0) | (n < 0) | (m * n > RAMP)
            if bad.any():
                raise ParameterError(
                    f"{name}.M = {int(m[bad][0])}, N = {int(n[bad][0])} is not "
                    f"supported: M, N >= 0 and M * N <= {RAMP}"
                )
        check(self, self._rules())
        if is_concrete(self.M, self.N, self.T9):
            used = np.asarray(self.M) * np.asarray(self.N) > 0
            check(
                self,
                [
                    (
                        "T9",
                        lambda o: (v(o, "T9") > 0) | ~used,
                        "must be > 0 where the ramp-tracking filter is used (M, N > 0)",
                    )
                ],
            )

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` holds the ICONs ICS1, IB1, ICS2, IB2, M, N and the CONs."""
        return build_group(
            cls,
            gen_positions,
            [{**p, **{k: p.get(k, 0) for k in cls.icons}} for p in params],
            (*cls.icons, *cls.con_names),
        )

    def _inputs(self, meas):
        return stabilizer_signal(self.ICS1, meas), stabilizer_signal(self.ICS2, meas)

    def _tail(self, x, v):
        """The lead-lags after KS1 (PSS2B adds one): (output, [dx])."""
        y1, d1 = leadlag(x[14], v, self.T1, self.T2)
        y2, d2 = leadlag(x[15], y1, self.T3, self.T4)
        return y2, [d1, d2]

    def _f(self, x, meas):
        u1, u2 = self._inputs(meas)
        a, d0 = _washout_or_bypass(x[0], u1, self.TW1)
        a, d1 = _washout_or_bypass(x[1], a, self.TW2)
        y1, d2 = lag(x[2], a, 1.0, self.T6)
        b, d3 = _washout_or_bypass(x[3], u2, self.TW3)
        b, d4 = _washout_or_bypass(x[4], b, self.TW4)
        y2, d5 = lag(x[5], b, self.KS2, self.T7)
        z, dr = _ramp_filter(
            x[6 : 6 + RAMP], y1 + self.KS3 * y2, self.T8, self.T9, self.M, self.N
        )
        out, dt = self._tail(x, self.KS1 * (z - y2))
        vs = jnp.clip(out, self.VSTMIN, self.VSTMAX)
        return vs, jnp.stack([d0, d1, d2, d3, d4, d5, *dr, *dt])

    def init(self, y0, meas):
        name = type(self).__name__
        require_at_rest(
            y0 == 0, name, "Vs0", y0, "a stabilizer with washouts rests at 0"
        )
        u1, u2 = self._inputs(meas)
        u1, u2 = u1 + 0.0 * y0, u2 + 0.0 * y0
        zero = 0.0 * u1
        # each channel's first washout holds its input; everything after it rests at 0
        x0 = [u1, zero, zero, u2] + [zero] * (len(self.state_names) - 4)
        return jnp.stack(x0), zero

    def rhs(self, x, meas, ref):
        return self._f(x, meas)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas)[0]


class PSS2B(PSS2A):
    T10: np.ndarray = eqx.field(converter=f64)  # third lead-lag (s)
    T11: np.ndarray = eqx.field(converter=f64)
    VS1MAX: np.ndarray = eqx.field(converter=f64)  # input limits (pu)
    VS1MIN: np.ndarray = eqx.field(converter=f64)
    VS2MAX: np.ndarray = eqx.field(converter=f64)
    VS2MIN: np.ndarray = eqx.field(converter=f64)

    state_names: ClassVar[tuple[str, ...]] = (*PSS2A.state_names, "x_ll3")
    con_names = DYR_MODELS["PSS2B"][6:]

    def _rules(self):
        return [
            *super()._rules(),
            proper("T10", "T11"),
            ordered("VS1MIN", "VS1MAX"),
            ordered("VS2MIN", "VS2MAX"),
        ]

    def _inputs(self, meas):
        u1, u2 = super()._inputs(meas)
        return (
            jnp.clip(u1, self.VS1MIN, self.VS1MAX),
            jnp.clip(u2, self.VS2MIN, self.VS2MAX),
        )

    def _tail(self, x, v):
        y, ds = super()._tail(x, v)
        y3, d3 = leadlag(x[16], y, self.T10, self.T11)
        return y3, [*ds, d3]
