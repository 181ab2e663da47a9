"""Direct inputs: a machine's field voltage and an SVC's susceptance commanded from
outside (the paper's synergetic law, open-loop studies, a controller under test).

`DirectField` (an exciter with no states):

    Efd = clip(Efd0 + Efd_cmd, EMIN, EMAX)

with Efd0 the operating point's field voltage, held from `init` as `ref`, and
Efd_cmd the external command (pu, the input named "Efd_cmd"; 0 gives the `none`
baseline of docs/model.md section 2). The clip is a plain output limit (default: none).

`DirectSVC` (a shunt device at bus positions `bus`): the paper's SVC (docs/model.md
section 1),

    TR dB/dt = -(B - B0) + clip(u, UMIN, UMAX)

with B the net susceptance (pu on the system base, capacitive positive), B0 its
operating-point value (from the power flow's reactive injection q = B0 |V|^2, held
as `ref`) and u the external command (pu, system base). The limits are on the
command, as docs/model.md's u_r in [ur_min, ur_max], which keeps B - B0 in the same
range. `CSVGN1` with K = 0 reduces to this.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._blocks import build_group, check, ordered, positive
from .base import AbstractController, AbstractShuntDevice, f64, i64

__all__ = ["DirectField", "DirectSVC"]


class DirectField(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    EMIN: np.ndarray = eqx.field(converter=f64, default=-np.inf)  # output limits (pu)
    EMAX: np.ndarray = eqx.field(converter=f64, default=np.inf)

    inputs = ("Efd_cmd",)
    output = "Efd"
    state_names = ()
    con_names = ()

    def __check_init__(self):
        check(self, [ordered("EMIN", "EMAX")])

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` may hold EMIN, EMAX (default: no limits)."""
        params = [{"EMIN": -np.inf, "EMAX": np.inf, **p} for p in params]
        return build_group(cls, gen_positions, params, ("EMIN", "EMAX"))

    def init(self, y0, meas):
        return jnp.zeros((0,) + jnp.shape(y0)), y0

    def rhs(self, x, meas, ref):
        return x

    def out(self, x, meas, ref):
        return jnp.clip(ref + meas["Efd_cmd"], self.EMIN, self.EMAX)


class DirectSVC(AbstractShuntDevice):
    bus: np.ndarray = eqx.field(converter=i64)
    TR: np.ndarray = eqx.field(converter=f64)  # SVC time constant (s)
    UMIN: np.ndarray = eqx.field(converter=f64, default=-np.inf)  # command limits
    UMAX: np.ndarray = eqx.field(converter=f64, default=np.inf)  # (pu, system base)

    state_names = ("B",)

    def __check_init__(self):
        check(self, [*positive("TR"), ordered("UMIN", "UMAX")])

    @classmethod
    def from_params(cls, bus_positions, params):
        """`params[i]` holds TR and may hold UMIN, UMAX (default: no limits)."""
        params = [{"UMIN": -np.inf, "UMAX": np.inf, **p} for p in params]
        return build_group(
            cls, bus_positions, params, ("TR", "UMIN", "UMAX"), pos_field="bus"
        )

    def admittance(self, x, s_base):
        return 1j * x[0]

    def rhs(self, x, vm, cmd, ref):
        u = jnp.clip(cmd, self.UMIN, self.UMAX)
        return jnp.stack([(-(x[0] - ref) + u) / self.TR])

    def init(self, v, q, s_base):
        b0 = q / jnp.abs(v) ** 2
        return jnp.stack([b0]), b0
