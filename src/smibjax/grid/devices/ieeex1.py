"""IEEEX1 and EXDC2: the DC commutator exciters (PSS/E `IEEEX1`, the 1979 IEEE
type 1 / DC1; `EXDC2`, the 1981 IEEE type DC2; ANDES `IEEEX1`, `EXDC2`). Both take
the CONs TR, KA, TA, TB, TC, VRMAX, VRMIN, KE, TE, KF, TF1, SWITCH, E1, SE1, E2, SE2.

    Vm: TR dVm/dt = Vt - Vm                              sensing lag (TR = 0: Vm = Vt)
    Vi  = Vref - Vm - Vf + Vs                            error
    x_ll: TB dx_ll/dt = Vi - x_ll, y = x_ll + (TC/TB)(Vi - x_ll)  lead-lag (1 + s TC)/(1 + s TB)
    VR: TA dVR/dt = KA y - VR                            regulator, non-windup limits
    Efd: TE dEfd/dt = VR - (KE + SE(Efd)) Efd            exciter
    x_f: TF1 dx_f/dt = Efd - x_f,  Vf = (KF/TF1)(Efd - x_f)   rate feedback s KF/(1 + s TF1)

Regulator limits (non-windup on VR, as PSS/E draws them on the KA/(1 + s TA) block
and ANDES `LagAntiWindup`): IEEEX1 [VRMIN, VRMAX]; EXDC2 [VRMIN Vt, VRMAX Vt], the
DC2 regulator being fed from the terminal bus, so its ceiling moves with the
terminal voltage Vt (the measured, not the sensed, value). EXDC2's moving limits
sweep the state along (`_blocks.sweeping`: a ceiling that falls below VR draws VR
down with it, as PSS/E's clamp and ANDES's reset do); IEEEX1's constant ones hold
it. ANDES 2.0's sources have the scaling the other way round (its IEEEX1 defines
VRMAX v, VRMIN v, its EXDC2 does not), but ANDES 2.0.0's IEEEX1 never hands the
scaled bounds to its limiter (it replaces the lag's `upper`/`lower` after the lag
built its `AntiWindup` on VRMAX/VRMIN), so in effect both its models have constant
limits; its EXDC2 multiplies Efd by the speed (1 + omega). smibjax follows PSS/E
and the IEEE reports. TA = 0 makes the regulator algebraic (VR = clip(KA y)).

Saturation (PSS/E's for IEEEX1/EXDC2, ANDES `ExcQuadSat`), the default
`saturation="quadratic"`:

    SE(Efd) Efd = B (Efd - A)^2  for Efd > A, else 0,
    a = sqrt(SE1 E1 / (SE2 E2)),  A = E2 - (E1 - E2)/(a - 1),
    B = SE2 E2 (a - 1)^2 / (E1 - E2)^2,

the curve through (E1, SE1) and (E2, SE2); SE1 E1 = 0 or SE2 = 0 (no data)
disables it (B = 0), as in ANDES; SE1 E1 = SE2 E2 != 0 has no such curve and is
refused. `saturation="exponential"` takes instead
SE(Efd) = A e^{B Efd} through the same points (B = ln(SE2/SE1)/(E2 - E1), A = SE1
e^{-B E1}; off where either SE is 0); it is not a PSS/E choice for these models.

KE = 0 marks a self-excited shunt field: as in PSS/E, KE is then set at `init` to
-SE(Efd0), so that VR = 0 at rest (ANDES uses KE = 0 as given). SWITCH is kept as
data and unused (PSS/E ignores it too).

At rest: VR0 = (KE + SE(Efd0)) Efd0, y = VR0/KA, Vf = 0, Vm = Vt0, so Vref = Vt0 -
Vs0 + VR0/KA. `ref` is the array (2, k): row 0 Vref, row 1 the KE in force.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._errors import ParameterError
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

__all__ = ["IEEEX1", "EXDC2", "saturation_coefficients"]

CONS = DYR_MODELS["IEEEX1"]  # EXDC2 has the same CONs


def saturation_coefficients(E1, SE1, E2, SE2, kind="quadratic"):
    """(A, B) of the saturation curve through (E1, SE1), (E2, SE2); see the module
    docstring for both forms. Disabled curves come back with B = 0 (quadratic) or
    A = 0 (exponential)."""
    E1, SE1, E2, SE2 = (jnp.asarray(a, dtype=jnp.float64) for a in (E1, SE1, E2, SE2))
    if kind == "quadratic":
        on = (SE1 * E1 != 0) & (SE2 * E2 != 0)
        p1 = jnp.where(on, SE1 * E1, 1.0)
        p2 = jnp.where(on, SE2 * E2, 4.0)
        a = jnp.sqrt(jnp.abs(p1 / p2))
        d = jnp.where(on, E1 - E2, 1.0)
        am1 = jnp.where(on & (a != 1), a - 1.0, 1.0)
        A = jnp.where(on, E2 - d / am1, 0.0)
        B = jnp.where(on, p2 * am1**2 / d**2, 0.0)
        return A, B
    if kind == "exponential":
        on = (SE1 > 0) & (SE2 > 0) & (E1 != E2)
        B = jnp.where(
            on,
            jnp.log(jnp.where(on, SE2 / SE1, 1.0)) / jnp.where(on, E2 - E1, 1.0),
            0.0,
        )
        A = jnp.where(on, SE1 * jnp.exp(-B * E1), 0.0)
        return A, B
    raise ParameterError(f"saturation = {kind!r}: must be 'quadratic' or 'exponential'")


class _DCExciter(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag (s)
    TC: np.ndarray = eqx.field(converter=f64)  # lead-lag lead (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu; EXDC2: x Vt)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KE: np.ndarray = eqx.field(
        converter=f64
    )  # exciter field constant (0: self-excited)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF1: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    SWITCH: np.ndarray = eqx.field(converter=f64)  # unused (PSS/E too)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu field voltage)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)
    saturation: str = eqx.field(static=True, default="quadratic")

    inputs = ("Vt", "Vs")
    output = "Efd"
    state_names = ("Vm", "x_ll", "VR", "Efd", "x_f")
    con_names = CONS
    vt_limits: ClassVar[bool] = False
    ref_limits: ClassVar[bool] = False  # ref carries KE, VRMAX, VRMIN in force

    def __check_init__(self):
        if self.saturation not in ("quadratic", "exponential"):
            raise ParameterError(
                f"{type(self).__name__}.saturation = {self.saturation!r}: must be "
                "'quadratic' or 'exponential'"
            )
        check(
            self,
            [
                *nonneg("TR", "TA", "KF"),
                *positive("KA", "TE"),
                proper("TC", "TB"),
                ordered("VRMIN", "VRMAX"),
                (
                    "TF1",
                    lambda o: (v(o, "TF1") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0",
                ),
                (
                    "SE2",
                    lambda o: (
                        (o.saturation != "quadratic")
                        | (v(o, "SE1") * v(o, "E1") == 0)
                        | (v(o, "SE2") * v(o, "E2") == 0)
                        | ~np.isclose(
                            v(o, "SE1") * v(o, "E1"),
                            v(o, "SE2") * v(o, "E2"),
                            rtol=1e-9,
                        )
                    ),
                    "must make SE2 E2 != SE1 E1 (no quadratic curve passes "
                    "through both points)",
                ),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params, saturation="quadratic"):
        return build_group(
            cls, gen_positions, params, cls.con_names, saturation=saturation
        )

    def saturation_AB(self):
        """(A, B) of this group's saturation curves."""
        return saturation_coefficients(
            self.E1, self.SE1, self.E2, self.SE2, self.saturation
        )

    def se(self, efd):
        """SE(Efd) (pu/pu): the exciter's saturation function."""
        A, B = self.saturation_AB()
        if self.saturation == "quadratic":
            safe = jnp.where(efd > A, efd, 1.0)
            return jnp.where(efd > A, B * (efd - A) ** 2 / safe, 0.0)
        return A * jnp.exp(B * efd)

    def _se_efd(self, efd):
        """SE(Efd) Efd, without the division (finite at Efd = 0)."""
        A, B = self.saturation_AB()
        if self.saturation == "quadratic":
            return B * jnp.maximum(efd - A, 0.0) ** 2
        return A * jnp.exp(B * efd) * efd

    def _limits(self, meas, ref):
        if self.ref_limits:  # the limits in force, from `init` (ESDC2A)
            lo, hi = ref[3], ref[2]
        else:
            lo, hi = self.VRMIN, self.VRMAX
        if self.vt_limits:
            return lo * meas["Vt"], hi * meas["Vt"]
        return lo, hi

    def _constants(self, y0):
        """(KE, VRMAX, VRMIN) in force: KE = 0 becomes -SE(Efd0) (VR0 = 0)."""
        ke = jnp.where(self.KE == 0, -self.se(y0), self.KE)
        return ke, self.VRMAX + 0.0 * y0, self.VRMIN + 0.0 * y0

    def init(self, y0, meas):
        ke, vrmax, vrmin = self._constants(y0)
        vr0 = ke * y0 + self._se_efd(y0)
        zero = 0.0 * y0
        consts = jnp.stack([ke + zero, vrmax + zero, vrmin + zero])
        lo, hi = self._limits(meas, jnp.concatenate([zero[None], consts]))
        require_at_rest(
            (vr0 >= lo) & (vr0 <= hi),
            type(self).__name__,
            "VR0",
            vr0,
            "the regulator output at the operating point must lie within its limits",
        )
        vref = regulated(meas) - meas["Vs"] + vr0 / self.KA
        vt = regulated(meas) + zero
        y_ll = vref - vt - zero + meas["Vs"]  # as rhs computes it
        x0 = jnp.stack([vt, y_ll, self.KA * y_ll, y0 + zero, y0 + zero])
        if self.ref_limits:
            return x0, jnp.concatenate([vref[None], consts])
        return x0, jnp.stack([vref, ke + zero])

    def _f(self, x, meas, ref):
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        vf, dxf = washout(x[4], x[3], self.KF, self.TF1)
        vi = ref[0] - vm - vf + meas["Vs"]
        y, dll = leadlag(x[1], vi, self.TC, self.TB)
        lo, hi = self._limits(meas, ref)
        vr, dvr = lag_nonwindup(
            x[2], y, self.KA, self.TA, lo, hi, moving=self.vt_limits
        )
        defd = (vr - ref[1] * x[3] - self._se_efd(x[3])) / self.TE
        return jnp.stack([dvm, dll, dvr, defd, dxf])

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)

    def out(self, x, meas, ref):
        return x[3]


class IEEEX1(_DCExciter):
    """PSS/E IEEEX1 (IEEE type 1 / DC1): regulator limits [VRMIN, VRMAX]."""

    vt_limits: ClassVar[bool] = False


class EXDC2(_DCExciter):
    """PSS/E EXDC2 (IEEE type DC2): regulator limits [VRMIN Vt, VRMAX Vt]."""

    vt_limits: ClassVar[bool] = True
