"""EXST1: the IEEE type ST1 static (potential-source, controlled-rectifier) exciter
(PSS/E `EXST1`, CONs TR, VIMAX, VIMIN, TC, TB, KA, TA, VRMAX, VRMIN, KC, KF, TF;
ANDES `EXST1`).

    Vm: TR dVm/dt = Vt - Vm                              sensing lag (TR = 0: Vm = Vt)
    Vi  = clip(Vref - Vm - Vf + Vs, VIMIN, VIMAX)        input limiter (windup-free:
                                                         algebraic)
    x_ll: TB dx_ll/dt = Vi - x_ll, y = x_ll + (TC/TB)(Vi - x_ll)  lead-lag (1 + s TC)/(1 + s TB)
    Efd: TA dEfd/dt = KA y - Efd                         regulator, non-windup limits
                                                         [VRMIN - KC XadIfd, VRMAX - KC XadIfd]
    x_f: TF dx_f/dt = Efd - x_f,  Vf = (KF/TF)(Efd - x_f)    rate feedback s KF/(1 + s TF)

XadIfd is the field current (pu on the Xad base, the machine's measurement
"XadIfd"); KC is the rectifier's commutation drop. The regulator's limits are
non-windup (the state Efd is held at a limit while KA y pushes outwards). ANDES
2.0 instead clips the output of an unlimited KA/(1 + s TA) with a hard limiter and
feeds the rate feedback from the unlimited regulator output; the two agree inside
the limits, and smibjax's form is the one whose state cannot wind up. TA = 0 (only
with KF = 0, else an algebraic loop): Efd = clip(KA y); TB = 0 (with TC = 0): no
lead-lag; KF = 0: no feedback (TF may be 0).

The smibjax SMIB's "ST1A-like" exciter (`smibjax.controllers.avr_pss`) is the case
TR = 0, TC = TB, KC = 0, KF = 0, infinite VIMAX/VIMIN: Efd = KA/(1 + s TA)(Vref -
Vt + Vs) within non-windup [VRMIN, VRMAX].

At rest: y = Vi = Efd0/KA (which must lie within [VIMIN, VIMAX]), so Vref = Vt0 -
Vs0 + Efd0/KA, returned as `ref`.
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
    leadlag,
    nonneg,
    ordered,
    positive,
    proper,
    regulated,
    require_at_rest,
    v,
    washout,
)
from .base import AbstractController, f64, i64

__all__ = ["EXST1"]


class EXST1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    VIMAX: np.ndarray = eqx.field(converter=f64)  # input limits (pu)
    VIMIN: np.ndarray = eqx.field(converter=f64)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KC: np.ndarray = eqx.field(converter=f64)  # commutation factor (pu)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)

    inputs = ("Vt", "Vs", "XadIfd")
    output = "Efd"
    state_names = ("Vm", "x_ll", "Efd", "x_f")
    con_names = DYR_MODELS["EXST1"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "TA", "KC", "KF"),
                *positive("KA"),
                proper("TC", "TB"),
                ordered("VIMIN", "VIMAX"),
                ordered("VRMIN", "VRMAX"),
                (
                    "TF",
                    lambda o: (v(o, "TF") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0",
                ),
                (
                    "TA",
                    lambda o: (v(o, "TA") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0 (else an algebraic loop)",
                ),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _limits(self, meas):
        drop = self.KC * meas["XadIfd"]
        return self.VRMIN - drop, self.VRMAX - drop

    def init(self, y0, meas):
        lo, hi = self._limits(meas)
        vi0 = y0 / self.KA
        require_at_rest(
            (y0 >= lo) & (y0 <= hi) & (vi0 >= self.VIMIN) & (vi0 <= self.VIMAX),
            "EXST1",
            "Efd0",
            y0,
            "the operating point needs Efd0 within [VRMIN - KC XadIfd, VRMAX - KC "
            "XadIfd] and Efd0/KA within [VIMIN, VIMAX]",
        )
        ref = regulated(meas) - meas["Vs"] + vi0
        zero = 0.0 * y0
        vt = regulated(meas) + zero
        vi0 = ref - vt - zero + meas["Vs"]  # as rhs computes it
        efd0 = self.KA * vi0
        return jnp.stack([vt, vi0, efd0, efd0]), ref

    def _f(self, x, meas, ref):
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        vf, dxf = washout(x[3], x[2], self.KF, self.TF)
        vi = jnp.clip(ref - vm - vf + meas["Vs"], self.VIMIN, self.VIMAX)
        y, dll = leadlag(x[1], vi, self.TC, self.TB)
        lo, hi = self._limits(meas)
        efd, defd = lag_nonwindup(
            x[2], y, self.KA, self.TA, lo, hi, moving=self.KC != 0
        )
        return efd, jnp.stack([dvm, dll, defd, dxf])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
