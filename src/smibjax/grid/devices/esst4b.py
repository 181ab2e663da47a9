"""ESST4B: the IEEE 421.5-2005 type ST4B static exciter, a potential- (and
compound-) source controlled rectifier with proportional-integral outer voltage
and inner field-voltage regulators (PSS/E `ESST4B`, CONs TR, KPR, KIR, VRMAX,
VRMIN, TA, KPM, KIM, VMMAX, VMMIN, KG, KP, KI, VBMAX, KC, XL, THETAP; ANDES
`ESST4B`).

    Vm: TR dVm/dt = Vc - Vm                      sensing lag (TR = 0: Vm = Vc)
    e   = Vref - Vm + Vs
    VR  = clip(KPR e + x_r, VRMIN, VRMAX),  dx_r/dt = KIR e      non-windup PI
    VA: TA dVA/dt = VR - VA                      bridge firing lag (TA = 0: VA = VR)
    VG  = KG Efd                                 inner-loop feedback
    VM  = clip(KPM (VA - VG) + x_m, VMMIN, VMMAX),  dx_m/dt = KIM (VA - VG)
                                                 non-windup PI
    VE  = |KP e^{j THETAP} Vt + j (KI + KP e^{j THETAP} XL) It|   power source
    VB  = min(VE FEX(KC XadIfd / VE), VBMAX)     (`esst3a.ESST3A.vb`, the same)
    Efd = VB VM

The PIs are IEEE 421.5's non-windup PI (Annex E): the output is the clipped sum,
and the integrator stops while the sum is at (or past) a limit and its input
pushes outwards. The inner loop closes algebraically through Efd = VB VM (VG =
KG VB VM): it is solved exactly, VM = clip((KPM VA + x_m) / (1 + KPM KG VB),
VMMIN, VMMAX) (the clip of the unlimited solution solves the limited loop, the
loop's gain being negative), as ANDES solves it with its algebraic variables.
PSS/E's ESST4B has no VGMAX (ANDES adds one, 20 by default); the OEL's LV gate
and the UEL have no input here (no limiter models).

At rest (`init`), each PI starts with its input at zero and its integrator at
its output (OpenIPSL's PSSE.ES.ESST4B and ANDES initialize it so): VB0 from the
measured phasors, VM0 = Efd0/VB0 = x_m, VA0 = VR0 = x_r = KG Efd0, Vref = Vc0 -
Vs0 (returned as `ref`). With KIM = 0 (KIR = 0), as in ACTIVSg2000's data, the
integrator then holds a constant bias: VM = KPM (VA - VG) + VM0. VM0 and VR0 must
lie within their limits.
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
    ordered,
    positive,
    regulated,
    require_at_rest,
)
from .base import AbstractController, f64, i64
from .esst3a import ESST3A

__all__ = ["ESST4B", "pi_nonwindup"]


def pi_nonwindup(x, u, KP, KI, lo, hi):
    """IEEE 421.5's non-windup PI KP + KI/s with output limits [lo, hi]: (y,
    dx/dt), y = clip(KP u + x, lo, hi), dx/dt = KI u, zero while KP u + x is at
    (or past) a limit and u pushes outwards."""
    s = KP * u + x
    pinned = ((s >= hi) & (u > 0)) | ((s <= lo) & (u < 0))
    return jnp.clip(s, lo, hi), jnp.where(pinned, 0.0, KI * u)


class ESST4B(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KPR: np.ndarray = eqx.field(converter=f64)  # voltage regulator P gain (pu/pu)
    KIR: np.ndarray = eqx.field(converter=f64)  # voltage regulator I gain (pu/pu/s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # voltage regulator limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    TA: np.ndarray = eqx.field(converter=f64)  # bridge firing time constant (s)
    KPM: np.ndarray = eqx.field(converter=f64)  # inner loop P gain (pu/pu)
    KIM: np.ndarray = eqx.field(converter=f64)  # inner loop I gain (pu/pu/s)
    VMMAX: np.ndarray = eqx.field(converter=f64)  # inner loop limits (pu)
    VMMIN: np.ndarray = eqx.field(converter=f64)
    KG: np.ndarray = eqx.field(converter=f64)  # inner-loop feedback gain (pu/pu)
    KP: np.ndarray = eqx.field(converter=f64)  # potential circuit gain (pu/pu)
    KI: np.ndarray = eqx.field(converter=f64)  # current circuit gain (pu/pu)
    VBMAX: np.ndarray = eqx.field(converter=f64)  # power source ceiling (pu)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)
    XL: np.ndarray = eqx.field(converter=f64)  # potential source reactance (pu)
    THETAP: np.ndarray = eqx.field(converter=f64)  # potential circuit angle (deg)

    inputs = ("Vt", "Vs", "XadIfd", "Vt_re", "Vt_im", "It_re", "It_im")
    output = "Efd"
    state_names = ("Vm", "x_r", "VA", "x_m")
    con_names = DYR_MODELS["ESST4B"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "TA", "KPR", "KIR", "KPM", "KIM", "KG", "KI", "KC"),
                *nonneg("XL"),
                *positive("KP", "VBMAX"),
                ordered("VRMIN", "VRMAX"),
                ordered("VMMIN", "VMMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def vb(self, meas):
        """VB = min(VE FEX(KC XadIfd / VE), VBMAX) (pu): ST3A's power source (the
        same CONs KP, KI, XL, THETAP, KC, VBMAX)."""
        return ESST3A.vb(self, meas)

    def _inner(self, xm, va, vb):
        """(VM, Efd, dx_m/dt) of the inner loop closed through Efd = VB VM."""
        s = (self.KPM * va + xm) / (1.0 + self.KPM * self.KG * vb)
        vm = jnp.clip(s, self.VMMIN, self.VMMAX)
        efd = vb * vm
        e = va - self.KG * efd
        pinned = ((s >= self.VMMAX) & (e > 0)) | ((s <= self.VMMIN) & (e < 0))
        return vm, efd, jnp.where(pinned, 0.0, self.KIM * e)

    def init(self, y0, meas):
        vb0 = self.vb(meas)
        safe = jnp.where(vb0 > 0, vb0, 1.0)
        vm0 = y0 / safe
        va0 = self.KG * y0
        require_at_rest(
            (vb0 > 0)
            & (vm0 >= self.VMMIN)
            & (vm0 <= self.VMMAX)
            & (va0 >= self.VRMIN)
            & (va0 <= self.VRMAX),
            "ESST4B",
            "Efd0",
            y0,
            "the operating point needs VB0 > 0, VM0 = Efd0/VB0 within [VMMIN, "
            "VMMAX] and VR0 = VA0 within [VRMIN, VRMAX]",
        )
        vc = regulated(meas) + 0.0 * y0
        ref = vc - meas["Vs"]
        e = ref - vc + meas["Vs"]  # as rhs computes it: 0 to roundoff
        vr = jnp.clip(self.KPR * e + va0, self.VRMIN, self.VRMAX)
        return jnp.stack([vc, va0, vr, vm0]), ref

    def _f(self, x, meas, ref):
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        e = ref - vm + meas["Vs"]
        vr, dxr = pi_nonwindup(x[1], e, self.KPR, self.KIR, self.VRMIN, self.VRMAX)
        va, dva = lag(x[2], vr, 1.0, self.TA)
        _, efd, dxm = self._inner(x[3], va, self.vb(meas))
        return efd, jnp.stack([dvm, dxr, dva, dxm])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
