"""DC4B: the IEEE 421.5-2005 type DC4B DC commutator exciter with a PID regulator
(PSS/E `DC4B`; ICONs UEL, OEL, then CONs TR, KP, KI, KD, TD, VRMAX, VRMIN, KA, TA,
KE, TE, KF, TF, VEMIN, E1, SE(E1), E2, SE(E2): the order of the NETS-NYPS 68-bus
case's records in NREL-Sienna/PowerSystemsTestData and of OpenIPSL's
`PSSE.ES.DC4B`).

    Vm: TR dVm/dt = Vc - Vm                        sensing lag (TR = 0: Vm = Vc)
    e   = Vref - Vm + Vs - VF
    VP  = clip(KP e + x_i + KD s/(1 + s TD) e, VRMIN/KA, VRMAX/KA),  dx_i/dt = KI e
                                                   non-windup PID
    VR: TA dVR/dt = KA Vt VP - VR,  non-windup [Vt VRMIN, Vt VRMAX]  (bus-fed)
    Efd: TE dEfd/dt = VR - (KE + SE(Efd)) Efd,  non-windup lower limit VEMIN
    x_f: TF dx_f/dt = Efd - x_f,  VF = (KF/TF)(Efd - x_f)          rate feedback

SE is PSS/E's quadratic exciter saturation through (E1, SE(E1)), (E2, SE(E2))
(`ieeex1.saturation_coefficients`). KE = 0 and VRMAX = 0 are computed at rest as
for PSS/E's other DC exciters (`esdc2a.dc_constants`, as OpenIPSL's DC4B does).
The PID's limits are IEEE 421.5's non-windup PID (its integrator stops while the
sum is at or past a limit and e pushes outwards), VR's limits move with the
terminal voltage Vt and sweep VR along (`_blocks.sweeping`). UEL and OEL select
where limiters would enter: smibjax has none, so they are kept as data.

Neither PSS/E's nor another program's results are at hand: the model follows
OpenIPSL's PSSE.ES.DC4B (validated there against PSS/E) and is checked against its
own closed forms. At rest: KE, VRMAX, VRMIN in force, VR0 = (KE + SE(Efd0)) Efd0,
the PID's input zero and its integrator at VP0 = VR0/(KA Vt0), Vref = Vc0 - Vs0.
`ref` is (4, k): Vref and the KE, VRMAX, VRMIN in force.
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
    nonneg,
    nonwindup,
    ordered,
    positive,
    regulated,
    require_at_rest,
    v,
    washout,
)
from .base import AbstractController, f64, i64
from .esdc2a import dc_constants
from .exac1 import exciter_saturation_rule
from .ieeex1 import saturation_coefficients

__all__ = ["DC4B"]


class DC4B(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    UEL: np.ndarray = eqx.field(converter=f64)  # UEL input code (no UEL: unused)
    OEL: np.ndarray = eqx.field(converter=f64)  # OEL input code (no OEL: unused)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KP: np.ndarray = eqx.field(converter=f64)  # PID proportional gain (pu/pu)
    KI: np.ndarray = eqx.field(converter=f64)  # PID integral gain (pu/pu/s)
    KD: np.ndarray = eqx.field(converter=f64)  # PID derivative gain (pu s/pu)
    TD: np.ndarray = eqx.field(converter=f64)  # derivative time constant (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu, x Vt)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (0: at rest)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    VEMIN: np.ndarray = eqx.field(converter=f64)  # exciter output floor (pu)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)

    inputs = ("Vt", "Vs")
    output = "Efd"
    state_names = ("Vm", "x_i", "x_d", "VR", "Efd", "x_f")
    con_names = DYR_MODELS["DC4B"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "KP", "KI", "KD", "TD", "TA", "KF", "TF"),
                *positive("KA", "TE"),
                ordered("VRMIN", "VRMAX"),
                (
                    "TD",
                    lambda o: (v(o, "TD") > 0) | (v(o, "KD") == 0),
                    "must be > 0 where KD != 0 (else a pure derivative)",
                ),
                (
                    "TF",
                    lambda o: (v(o, "TF") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0",
                ),
                exciter_saturation_rule(),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def se_efd(self, efd):
        """SE(Efd) Efd (pu): PSS/E's quadratic exciter saturation."""
        A, B = saturation_coefficients(self.E1, self.SE1, self.E2, self.SE2)
        return B * jnp.maximum(efd - A, 0.0) ** 2

    def init(self, y0, meas):
        safe = jnp.where(y0 != 0, y0, 1.0)
        se0 = self.se_efd(y0) / safe
        ke, vrmax, vrmin = dc_constants(
            self.VRMAX, self.VRMIN, self.KE, self.E2, self.SE2, y0, se0
        )
        vr0 = ke * y0 + self.se_efd(y0)
        vt = meas["Vt"]
        require_at_rest(
            (vr0 >= vt * vrmin) & (vr0 <= vt * vrmax) & (y0 >= self.VEMIN),
            "DC4B",
            "Efd0",
            y0,
            "the operating point needs VR0 = (KE + SE(Efd0)) Efd0 within [Vt VRMIN, "
            "Vt VRMAX] and Efd0 >= VEMIN",
        )
        vp0 = vr0 / (self.KA * vt)
        vc = regulated(meas) + 0.0 * y0
        vref = vc - meas["Vs"]
        zero = 0.0 * y0
        e = vref - vc + meas["Vs"]  # as rhs computes it: 0 to roundoff
        x0 = jnp.stack([vc, vp0, e, vr0, y0 + zero, y0 + zero])
        return x0, jnp.stack([vref, ke + zero, vrmax + zero, vrmin + zero])

    def _f(self, x, meas, ref):
        vt = meas["Vt"]
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        vf, dxf = washout(x[5], x[4], self.KF, self.TF)
        e = ref[0] - vm + meas["Vs"] - vf
        deriv, dxd = washout(x[2], e, self.KD, self.TD)
        lo, hi = ref[3] / self.KA, ref[2] / self.KA
        s = self.KP * e + x[1] + deriv
        pinned = ((s >= hi) & (e > 0)) | ((s <= lo) & (e < 0))
        vp = jnp.clip(s, lo, hi)
        dxi = jnp.where(pinned, 0.0, self.KI * e)
        vr, dvr = lag_nonwindup(
            x[3], vt * vp, self.KA, self.TA, vt * ref[3], vt * ref[2], moving=True
        )
        defd = (vr - ref[1] * x[4] - self.se_efd(x[4])) / self.TE
        defd = nonwindup(x[4], defd, self.VEMIN, jnp.inf)
        return jnp.stack([dvm, dxi, dxd, dvr, defd, dxf])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)

    def out(self, x, meas, ref):
        return x[4]
