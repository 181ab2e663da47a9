"""IEEET2: the 1968 IEEE type 2 DC exciter, rate feedback from the regulator output
through two lags (PSS/E `IEEET2`, CONs TR, KA, TA, VRMAX, VRMIN, KE, TE, KF, TF1,
TF2, E1, SE(E1), E2, SE(E2); OpenIPSL `PSSE.ES.IEEET2`; ANDES has no IEEET2).

    Vm: TR dVm/dt = Vc - Vm                        sensing lag (TR = 0: Vm = Vc)
    VR: TA dVR/dt = KA (Vref - Vm - Vf + Vs) - VR  regulator, non-windup [VRMIN, VRMAX]
    Efd: TE dEfd/dt = VR - (KE + SE(Efd)) Efd      exciter
    x1: TF1 dx1/dt = VR - x1,   w = (KF/TF1)(VR - x1)     s KF/(1 + s TF1)
    Vf: TF2 dVf/dt = w - Vf                        1/(1 + s TF2) (TF2 = 0: Vf = w)

so Vf = s KF / ((1 + s TF1)(1 + s TF2)) VR, the IEEE 1968 type 2 feedback. SE is
the quadratic saturation through (E1, SE1), (E2, SE2) (`ieeex1.saturation_
coefficients`); the regulator limits are non-windup (drawn on the KA/(1 + s TA)
block). PSS/E's DC-exciter initialization applies (`esdc2a.dc_constants`): VRMAX =
0 and KE = 0 are computed at rest.

At rest: VR0 = (KE + SE(Efd0)) Efd0, x1 = VR0, Vf = 0, Vref = Vc0 - Vs0 + VR0/KA.
`ref` is (4, k): Vref, and the KE, VRMAX, VRMIN in force.
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
    ordered,
    positive,
    regulated,
    require_at_rest,
    v,
    washout,
)
from .base import AbstractController, f64, i64
from .esdc2a import dc_constants
from .ieeex1 import saturation_coefficients

__all__ = ["IEEET2"]


class IEEET2(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu; 0: at rest)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (0: at rest)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF1: np.ndarray = eqx.field(converter=f64)  # rate feedback time constants (s)
    TF2: np.ndarray = eqx.field(converter=f64)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu field voltage)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)

    inputs = ("Vt", "Vs")
    output = "Efd"
    state_names = ("Vm", "VR", "Efd", "x_f1", "Vf")
    con_names = DYR_MODELS["IEEET2"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TR", "TA", "KF", "TF2"),
                *positive("KA", "TE"),
                ordered("VRMIN", "VRMAX"),
                (
                    "TF1",
                    lambda o: (v(o, "TF1") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0",
                ),
                (
                    "TA",
                    lambda o: (v(o, "TA") > 0) | (v(o, "KF") == 0),
                    "must be > 0 where KF != 0 (else an algebraic loop)",
                ),
                (
                    "SE2",
                    lambda o: (
                        (v(o, "SE1") * v(o, "E1") == 0)
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
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _se_efd(self, efd):
        """SE(Efd) Efd = B max(Efd - A, 0)^2 (pu)."""
        A, B = saturation_coefficients(self.E1, self.SE1, self.E2, self.SE2)
        return B * jnp.maximum(efd - A, 0.0) ** 2

    def se(self, efd):
        """SE(Efd) (pu/pu)."""
        safe = jnp.where(efd != 0, efd, 1.0)
        return jnp.where(efd != 0, self._se_efd(efd) / safe, 0.0)

    def init(self, y0, meas):
        ke, vrmax, vrmin = dc_constants(
            self.VRMAX, self.VRMIN, self.KE, self.E2, self.SE2, y0, self.se(y0)
        )
        vr0 = ke * y0 + self._se_efd(y0)
        require_at_rest(
            (vr0 >= vrmin) & (vr0 <= vrmax),
            "IEEET2",
            "VR0",
            vr0,
            "the regulator output at the operating point must lie within its limits",
        )
        vref = regulated(meas) - meas["Vs"] + vr0 / self.KA
        zero = 0.0 * y0
        vc = regulated(meas) + zero
        vr = self.KA * (vref - vc + meas["Vs"])  # as rhs computes it
        x0 = jnp.stack([vc, vr, y0 + zero, vr, zero])
        return x0, jnp.stack([vref, ke + zero, vrmax + zero, vrmin + zero])

    def rhs(self, x, meas, ref):
        vm, dvm = lag(x[0], regulated(meas), 1.0, self.TR)
        # the feedback from the regulator's state (TA > 0 wherever KF != 0)
        w, _ = washout(x[3], jnp.clip(x[1], ref[3], ref[2]), self.KF, self.TF1)
        vf, dvf = lag(x[4], w, 1.0, self.TF2)
        vr, dvr = lag_nonwindup(
            x[1], ref[0] - vm - vf + meas["Vs"], self.KA, self.TA, ref[3], ref[2]
        )
        _, dx1 = washout(x[3], vr, self.KF, self.TF1)
        defd = (vr - ref[1] * x[2] - self._se_efd(x[2])) / self.TE
        return jnp.stack([dvm, dvr, defd, dx1, dvf])

    def out(self, x, meas, ref):
        return x[2]
