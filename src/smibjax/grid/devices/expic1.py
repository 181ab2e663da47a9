"""EXPIC1: the proportional/integral excitation system (PSS/E `EXPIC1`, CONs TR,
KA, TA1, VR1, VR2, TA2, TA3, TA4, VRMAX, VRMIN, KF, TF1, TF2, EFDMAX, EFDMIN, KE,
TE, E1, SE(E1), E2, SE(E2), KP, KI, KC; ANDES 2.0 lists the same CONs and reads
the model as an SEXS, PSID and OpenIPSL have none).

    Vm: TR dVm/dt = Vc - Vm                          sensing lag (TR = 0: Vm = Vc)
    e   = Vref - Vm + Vs - VF
    VA  = clip(KA TA1 e + x_a, VR2, VR1),  dx_a/dt = KA e     PI KA (1 + s TA1)/s,
                                                             non-windup
    y   = (1 + s TA3) / ((1 + s TA2)(1 + s TA4)) VA          regulator filter
    VR  = clip(y, VRMIN, VRMAX)
    VF  = KF s / ((1 + s TF1)(1 + s TF2)) VR                 rate feedback from VR
    VE  = |KP Vt + j KI It|,  VB = VE FEX(KC XadIfd / VE)    (KP = KI = 0: VB = 1)
    E0  = clip(VB VR, EFDMIN, EFDMAX)
    TE dEfd/dt = E0 - (KE + SE(Efd)) Efd                     exciter (TE = 0: Efd = E0)

Vt and It are the terminal voltage and current phasors (It on the machine base),
XadIfd the field current (pu on the Xad base), SE PSS/E's quadratic exciter
saturation through (E1, SE(E1)), (E2, SE(E2)) (`ieeex1.saturation_coefficients`;
E1 SE(E1) = 0: none). The filter with one of TA2, TA4 zero is (1 + s TA3)/(1 + s
(TA2 + TA4)); with both zero it is bypassed (TA3 unused); the feedback with one of
TF1, TF2 zero is s/(1 + s (TF1 + TF2)). Sources: the block diagram as PowerWorld
documents it and OPAL-RT's ePHASORsim Modelica library implements it
(karlbenoit-at-opal/modelica-ephasor-components, `OpalRT/Electrical/Control/
Excitation/EXPIC1.mo`), no program's results: the model is checked against its
own closed forms. The PI's limits VR1, VR2 are taken as non-windup (IEEE 421.5's
PI, as ESST4B's, the model EXPIC1 data are translated from in ACTIVSg2000);
OPAL-RT's library clips the PI's output and lets its integrator run on (windup).
VRMAX/VRMIN and EFDMAX/EFDMIN are algebraic clips.

KF != 0 is refused where the PI (TA1 != 0) and the filter both pass their input
straight through (an algebraic loop through the rate feedback).

At rest (`init`): the PI's input is zero and its integrator holds its output:
VB0 from the measured phasors, E0 = (KE + SE(Efd0)) Efd0 (TE > 0; TE = 0: E0 =
Efd0), VR0 = VA0 = x_a = E0/VB0, Vref = Vc0 - Vs0 (returned as `ref`); VA0 within
[VR2, VR1] and [VRMIN, VRMAX], E0 within [EFDMIN, EFDMAX].
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    fex,
    lag,
    nonneg,
    ordered,
    positive,
    regulated,
    require_at_rest,
    second_order_leadlag,
    v,
    washout,
)
from .base import AbstractController, f64, i64
from .esst4b import pi_nonwindup
from .exac1 import exciter_saturation_rule
from .ieeex1 import saturation_coefficients

__all__ = ["EXPIC1"]


def _filter_feedthrough(ta2, ta3, ta4):
    """The high-frequency gain of (1 + s TA3)/((1 + s TA2)(1 + s TA4)) as EXPIC1
    reads it: 0 with two lags, TA3/(TA2 + TA4) with one, 1 bypassed."""
    both = (ta2 > 0) & (ta4 > 0)
    one = ~both & (ta2 + ta4 > 0)
    return np.where(both, 0.0, np.where(one, ta3 / np.where(one, ta2 + ta4, 1), 1.0))


class EXPIC1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KA: np.ndarray = eqx.field(converter=f64)  # PI gain (pu/pu/s)
    TA1: np.ndarray = eqx.field(converter=f64)  # PI lead time constant (s)
    VR1: np.ndarray = eqx.field(converter=f64)  # PI limits (pu)
    VR2: np.ndarray = eqx.field(converter=f64)
    TA2: np.ndarray = eqx.field(converter=f64)  # filter lag (s)
    TA3: np.ndarray = eqx.field(converter=f64)  # filter lead (s)
    TA4: np.ndarray = eqx.field(converter=f64)  # filter lag (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF1: np.ndarray = eqx.field(converter=f64)  # rate feedback time constants (s)
    TF2: np.ndarray = eqx.field(converter=f64)
    EFDMAX: np.ndarray = eqx.field(converter=f64)  # exciter input limits (pu)
    EFDMIN: np.ndarray = eqx.field(converter=f64)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (pu)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s; 0: none)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)
    KP: np.ndarray = eqx.field(converter=f64)  # potential source gain (pu/pu)
    KI: np.ndarray = eqx.field(converter=f64)  # current source gain (pu/pu)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)

    inputs = ("Vt", "Vs", "XadIfd", "Vt_re", "Vt_im", "It_re", "It_im")
    output = "Efd"
    state_names = ("Vm", "x_a", "x_f1", "x_f2", "x_v1", "x_v2", "Efd")
    con_names = DYR_MODELS["EXPIC1"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "TA1", "TA2", "TA3", "TA4", "KF", "TF1", "TF2", "TE"),
                *nonneg("KP", "KI", "KC"),
                *positive("KA"),
                ordered("VR2", "VR1"),
                ordered("VRMIN", "VRMAX"),
                ordered("EFDMIN", "EFDMAX"),
                (
                    "TF1",
                    lambda o: (v(o, "KF") == 0) | (v(o, "TF1") + v(o, "TF2") > 0),
                    "must be > 0 (or TF2 > 0) where KF != 0 (else a pure derivative)",
                ),
                (
                    "KF",
                    lambda o: (
                        (v(o, "KF") == 0)
                        | (v(o, "TA1") == 0)
                        | (
                            _filter_feedthrough(v(o, "TA2"), v(o, "TA3"), v(o, "TA4"))
                            == 0
                        )
                    ),
                    "must be 0 where TA1 != 0 and the filter TA2, TA3, TA4 passes its "
                    "input straight through (an algebraic loop)",
                ),
                exciter_saturation_rule(),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def vb(self, meas):
        """VB = VE FEX(KC XadIfd / VE), VE = |KP Vt + j KI It| (pu); KP = KI = 0:
        VB = 1."""
        vt = meas["Vt_re"] + 1j * meas["Vt_im"]
        it = meas["It_re"] + 1j * meas["It_im"]
        ve = jnp.abs(self.KP * vt + 1j * self.KI * it)
        safe = jnp.where(ve > 0, ve, 1.0)
        i_n = jnp.where(ve > 0, self.KC * meas["XadIfd"] / safe, 2.0)
        none = (self.KP == 0) & (self.KI == 0)
        return jnp.where(none, 1.0, ve * fex(i_n))

    def se_efd(self, efd):
        """SE(Efd) Efd (pu): PSS/E's quadratic exciter saturation."""
        A, B = saturation_coefficients(self.E1, self.SE1, self.E2, self.SE2)
        return B * jnp.maximum(efd - A, 0.0) ** 2

    def _feedback(self, xv1, xv2, vr):
        """(VF, dx_v1, dx_v2): KF s/((1 + s TF1)(1 + s TF2)) of VR, as a lag
        TF1 then a washout TF2 (one of them zero: the washout TF1 + TF2)."""
        both = (self.TF1 > 0) & (self.TF2 > 0)
        t_lag = jnp.where(both, self.TF1, 0.0)
        t_wo = jnp.where(both, self.TF2, self.TF1 + self.TF2)
        u, dv1 = lag(xv1, vr, 1.0, t_lag)
        vf, dv2 = washout(xv2, u, self.KF, t_wo)
        return vf, dv1, dv2

    def _regulator(self, x, e):
        """(VR, dx_a, dx_f1, dx_f2) for the PI's input e."""
        va, dxa = pi_nonwindup(x[1], e, self.KA * self.TA1, self.KA, self.VR2, self.VR1)
        y, df1, df2 = second_order_leadlag(
            x[2], x[3], va, self.TA2 + self.TA4, self.TA2 * self.TA4, self.TA3, 0.0
        )
        return jnp.clip(y, self.VRMIN, self.VRMAX), dxa, df1, df2

    def init(self, y0, meas):
        vb0 = self.vb(meas)
        e0 = jnp.where(self.TE > 0, self.KE * y0 + self.se_efd(y0), y0)
        safe = jnp.where(vb0 > 0, vb0, 1.0)
        va0 = e0 / safe
        require_at_rest(
            (vb0 > 0)
            & (va0 >= self.VR2)
            & (va0 <= self.VR1)
            & (va0 >= self.VRMIN)
            & (va0 <= self.VRMAX)
            & (e0 >= self.EFDMIN)
            & (e0 <= self.EFDMAX),
            "EXPIC1",
            "Efd0",
            y0,
            "the operating point needs VB0 > 0, VA0 = E0/VB0 within [VR2, VR1] and "
            "[VRMIN, VRMAX] and E0 = (KE + SE(Efd0)) Efd0 within [EFDMIN, EFDMAX]",
        )
        vc = regulated(meas) + 0.0 * y0
        ref = vc - meas["Vs"]
        # the filter at rest: (x1, x2) = (VA0, 0); the feedback's states at VR0
        zero = 0.0 * y0
        x = jnp.stack([vc, va0, va0 + zero, zero, va0 + zero, va0 + zero, y0 + zero])
        return x, ref

    def _f(self, x, meas, ref):
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        e_open = ref - vm + meas["Vs"]
        # the rate feedback: VR does not depend on this instant's e wherever KF !=
        # 0 (checked), so VR from the open-loop error is VR
        vr_fb = self._regulator(x, e_open)[0]
        vf, dv1, dv2 = self._feedback(x[4], x[5], vr_fb)
        vr, dxa, df1, df2 = self._regulator(x, e_open - vf)
        e0 = jnp.clip(self.vb(meas) * vr, self.EFDMIN, self.EFDMAX)
        on = self.TE > 0
        defd = jnp.where(
            on,
            (e0 - self.KE * x[6] - self.se_efd(x[6])) / jnp.where(on, self.TE, 1.0),
            0.0,
        )
        efd = jnp.where(on, x[6], e0)
        return efd, jnp.stack([dvm, dxa, df1, df2, dv1, dv2, defd])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
