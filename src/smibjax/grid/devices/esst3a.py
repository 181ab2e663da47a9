"""ESST3A: the IEEE 421.5 type ST3A static exciter, a potential- (and compound-)
source controlled rectifier with an inner field-voltage loop (PSS/E `ESST3A`, CONs
TR, VIMAX, VIMIN, KM, TC, TB, KA, TA, VRMAX, VRMIN, KG, KP, KI, VBMAX, KC, XL,
VGMAX, THETAP, TM, VMMAX, VMMIN; ANDES `ESST3A`).

    Vm: TR dVm/dt = Vc - Vm                        sensing lag (TR = 0: Vm = Vc)
    Vi  = clip(Vref - Vm + Vs, VIMIN, VIMAX)       input limiter (algebraic)
    x_ll: TB dx_ll/dt = Vi - x_ll,  VA = x_ll + (TC/TB)(Vi - x_ll)   lead-lag
    VR: TA dVR/dt = KA VA - VR                     regulator, non-windup [VRMIN, VRMAX]
    VG  = min(KG Efd, VGMAX)                       inner-loop feedback
    VM: TM dVM/dt = KM (VR - VG) - VM              inner loop, non-windup [VMMIN, VMMAX]
    VE  = |KP e^{j THETAP} Vt + j (KI + KP e^{j THETAP} XL) It|   power source
    IN  = KC XadIfd / VE,   VB = min(VE FEX(IN), VBMAX)           (`_blocks.fex`)
    Efd = VB VM

Vc is the regulated voltage (the compensator's, else the terminal voltage), Vt and
It the terminal voltage and current phasors (pu; It on the machine base, out of the
terminal: the closed loop's "Vt_re", "Vt_im", "It_re", "It_im"), XadIfd the field
current (pu on the Xad base), THETAP in degrees. The two lag blocks' limits are
non-windup (PSS/E draws them on the KA/(1 + s TA) and KM/(1 + s TM) blocks; ANDES
`LagAntiWindup`); the input limiter and the VB and VG ceilings are algebraic. TA =
0 makes the regulator algebraic (VR = clip(KA VA)), TB = 0 (with TC = 0) drops the
lead-lag; TM = 0 is refused where KG != 0 (an algebraic loop through Efd). The
under-excitation limiter's HV gate has no input here (no UEL model).

At rest (`init`): VB0 from the measured phasors, VM0 = Efd0/VB0, VR0 = VM0/KM +
VG0, VA0 = Vi0 = VR0/KA, Vref = Vc0 - Vs0 + VR0/KA (returned as `ref`); each must
lie within its limits.
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
    lag_nonwindup,
    leadlag,
    nonneg,
    ordered,
    positive,
    proper,
    regulated,
    require_at_rest,
    v,
)
from .base import AbstractController, f64, i64

__all__ = ["ESST3A"]


class ESST3A(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    VIMAX: np.ndarray = eqx.field(converter=f64)  # input limits (pu)
    VIMIN: np.ndarray = eqx.field(converter=f64)
    KM: np.ndarray = eqx.field(converter=f64)  # inner-loop forward gain (pu/pu)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KG: np.ndarray = eqx.field(converter=f64)  # inner-loop feedback gain (pu/pu)
    KP: np.ndarray = eqx.field(converter=f64)  # potential circuit gain (pu/pu)
    KI: np.ndarray = eqx.field(converter=f64)  # current circuit gain (pu/pu)
    VBMAX: np.ndarray = eqx.field(converter=f64)  # power source ceiling (pu)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier commutation factor (pu)
    XL: np.ndarray = eqx.field(converter=f64)  # potential source reactance (pu)
    VGMAX: np.ndarray = eqx.field(converter=f64)  # feedback ceiling (pu)
    THETAP: np.ndarray = eqx.field(converter=f64)  # potential circuit angle (deg)
    TM: np.ndarray = eqx.field(converter=f64)  # inner-loop time constant (s)
    VMMAX: np.ndarray = eqx.field(converter=f64)  # inner-loop limits (pu)
    VMMIN: np.ndarray = eqx.field(converter=f64)

    inputs = ("Vt", "Vs", "XadIfd", "Vt_re", "Vt_im", "It_re", "It_im")
    output = "Efd"
    state_names = ("Vm", "x_ll", "VR", "VM")
    con_names = DYR_MODELS["ESST3A"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "TA", "KC", "KG", "KI", "XL"),
                *positive("KA", "KM", "KP", "VBMAX"),
                proper("TC", "TB"),
                ordered("VIMIN", "VIMAX"),
                ordered("VRMIN", "VRMAX"),
                ordered("VMMIN", "VMMAX"),
                (
                    "TM",
                    lambda o: (
                        (v(o, "TM") > 0) | ((v(o, "TM") == 0) & (v(o, "KG") == 0))
                    ),
                    "must be > 0 where KG != 0 (else an algebraic loop), and >= 0",
                ),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def vb(self, meas):
        """VB = min(VE FEX(KC XadIfd / VE), VBMAX): the rectifier's available
        voltage (pu)."""
        kp = self.KP * jnp.exp(1j * jnp.deg2rad(self.THETAP))
        vt = meas["Vt_re"] + 1j * meas["Vt_im"]
        it = meas["It_re"] + 1j * meas["It_im"]
        ve = jnp.abs(kp * vt + 1j * (self.KI + kp * self.XL) * it)
        safe = jnp.where(ve > 0, ve, 1.0)
        i_n = jnp.where(ve > 0, self.KC * meas["XadIfd"] / safe, 2.0)
        return jnp.minimum(ve * fex(i_n), self.VBMAX)

    def _vg(self, efd):
        return jnp.minimum(self.KG * efd, self.VGMAX)

    def init(self, y0, meas):
        vb0 = self.vb(meas)
        safe = jnp.where(vb0 > 0, vb0, 1.0)
        vm0 = y0 / safe
        vr0 = vm0 / self.KM + self._vg(y0)
        va0 = vr0 / self.KA
        require_at_rest(
            (vb0 > 0)
            & (vm0 >= self.VMMIN)
            & (vm0 <= self.VMMAX)
            & (vr0 >= self.VRMIN)
            & (vr0 <= self.VRMAX)
            & (va0 >= self.VIMIN)
            & (va0 <= self.VIMAX),
            "ESST3A",
            "Efd0",
            y0,
            "the operating point needs VB0 > 0, VM0 = Efd0/VB0 within [VMMIN, "
            "VMMAX], VR0 = VM0/KM + VG0 within [VRMIN, VRMAX] and VR0/KA within "
            "[VIMIN, VIMAX]",
        )
        ref = regulated(meas) - meas["Vs"] + va0
        zero = 0.0 * y0
        vc = regulated(meas) + zero
        vi0 = ref - vc + meas["Vs"]  # as rhs computes it
        vr0 = self.KA * vi0
        vm0 = self.KM * (vr0 - self._vg(y0))
        return jnp.stack([vc, vi0, vr0, vm0]), ref

    def _f(self, x, meas, ref):
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        vi = jnp.clip(ref - vm + meas["Vs"], self.VIMIN, self.VIMAX)
        va, dll = leadlag(x[1], vi, self.TC, self.TB)
        vr, dvr = lag_nonwindup(x[2], va, self.KA, self.TA, self.VRMIN, self.VRMAX)
        vb = self.vb(meas)
        # TM > 0 wherever KG != 0: Efd from the state VM, then VG from Efd
        efd_state = vb * jnp.clip(x[3], self.VMMIN, self.VMMAX)
        vmi, dvmi = lag_nonwindup(
            x[3], vr - self._vg(efd_state), self.KM, self.TM, self.VMMIN, self.VMMAX
        )
        return vb * vmi, jnp.stack([dvm, dll, dvr, dvmi])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
