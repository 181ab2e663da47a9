"""EXAC1 and ESAC1A: the AC alternator-rectifier exciters of IEEE type AC1 (PSS/E
`EXAC1`, the 1981 IEEE report; CONs TR, TB, TC, KA, TA, VRMAX, VRMIN, TE, KF, TF,
KC, KD, KE, E1, SE(E1), E2, SE(E2)) and IEEE 421.5-2005 type AC1A (PSS/E `ESAC1A`;
CONs TR, TB, TC, KA, TA, VAMAX, VAMIN, TE, KF, TF, KC, KD, KE, E1, SE(E1), E2,
SE(E2), VRMAX, VRMIN). PSS/E's CON order (PSS/E Model Library; the records of
ACTIVSg2000 and of PowerSimulationsDynamics.jl's PSS/E test files fit it, ANDES
2.0's psse-dyr.yaml lists ESAC1A's in another order).

    Vm: TR dVm/dt = Vc - Vm                          sensing lag (TR = 0: Vm = Vc)
    Vi  = Vref - Vm - VF + Vs
    x_ll: TB dx_ll/dt = Vi - x_ll, y = x_ll + (TC/TB)(Vi - x_ll)     lead-lag
    EXAC1:  VR: TA dVR/dt = KA y - VR,  non-windup [VRMIN, VRMAX]
    ESAC1A: VA: TA dVA/dt = KA y - VA,  non-windup [VAMIN, VAMAX];
            VR = clip(VA, VRMIN, VRMAX)  (windup: an algebraic limiter)
    VFE = KD XadIfd + KE VE + SE(VE) VE              exciter field demand
    VE: TE dVE/dt = VR - VFE,  non-windup lower limit 0   exciter (alternator)
    x_f: TF dx_f/dt = VFE - x_f,  VF = (KF/TF)(VFE - x_f)  rate feedback from VFE
    IN = KC XadIfd / VE,  Efd = VE FEX(IN)          rectifier (`_blocks.fex`)

Vc is the regulated voltage (the compensator's, else Vt), XadIfd the machine's
field current (pu on the Xad base, from its `measure`). SE is PSS/E's quadratic
exciter saturation through (E1, SE(E1)), (E2, SE(E2)): SE(VE) VE = B (VE - A)^2
for VE > A (`ieeex1.saturation_coefficients`; no data, E1 SE(E1) = 0, is none).
The exciter's lower limit VE >= 0 is drawn on the 1/(s TE) integrator (IEEE
421.5-2005 AC1A; PowerSimulationsDynamics.jl also applies it to EXAC1). ESAC1A's
HV/LV gates for the under/over-excitation limiters pass VA through (no UEL or OEL
model). TA = 0 makes the regulator algebraic.

At rest (`init`): VE0 solves Efd0 = VE0 FEX(KC XadIfd0 / VE0) in closed form
(`ve_at_rest`), VR0 = VFE0, Vref = Vc0 - Vs0 + VR0/KA, the rate feedback's state at
VFE0; VR0 (and ESAC1A's VA0 = VR0) must lie within the limits.
"""

from __future__ import annotations

from typing import ClassVar

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
    nonwindup,
    ordered,
    positive,
    proper,
    regulated,
    require_at_rest,
    v,
    washout,
)
from .base import AbstractController, f64, i64
from .ieeex1 import saturation_coefficients

__all__ = ["EXAC1", "ESAC1A", "ve_at_rest", "exciter_saturation_rule"]


