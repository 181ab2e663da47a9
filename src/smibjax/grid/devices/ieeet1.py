"""IEEET1: the 1968 IEEE type 1 DC exciter (PSS/E `IEEET1`, CONs TR, KA, TA, VRMAX,
VRMIN, KE, TE, KF, TF, SWITCH, E1, SE(E1), E2, SE(E2); ANDES `IEEET1`; OpenIPSL
`PSSE.ES.IEEET1`).

    TR dVm/dt = Vc - Vm                            sensing lag (TR = 0: Vm = Vc)
    TA dVR/dt = KA (Vref - Vm - Vf + Vs) - VR      non-windup [VRMIN, VRMAX]
    TE dEfd/dt = VR - (KE + SE(Efd)) Efd           exciter, quadratic saturation
    TF dx_f/dt = Efd - x_f,  Vf = (KF/TF)(Efd - x_f)   rate feedback from Efd

It is ESDC1A's diagram without the lead-lag (TB = TC = 0), with PSS/E's DC-exciter
initialization (`esdc2a.dc_constants`: VRMAX = 0 and KE = 0 computed at rest).
SWITCH is kept as data and unused (PSS/E too). The group holds its own CONs and
evaluates through an ESDC1A of the same data (`as_esdc1a`), so the two cannot
drift apart. States: Vm, x_ll (a placeholder: no lead-lag), VR, Efd, x_f.
"""

from __future__ import annotations

import equinox as eqx
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import build_group
from .base import AbstractController, f64, i64
from .esdc2a import ESDC1A

__all__ = ["IEEET1"]


class IEEET1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # sensing time constant (s)
    KA: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu/pu)
    TA: np.ndarray = eqx.field(converter=f64)  # regulator time constant (s)
    VRMAX: np.ndarray = eqx.field(converter=f64)  # regulator limits (pu; 0: at rest)
    VRMIN: np.ndarray = eqx.field(converter=f64)
    KE: np.ndarray = eqx.field(converter=f64)  # exciter field constant (0: at rest)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    KF: np.ndarray = eqx.field(converter=f64)  # rate feedback gain (pu)
    TF: np.ndarray = eqx.field(converter=f64)  # rate feedback time constant (s)
    SWITCH: np.ndarray = eqx.field(converter=f64)  # unused (PSS/E too)
    E1: np.ndarray = eqx.field(converter=f64)  # saturation points (pu field voltage)
    SE1: np.ndarray = eqx.field(converter=f64)
    E2: np.ndarray = eqx.field(converter=f64)
    SE2: np.ndarray = eqx.field(converter=f64)

    inputs = ("Vt", "Vs")
    output = "Efd"
    state_names = ESDC1A.state_names
    con_names = DYR_MODELS["IEEET1"]

    def __check_init__(self):
        self.as_esdc1a()  # the same rules, named by the same CONs (TF as TF1)

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def as_esdc1a(self) -> ESDC1A:
        """The ESDC1A with this group's data and TB = TC = 0, TF1 = TF."""
        zero = 0.0 * self.TR
        try:
            return ESDC1A(
                # positions unused by init/rhs; jit traces self.gen (issue 46)
                gen=np.zeros(np.shape(self.gen), dtype=np.int64),
                TB=zero,
                TC=zero,
                TF1=self.TF,
                **{n: getattr(self, n) for n in self.con_names if n not in ("TF",)},
            )
        except Exception as e:  # name the model the data came with
            msg = str(e).replace("ESDC1A.TF1", "IEEET1.TF").replace("ESDC1A", "IEEET1")
            raise type(e)(msg) from None

    def init(self, y0, meas):
        return self.as_esdc1a().init(y0, meas)

    def rhs(self, x, meas, ref):
        return self.as_esdc1a().rhs(x, meas, ref)

    def out(self, x, meas, ref):
        return x[3]
