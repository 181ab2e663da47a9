"""ST2CUT: the dual-input stabilizer with output cutoff (PSS/E `ST2CUT`, ICONs ICS1,
IB1, ICS2, IB2; CONs K1, K2, T1, T2, T3, T4, T5, T6, T7, T8, T9, T10, LSMAX, LSMIN,
VCU, VCL; ANDES `ST2CUT`).

    u_i  = the signal of code ICSi: 0 none (u = 0), 1 speed deviation omega (pu),
           3 electrical power Pe (pu machine base), 5 terminal voltage Vt (pu)
    x_1: T1 dx_1/dt = K1 u_1 - x_1                       transducer 1, K1/(1 + s T1)
    x_2: T2 dx_2/dt = K2 u_2 - x_2                       transducer 2, K2/(1 + s T2)
    x_w: T4 dx_w/dt = y_in - x_w,
         y_w = (T3/T4)(y_in - x_w)                       washout s T3/(1 + s T4),
                                                         y_in = y_1 + y_2
    three lead-lags (1 + s T5)/(1 + s T6), (1 + s T7)/(1 + s T8), (1 + s T9)/(1 + s T10)
    Vss = clip(y, LSMIN, LSMAX)                          output limiter (windup: an
                                                         algebraic clip)
    Vs  = Vss if VCL < Vt < VCU, else 0                  cutoff; VCU = 0 (VCL = 0): no
                                                         upper (lower) cutoff

Zero T1, T2 make the transducers algebraic (y_i = Ki u_i); T6 = 0 (T8, T10) with
T5 = 0 (T7, T9) drops a lead-lag; T4 must be > 0 (T3 = 0 then gives Vs = 0). ICS 2
(bus frequency), 4 (accelerating power) and 6 (voltage derivative) are refused.
IBi names the bus of a bus signal: it is ignored for ICS 0, 1 and 3 (as in PSS/E),
and must be 0 (the generator's terminal) for ICS 5. At rest the washout's output is
zero, so Vs0 = 0: `init` refuses another y0. `ref` is zeros (k,).

The cutoff compares Vt with VCU and VCL themselves, as IEEEST does (PSS/E draws
both the same way); ANDES 2.0's ST2CUT compares it with Vt0 + VCU and Vt0 + VCL.
ANDES also turns the washout into a lag 1/(1 + s T4) where T3 = 0; smibjax follows
the drawn transfer function (zero output).
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
    ordered,
    positive,
    proper,
    require_at_rest,
)
from .base import AbstractController, f64, i64

__all__ = ["ST2CUT", "stabilizer_signal"]

_CONS = DYR_MODELS["ST2CUT"][4:]  # the CONs after the ICONs ICS1, IB1, ICS2, IB2
SIGNALS = (0, 1, 3, 5)


def stabilizer_signal(ics, meas):
    """The stabilizer input of PSS/E input code `ics` (per device): 0 none, 1 speed
    deviation (pu), 3 electrical power (pu machine base), 5 terminal voltage (pu)."""
    return jnp.where(
        ics == 1,
        meas["omega"],
        jnp.where(ics == 3, meas["Pe"], jnp.where(ics == 5, meas["Vt"], 0.0)),
    )


def check_signals(model: str, pairs, arrays) -> None:
    """Refuse (one line) an input code smibjax cannot measure and a remote bus for a
    bus signal: `pairs` names (ICS field, IB field), `arrays` their values."""
    for (ics_name, ib_name), (ics, ib) in zip(pairs, arrays, strict=True):
        if not is_concrete(ics, ib):
            continue
        ics, ib = np.asarray(ics), np.asarray(ib)
        bad = ~np.isin(ics, SIGNALS)
        if bad.any():
            raise ParameterError(
                f"{model}.{ics_name} = {int(ics[bad][0])} is not supported: only 0 "
                "(none), 1 (speed deviation), 3 (electrical power) and 5 (terminal "
                "voltage)"
            )
        remote = (ics == 5) & (ib != 0)
        if remote.any():
            raise ParameterError(
                f"{model}.{ib_name} = {int(ib[remote][0])} is not supported: the "
                "voltage signal (ICS 5) is read at the generator's terminal only (0)"
            )


class ST2CUT(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    ICS1: np.ndarray = eqx.field(converter=i64)  # input codes and remote buses
    IB1: np.ndarray = eqx.field(converter=i64)
    ICS2: np.ndarray = eqx.field(converter=i64)
    IB2: np.ndarray = eqx.field(converter=i64)
    K1: np.ndarray = eqx.field(converter=f64)  # input gains (pu/pu)
    K2: np.ndarray = eqx.field(converter=f64)
    T1: np.ndarray = eqx.field(converter=f64)  # transducer time constants (s)
    T2: np.ndarray = eqx.field(converter=f64)
    T3: np.ndarray = eqx.field(converter=f64)  # washout numerator (s)
    T4: np.ndarray = eqx.field(converter=f64)  # washout denominator (s)
    T5: np.ndarray = eqx.field(converter=f64)  # lead-lags (s)
    T6: np.ndarray = eqx.field(converter=f64)
    T7: np.ndarray = eqx.field(converter=f64)
    T8: np.ndarray = eqx.field(converter=f64)
    T9: np.ndarray = eqx.field(converter=f64)
    T10: np.ndarray = eqx.field(converter=f64)
    LSMAX: np.ndarray = eqx.field(converter=f64)  # output limits (pu)
    LSMIN: np.ndarray = eqx.field(converter=f64)
    VCU: np.ndarray = eqx.field(converter=f64)  # voltage cutoff (pu; 0 = none)
    VCL: np.ndarray = eqx.field(converter=f64)

    inputs = ("omega", "Pe", "Vt")
    output = "Vs"
    state_names = ("x_1", "x_2", "x_w", "x_ll1", "x_ll2", "x_ll3")
    con_names = _CONS

    def __check_init__(self):
        check_signals(
            "ST2CUT",
            [("ICS1", "IB1"), ("ICS2", "IB2")],
            [(self.ICS1, self.IB1), (self.ICS2, self.IB2)],
        )
        check(
            self,
            [
                *nonneg("T1", "T2", "T3"),
                *positive("T4"),
                proper("T5", "T6"),
                proper("T7", "T8"),
                proper("T9", "T10"),
                ordered("LSMIN", "LSMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` holds ICS1, IB1, ICS2, IB2 (the ICONs) and the CONs."""
        icons = ("ICS1", "IB1", "ICS2", "IB2")
        return build_group(
            cls,
            gen_positions,
            [{**p, **{k: p.get(k, 0) for k in icons}} for p in params],
            (*icons, *cls.con_names),
        )

    def _f(self, x, meas):
        u1 = stabilizer_signal(self.ICS1, meas)
        u2 = stabilizer_signal(self.ICS2, meas)
        y1, d1 = lag(x[0], u1, self.K1, self.T1)
        y2, d2 = lag(x[1], u2, self.K2, self.T2)
        yin = y1 + y2
        yw = self.T3 / self.T4 * (yin - x[2])
        dw = (yin - x[2]) / self.T4
        y3, d3 = leadlag(x[3], yw, self.T5, self.T6)
        y4, d4 = leadlag(x[4], y3, self.T7, self.T8)
        y5, d5 = leadlag(x[5], y4, self.T9, self.T10)
        vss = jnp.clip(y5, self.LSMIN, self.LSMAX)
        vt = meas["Vt"]
        on = ((self.VCU == 0) | (vt < self.VCU)) & ((self.VCL == 0) | (vt > self.VCL))
        return jnp.where(on, vss, 0.0), jnp.stack([d1, d2, dw, d3, d4, d5])

    def init(self, y0, meas):
        require_at_rest(
            y0 == 0, "ST2CUT", "Vs0", y0, "a stabilizer with a washout rests at 0"
        )
        y1 = self.K1 * stabilizer_signal(self.ICS1, meas) + 0.0 * y0
        y2 = self.K2 * stabilizer_signal(self.ICS2, meas) + 0.0 * y0
        zero = 0.0 * y1
        return jnp.stack([y1, y2, y1 + y2, zero, zero, zero]), zero

    def rhs(self, x, meas, ref):
        return self._f(x, meas)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas)[0]