def ve_at_rest(efd, ifd, kc):
    """The exciter output voltage VE (pu) with VE FEX(KC ifd / VE) = efd: the
    inverse of the rectifier's regulation, branch by branch of IEEE 421.5's FEX
    (IN <= 0.433: VE = efd + 0.577 KC ifd; 0.433 < IN <= 0.75: VE = sqrt((efd^2 +
    (KC ifd)^2) / 0.75); 0.75 < IN <= 1: VE = efd / 1.732 + KC ifd), the first
    whose IN lies in its branch; KC ifd <= 0: VE = efd."""
    a = kc * ifd
    ve1 = efd + 0.577 * a
    ve2 = jnp.sqrt((efd**2 + a**2) / 0.75)
    ve3 = efd / 1.732 + a

    def i_n(ve):
        return a / jnp.where(ve > 0, ve, 1.0)

    return jnp.where(
        a <= 0,
        efd,
        jnp.where(i_n(ve1) <= 0.433, ve1, jnp.where(i_n(ve2) <= 0.75, ve2, ve3)),
    )


def exciter_saturation_rule():
    """A `check` rule: a quadratic saturation curve passes through (E1, SE1) and
    (E2, SE2) (SE1 E1 != SE2 E2 unless a point is empty)."""
    return (
        "SE2",
        lambda o: (
            (v(o, "SE1") * v(o, "E1") == 0)
            | (v(o, "SE2") * v(o, "E2") == 0)
            | ~np.isclose(v(o, "SE1") * v(o, "E1"), v(o, "SE2") * v(o, "E2"), rtol=1e-9)
        ),
        "must make SE2 E2 != SE1 E1 (no quadratic curve passes through both points)",
    )


def ac_se_ve(dev, ve):
    """SE(VE) VE (pu): an AC exciter's saturation, PSS/E's quadratic curve through
    `dev`'s (E1, SE1), (E2, SE2)."""
    A, B = saturation_coefficients(dev.E1, dev.SE1, dev.E2, dev.SE2)
    return B * jnp.maximum(ve - A, 0.0) ** 2


def ac_vfe(dev, ve, ifd):
    """VFE = KD XadIfd + KE VE + SE(VE) VE (pu): an AC exciter's field demand."""
    return dev.KD * ifd + dev.KE * ve + ac_se_ve(dev, ve)


def ac_efd(dev, ve, ifd):
    """Efd = VE FEX(KC XadIfd / VE) (pu): the rectified output (0 where VE <= 0)."""
    safe = jnp.where(ve > 0, ve, 1.0)
    i_n = jnp.where(ve > 0, dev.KC * ifd / safe, 2.0)
    return jnp.where(ve > 0, ve, 0.0) * fex(i_n)


class ACField(AbstractController):
    """What every AC exciter's rectified output is made of (`ac_se_ve`, `ac_vfe`,
    `ac_efd`), for the models whose fields include E1, SE1, E2, SE2, KD, KE, KC."""

    def se_ve(self, ve):
        """SE(VE) VE (pu): the exciter's saturation, PSS/E's quadratic curve."""
        return ac_se_ve(self, ve)

    def vfe(self, ve, ifd):
        """VFE = KD XadIfd + KE VE + SE(VE) VE (pu): the exciter field demand."""
        return ac_vfe(self, ve, ifd)

    def efd(self, ve, ifd):
        """Efd = VE FEX(KC XadIfd / VE) (pu)."""
        return ac_efd(self, ve, ifd)


