"""EXAC2: the IEEE 1981 type AC2 high-initial-response alternator-rectifier exciter
(PSS/E `EXAC2`, CONs TR, TB, TC, KA, TA, VAMAX, VAMIN, KB, VRMAX, VRMIN, TE, KL,
KH, KF, TF, KC, KD, KE, VLR, E1, SE(E1), E2, SE(E2); ANDES `EXAC2`, the same order).

EXAC1's diagram (`exac1`: sensing lag, lead-lag, rate feedback from VFE, the
exciter TE dVE/dt = VR - VFE with VE >= 0, VFE = KD XadIfd + KE VE + SE(VE) VE,
Efd = VE FEX(KC XadIfd / VE)) with a second, fast loop and a field current limiter
between the regulator and the exciter:

    VA: TA dVA/dt = KA y - VA,  non-windup [VAMIN, VAMAX]
    VH  = KH VFE                                   exciter field current feedback
    VL  = KL (VLR - VFE)                           field current limiter
    VR  = clip(KB min(VA - VH, VL), VRMIN, VRMAX)  LV gate, then KB (windup clip)

At rest: VR0 = VFE0, VA0 = VFE0/KB + KH VFE0, Vref = Vc0 - Vs0 + VA0/KA; the
limiter must not be in control at rest (VL0 >= VFE0/KB), VA0 and VR0 within their
limits. ANDES 2.0 initializes Vref with KL in place of KH (`(VFE KL + VFE/KB)/KA`)
and moves VLR so that the gate starts balanced; smibjax keeps PSS/E's VLR and
refuses an operating point at which the limiter would act.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import check, lag_nonwindup, ordered, positive
from .base import f64, i64
from .exac1 import _ACExciter

__all__ = ["EXAC2"]


class EXAC2(_ACExciter):
    """PSS/E EXAC2 (IEEE 1981 type AC2)."""

    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VAMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VAMIN: np.ndarray = eqx.field(converter=f64)
    KB: np.ndarray = eqx.field(converter=f64)  # second-stage gain (pu/pu)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # exciter field limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KL: np.ndarray = eqx.field(converter=f64)  # field current limiter gain (pu)
    KH: np.ndarray = eqx.field(converter=f64)  # field current feedback gain (pu)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)
    KD: np.ndarray = eqx.field(converter=f64)  # demagnetizing factor (pu)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (pu)
    VLR: np.ndarray = eqx.field(converter=f64)  # field current limit reference (pu)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)

    con_names = DYR_MODELS["EXAC2"]
    state_names = ("Vm", "x_ll", "VA", "VE", "x_f")

    def __check_init__(self):
        check(
            self,
            [
                *self._common_rules(),
                *positive("KB"),
                ordered("VAMIN", "VAMAX"),
                ("KL", lambda o: np.asarray(o.KL, float) >= 0, "must be >= 0"),
                ("KH", lambda o: np.asarray(o.KH, float) >= 0, "must be >= 0"),
            ],
        )

    def _regulator(self, xa, y, vfe):
        va, dva = lag_nonwindup(xa, y, self.KA, self.TA, self.VAMIN, self.VAMAX)
        gate = jnp.minimum(va - self.KH * vfe, self.KL * (self.VLR - vfe))
        return jnp.clip(self.KB * gate, self.VRMIN, self.VRMAX), dva

    def _reg_init(self, vr0):
        va0 = vr0 / self.KB + self.KH * vr0
        ok = (
            (vr0 >= self.VRMIN)
            & (vr0 <= self.VRMAX)
            & (va0 >= self.VAMIN)
            & (va0 <= self.VAMAX)
            & (self.KL * (self.VLR - vr0) >= vr0 / self.KB)
        )
        return (
            va0,
            ok,
            "VR0 = VFE0 within [VRMIN, VRMAX], VA0 = VFE0/KB + KH VFE0 within "
            "[VAMIN, VAMAX] and the field current limiter idle (KL (VLR - VFE0) "
            ">= VFE0/KB)",
        )
