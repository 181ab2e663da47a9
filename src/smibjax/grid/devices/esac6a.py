"""ESAC6A: the IEEE 421.5-2005 type AC6A alternator-rectifier exciter with a
system-fed regulator (PSS/E `ESAC6A`, CONs TR, KA, TA, TK, TB, TC, VAMAX, VAMIN,
VRMAX, VRMIN, TE, VFELIM, KH, VHMAX, TH, TJ, KC, KD, KE, E1, SE(E1), E2, SE(E2);
ANDES 2.0 lists the same CONs and reads the model as an SEXS, PSID and OpenIPSL
have none).

    Vm: TR dVm/dt = Vc - Vm                          sensing lag (TR = 0: Vm = Vc)
    e   = Vref - Vm + Vs
    VA  = KA (1 + s TK)/(1 + s TA) e,  non-windup [VAMIN, VAMAX]
          (state x_a: TA dx_a/dt = KA e - x_a, VA = x_a + (TK/TA)(KA e - x_a))
    VLL = (1 + s TC)/(1 + s TB) VA                    lead-lag
    VH  = clip(KH (1 + s TJ)/(1 + s TH) (VFE - VFELIM), 0, VHMAX)
                                                      field current limiter
    VR  = clip(VLL - VH, Vt VRMIN, Vt VRMAX)          bus-fed regulator (windup)
    VFE = KD XadIfd + KE VE + SE(VE) VE
    VE: TE dVE/dt = VR - VFE,  non-windup lower limit 0
    Efd = VE FEX(KC XadIfd / VE)

(`exac1` for VFE, SE, FEX and the VE >= 0 limit.) The regulator's limits are on
its first block (IEEE 421.5-2005; the CONs' own description, "maximum first
regulator block output", in PowerWorld's documentation), non-windup as the
standard's lead-lag with limits (its state stops while the limited output is
pushed outwards); OPAL-RT's ePHASORsim library draws them on the second lead-lag
instead. The limiter's VH is clipped at its output (windup). Neither PSS/E's
nor another program's results are at hand: the model is checked against its own
closed forms (the transfer function of the linear part, the limiter, the
ceiling). ACTIVSg2000's seven ESAC6A records have KH = 0 (no limiter) and TA =
17.5 s, TK = 3 s.

At rest (`init`): VE0 from Efd0 (`exac1.ve_at_rest`), VR0 = VFE0, VH0 from VFE0,
VLL0 = VA0 = VR0 + VH0, Vref = Vc0 - Vs0 + VA0/KA; VA0 within [VAMIN, VAMAX] and
VR0 within [Vt VRMIN, Vt VRMAX].
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import (
    _safe,
    build_group,
    check,
    lag,
    leadlag,
    nonneg,
    nonwindup,
    ordered,
    positive,
    proper,
    regulated,
    require_at_rest,
)
from .base import f64, i64
from .exac1 import ACField, exciter_saturation_rule, ve_at_rest

__all__ = ["ESAC6A", "leadlag_nonwindup"]


def leadlag_nonwindup(x, u, K, T_lead, T_lag, lo, hi):
    """K (1 + s T_lead)/(1 + s T_lag) with non-windup limits [lo, hi] on its
    output (IEEE 421.5 Annex E): (y, dx/dt), T_lag dx/dt = K u - x, y = clip(x +
    (T_lead/T_lag)(K u - x), lo, hi), dx/dt zero while the unlimited output is at
    (or past) a limit and dx/dt pushes it outwards; T_lag = 0: y = clip(K u)."""
    on = T_lag > 0
    f = (K * u - x) / _safe(T_lag)
    raw = jnp.where(on, x + T_lead * f, K * u)
    pinned = ((raw >= hi) & (f > 0)) | ((raw <= lo) & (f < 0))
    return jnp.clip(raw, lo, hi), jnp.where(on & ~pinned, f, 0.0)


class ESAC6A(ACField):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator lag (s)
    TK: np.ndarray = eqx.field(converter=f64)  # regulator lead (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    VAMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VAMIN: np.ndarray = eqx.field(converter=f64)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # exciter field limits (pu, x Vt)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    VFELIM: np.ndarray = eqx.field(converter=f64)  # field current limit (pu)
    KH: np.ndarray = eqx.field(converter=f64)  # limiter gain (pu)
    VHMAX: np.ndarray = eqx.field(converter=f64)  # limiter ceiling (pu)
    TH: np.ndarray = eqx.field(converter=f64)  # limiter lag (s)
    TJ: np.ndarray = eqx.field(converter=f64)  # limiter lead (s)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)
    KD: np.ndarray = eqx.field(converter=f64)  # demagnetizing factor (pu)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (pu)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)

    inputs = ("Vt", "Vs", "XadIfd")
    output = "Efd"
    state_names = ("Vm", "x_a", "x_ll", "VE", "x_h")
    con_names = DYR_MODELS["ESAC6A"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "KC", "KD", "KH", "VHMAX"),
                *positive("KA", "TE"),
                proper("TK", "TA"),
                proper("TC", "TB"),
                proper("TJ", "TH"),
                ordered("VAMIN", "VAMAX"),
                ordered("VRMIN", "VRMAX"),
                exciter_saturation_rule(),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _vh(self, xh, vfe):
        """(VH, dx_h/dt): the field current limiter."""
        y, dxh = leadlag(xh, vfe - self.VFELIM, self.TJ, self.TH)
        return jnp.clip(self.KH * y, 0.0, self.VHMAX), dxh

    def init(self, y0, meas):
        ifd = meas["XadIfd"]
        ve0 = ve_at_rest(y0, ifd, self.KC)
        vfe0 = self.vfe(ve0, ifd)
        vh0 = jnp.clip(self.KH * (vfe0 - self.VFELIM), 0.0, self.VHMAX)
        va0 = vfe0 + vh0
        vt = meas["Vt"]
        require_at_rest(
            (ve0 > 0)
            & (va0 >= self.VAMIN)
            & (va0 <= self.VAMAX)
            & (vfe0 >= vt * self.VRMIN)
            & (vfe0 <= vt * self.VRMAX),
            "ESAC6A",
            "Efd0",
            y0,
            "the operating point needs VE0 > 0, VA0 = VFE0 + VH0 within [VAMIN, "
            "VAMAX] and VR0 = VFE0 within [Vt VRMIN, Vt VRMAX]",
        )
        vc = regulated(meas) + 0.0 * y0
        ref = vc - meas["Vs"] + va0 / self.KA
        e = ref - vc + meas["Vs"]  # as rhs computes it
        zero = 0.0 * y0
        xh = vfe0 - self.VFELIM + zero
        return jnp.stack([vc, self.KA * e, va0 + zero, ve0 + zero, xh]), ref

    def _f(self, x, meas, ref):
        ifd = meas["XadIfd"]
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        e = ref - vm + meas["Vs"]
        va, dxa = leadlag_nonwindup(
            x[1], e, self.KA, self.TK, self.TA, self.VAMIN, self.VAMAX
        )
        vll, dll = leadlag(x[2], va, self.TC, self.TB)
        vfe = self.vfe(x[3], ifd)
        vh, dxh = self._vh(x[4], vfe)
        vt = meas["Vt"]
        vr = jnp.clip(vll - vh, vt * self.VRMIN, vt * self.VRMAX)
        dve = nonwindup(x[3], (vr - vfe) / self.TE, 0.0, jnp.inf)
        return self.efd(x[3], ifd), jnp.stack([dvm, dxa, dll, dve, dxh])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self.efd(x[3], meas["XadIfd"])