class _ACExciter(ACField):
    """What the AC alternator-rectifier exciters share: the exciter, its field
    demand VFE, the rectifier and the saturation. Subclasses give the regulator
    (`_regulator`: VR from its state, its input and VFE) and its state at rest
    (`_reg_init`: the regulator's state VA0 for VR0 = VFE0, whether it lies
    within the limits, and what they are)."""

    inputs = ("Vt", "Vs", "XadIfd")
    output = "Efd"
    state_names: ClassVar[tuple[str, ...]] = ("Vm", "x_ll", "VR", "VE", "x_f")

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _common_rules(self):
        return [
            *nonneg("TR", "TA", "KF", "KC", "KD"),
            *positive("KA", "TE"),
            proper("TC", "TB"),
            ordered("VRMIN", "VRMAX"),
            (
                "TF",
                lambda o: (v(o, "TF") > 0) | (v(o, "KF") == 0),
                "must be > 0 where KF != 0",
            ),
            exciter_saturation_rule(),
        ]

    def init(self, y0, meas):
        ifd = meas["XadIfd"]
        ve0 = ve_at_rest(y0, ifd, self.KC)
        vfe0 = self.vfe(ve0, ifd)
        va0, ok, what = self._reg_init(vfe0)
        require_at_rest(
            (ve0 > 0) & ok,
            type(self).__name__,
            "Efd0",
            y0,
            f"the operating point needs VE0 > 0 and {what}",
        )
        vc = regulated(meas) + 0.0 * y0
        ref = vc - meas["Vs"] + va0 / self.KA
        y = ref - vc + meas["Vs"]  # as rhs computes it (VF = 0 at rest)
        return jnp.stack([vc, y, self.KA * y, ve0, vfe0]), ref

    def _f(self, x, meas, ref):
        ifd = meas["XadIfd"]
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        vfe = self.vfe(x[3], ifd)
        vf, dxf = washout(x[4], vfe, self.KF, self.TF)
        y, dll = leadlag(x[1], ref - vm - vf + meas["Vs"], self.TC, self.TB)
        vr, dvr = self._regulator(x[2], y, vfe)
        dve = nonwindup(x[3], (vr - vfe) / self.TE, 0.0, jnp.inf)
        return self.efd(x[3], ifd), jnp.stack([dvm, dll, dvr, dve, dxf])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self.efd(x[3], meas["XadIfd"])


class EXAC1(_ACExciter):
    """PSS/E EXAC1 (IEEE 1981 type AC1): regulator KA/(1 + s TA) with non-windup
    limits [VRMIN, VRMAX]."""

    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)
    KD: np.ndarray = eqx.field(converter=f64)  # demagnetizing factor (pu)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (pu)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)

    con_names = DYR_MODELS["EXAC1"]

    def __check_init__(self):
        check(self, self._common_rules())

    def _regulator(self, xr, y, vfe):
        return lag_nonwindup(xr, y, self.KA, self.TA, self.VRMIN, self.VRMAX)

    def _reg_init(self, vr0):
        ok = (vr0 >= self.VRMIN) & (vr0 <= self.VRMAX)
        return vr0, ok, "VR0 = VFE0 within [VRMIN, VRMAX]"


class ESAC1A(_ACExciter):
    """PSS/E ESAC1A (IEEE 421.5-2005 type AC1A): regulator KA/(1 + s TA) with
    non-windup limits [VAMIN, VAMAX], then VR = clip(VA, VRMIN, VRMAX)."""

    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VAMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu)
    VAMIN: np.ndarray = eqx.field(converter=f64)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    KC: np.ndarray = eqx.field(converter=f64)  # rectifier loading factor (pu)
    KD: np.ndarray = eqx.field(converter=f64)  # demagnetizing factor (pu)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (pu)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # exciter field limits (pu)
    VRMIN: np.ndarray = eqx.field(converter=f64)

    con_names = DYR_MODELS["ESAC1A"]
    state_names = ("Vm", "x_ll", "VA", "VE", "x_f")

    def __check_init__(self):
        check(self, [*self._common_rules(), ordered("VAMIN", "VAMAX")])

    def _regulator(self, xa, y, vfe):
        va, dva = lag_nonwindup(xa, y, self.KA, self.TA, self.VAMIN, self.VAMAX)
        return jnp.clip(va, self.VRMIN, self.VRMAX), dva

    def _reg_init(self, vr0):
        ok = (
            (vr0 >= self.VRMIN)
            & (vr0 <= self.VRMAX)
            & (vr0 >= self.VAMIN)
            & (vr0 <= self.VAMAX)
        )
        return vr0, ok, "VR0 = VA0 = VFE0 within [VRMIN, VRMAX] and [VAMIN, VAMAX]"
