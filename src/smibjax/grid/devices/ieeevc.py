"""IEEEVC: the IEEE load (line-drop) compensator (PSS/E `IEEEVC`, CONs RC, XC;
ANDES `IEEEVC`): the voltage its machine's exciter regulates becomes

    Vc = |Vt + (RC + j XC) It|

with Vt the terminal voltage phasor (pu) and It the current out of the terminal
(pu, machine base; RC, XC in pu on the machine base). It has no states; the closed
loop evaluates it before the exciters and hands them Vc (`_blocks.regulated`),
also at `init`, so the exciter's Vref holds the compensated voltage at rest. XC >
0 regulates a point behind the terminal (reactive droop); XC < 0 a point out in the
network (line-drop compensation). PSS/E applies no sensing lag here: the exciter's
own TR filters Vc.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import build_group
from .base import AbstractController, f64, i64

__all__ = ["IEEEVC"]


class IEEEVC(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    RC: np.ndarray = eqx.field(converter=f64)  # compensating resistance (pu)
    XC: np.ndarray = eqx.field(converter=f64)  # compensating reactance (pu)

    inputs = ("Vt_re", "Vt_im", "It_re", "It_im")
    output = "Vc"
    state_names = ()
    con_names = DYR_MODELS["IEEEVC"]

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def init(self, y0, meas):
        return jnp.zeros((0, jnp.shape(y0)[0])), jnp.zeros(jnp.shape(y0))

    def rhs(self, x, meas, ref):
        return x

    def out(self, x, meas, ref):
        vt = meas["Vt_re"] + 1j * meas["Vt_im"]
        it = meas["It_re"] + 1j * meas["It_im"]
        return jnp.abs(vt + (self.RC + 1j * self.XC) * it)
