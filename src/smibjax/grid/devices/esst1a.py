"""ESST1A: the IEEE 421.5-2005 type ST1A potential-source controlled-rectifier
exciter (PSS/E `ESST1A`; ICONs UEL, VOS, then CONs TR, VIMAX, VIMIN, TC, TB, TC1,
TB1, KA, TA, VAMAX, VAMIN, VRMAX, VRMIN, KC, KF, TF, KLR, ILR, in PSS/E's order:
the order of the Australian 14-generator case's records; ANDES 2.0's psse-dyr.yaml
lists them in another order, which those records do not fit).

    Vm: TR dVm/dt = Vc - Vm                        sensing lag (TR = 0: Vm = Vc)
    Vi  = clip(Vref - Vm - VF + [VOS = 1] Vs, VIMIN, VIMAX)      input limiter
    x1: TB dx1/dt = Vi - x1,  y1 = x1 + (TC/TB)(Vi - x1)          lead-lag 1
    x2: TB1 dx2/dt = y1 - x2, y2 = x2 + (TC1/TB1)(y1 - x2)        lead-lag 2
    VA: TA dVA/dt = KA y2 - VA                     regulator, non-windup [VAMIN, VAMAX]
    ILR = max(KLR (XadIfd - ILR), 0)               field current limiter
    Vsum = VA - ILR + [VOS = 2] Vs
    Efd = clip(Vsum, Vt VRMIN, Vt VRMAX - KC XadIfd)   bus-fed bridge ceiling
    x_f: TF dx_f/dt = Vsum - x_f,  VF = (KF/TF)(Vsum - x_f)       rate feedback

Vc is the regulated voltage (the compensator's, else Vt), Vt the terminal voltage,
XadIfd the machine's field current (pu on the Xad base). The regulator's limits
are non-windup (drawn on the KA/(1 + s TA) block); the input limiter and the output
ceilings are algebraic (windup). The rate feedback takes the signal in front of
the output limiter (PowerSimulationsDynamics.jl's reading of PSS/E's diagram,
checked there against PSS/E's own results; `tests/data/psse/ESST1A`). UEL selects
where an under-excitation limiter would enter: smibjax has no UEL model, so the
HV/LV gates pass the regulator's signal through and UEL is kept as data. VOS
selects where the stabilizer enters: 1 at the voltage reference, 2 at the
regulator's output. TA = 0 makes the regulator algebraic and is refused where KF
!= 0 (an algebraic loop through the rate feedback).

At rest (`init`): VA0 = Efd0 + ILR0 - [VOS = 2] Vs0, Vi0 = VA0/KA (both lead-lags
pass it), Vref = Vc0 + Vi0 - [VOS = 1] Vs0 (returned as `ref`); VA0, Vi0 and Efd0
must lie within their limits.
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

__all__ = ["ESST1A"]


class ESST1A(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    UEL: np.ndarray = eqx.field(converter=f64)  # UEL input code 1..3 (no UEL: unused)
    VOS: np.ndarray = eqx.field(converter=f64)  # stabilizer input: 1 Vref, 2 output
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    VIMAX: np.ndarray = eqx.field(converter=f64)  # input limits (pu)
    VIMIN: np.ndarray = eqx.field(converter=f64)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 lead (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 lag (s)
    TC1: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 lead (s)
    TB1: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 lag (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VAMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VAMIN: np.ndarray = eqx.field(converter=f64)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # output limits (pu, x Vt)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    KLR: np.ndarray = eqx.field(converter=f64)  # field current limiter gain (pu)
    ILR: np.ndarray = eqx.field(converter=f64)  # field current limit (pu)

    inputs = ("Vt", "Vs", "XadIfd")
    output = "Efd"
    state_names = ("Vm", "x_ll1", "x_ll2", "VA", "x_f")
    con_names = DYR_MODELS["ESST1A"]

    def __check_init__(self):
        check(
            self,
            [
                (
                    "UEL",
                    lambda o: np.isin(v(o, "UEL"), (1.0, 2.0, 3.0)),
                    "must be 1, 2 or 3",
                ),
                ("VOS", lambda o: np.isin(v(o, "VOS"), (1.0, 2.0)), "must be 1 or 2"),
                *nonneg("TR", "TA", "KC", "KF", "KLR"),
                *positive("KA"),
                proper("TC", "TB"),
                proper("TC1", "TB1"),
                ordered("VIMIN", "VIMAX"),
                ordered("VAMIN", "VAMAX"),
                ordered("VRMIN", "VRMAX"),
                (
                    "TF",
                    lambda o: (v(o, "TF") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0",
                ),
                (
                    "TA",
                    lambda o: (v(o, "TA") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0 (else an algebraic loop through "
                    "the rate feedback)",
                ),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _ilr(self, ifd):
        """The field current limiter's signal max(KLR (XadIfd - ILR), 0) (pu)."""
        return jnp.maximum(self.KLR * (ifd - self.ILR), 0.0)

    def _ceilings(self, meas):
        vt = meas["Vt"]
        return vt * self.VRMIN, vt * self.VRMAX - self.KC * meas["XadIfd"]

    def init(self, y0, meas):
        vos1, vos2 = self.VOS == 1, self.VOS == 2
        vs = meas["Vs"]
        va0 = y0 + self._ilr(meas["XadIfd"]) - jnp.where(vos2, vs, 0.0)
        vi0 = va0 / self.KA
        lo, hi = self._ceilings(meas)
        require_at_rest(
            (va0 >= self.VAMIN)
            & (va0 <= self.VAMAX)
            & (vi0 >= self.VIMIN)
            & (vi0 <= self.VIMAX)
            & (y0 >= lo)
            & (y0 <= hi),
            "ESST1A",
            "Efd0",
            y0,
            "the operating point needs VA0 = Efd0 + ILR0 within [VAMIN, VAMAX], "
            "VA0/KA within [VIMIN, VIMAX] and Efd0 within [Vt VRMIN, Vt VRMAX - "
            "KC XadIfd]",
        )
        vc = regulated(meas) + 0.0 * y0
        ref = vc + vi0 - jnp.where(vos1, vs, 0.0)
        vi = ref - vc + jnp.where(vos1, vs, 0.0)  # as rhs computes it
        va = self.KA * vi
        vsum = va - self._ilr(meas["XadIfd"]) + jnp.where(vos2, vs, 0.0)
        return jnp.stack([vc, vi, vi, va, vsum]), ref

    def _f(self, x, meas, ref):
        vs = meas["Vs"]
        vos1, vos2 = self.VOS == 1, self.VOS == 2
        ilr = self._ilr(meas["XadIfd"])
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        # the rate feedback from the regulator's state (TA > 0 wherever KF != 0;
        # where KF = 0 its state is frozen)
        on = self.KF != 0
        vsum_fb = (
            jnp.clip(x[3], self.VAMIN, self.VAMAX) - ilr + jnp.where(vos2, vs, 0.0)
        )
        vf, dxf = washout(x[4], jnp.where(on, vsum_fb, x[4]), self.KF, self.TF)
        vi = jnp.clip(ref - vm - vf + jnp.where(vos1, vs, 0.0), self.VIMIN, self.VIMAX)
        y1, d1 = leadlag(x[1], vi, self.TC, self.TB)
        y2, d2 = leadlag(x[2], y1, self.TC1, self.TB1)
        va, dva = lag_nonwindup(x[3], y2, self.KA, self.TA, self.VAMIN, self.VAMAX)
        vsum = va - ilr + jnp.where(vos2, vs, 0.0)
        lo, hi = self._ceilings(meas)
        efd = jnp.minimum(jnp.maximum(vsum, lo), hi)
        return efd, jnp.stack([dvm, d1, d2, dva, dxf])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
