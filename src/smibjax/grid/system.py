"""A power system as data: buses, branches, shunts, loads and power-flow generators,
each group an equinox Module of arrays with a device axis (all quantities in per unit
on the system base `s_base` MVA, angles in radians).

This is the static network and its power-flow data; the dynamic devices (machines,
exciters, stabilizers, governors, SVCs) are described by `smibjax.grid.devices` and
attached to a `System` by `smibjax.grid.case.Case`. Index arrays (`Branches.fr`, ...)
are positions in `Buses`, not PSS/E bus numbers: `Buses.number` keeps those, and
`System.bus_index(number)` maps one to the other.
"""

from __future__ import annotations

import equinox as eqx
import numpy as np
from jaxtyping import Array, Complex, Float, Int

from .._errors import ParameterError

__all__ = [
    "PQ",
    "PV",
    "SLACK",
    "Buses",
    "Branches",
    "Shunts",
    "Loads",
    "Generators",
    "System",
]

PQ, PV, SLACK = 1, 2, 3  # PSS/E bus type codes (IDE)


def _f(x):
    return np.asarray(x, dtype=np.float64)


def _i(x):
    return np.asarray(x, dtype=np.int64)


class Buses(eqx.Module):
    """Buses: PSS/E number, type (PQ = 1, PV = 2, slack = 3), the voltage magnitude
    (pu) and angle (rad) of the raw file (the power flow's start; for PV and slack
    buses the magnitude is overridden by the generators' set point), base kV, area."""

    number: Int[np.ndarray, " n_bus"] = eqx.field(converter=_i)
    kind: Int[np.ndarray, " n_bus"] = eqx.field(converter=_i)
    vm: Float[Array, " n_bus"] = eqx.field(converter=_f)
    va: Float[Array, " n_bus"] = eqx.field(converter=_f)
    base_kv: Float[np.ndarray, " n_bus"] = eqx.field(converter=_f)
    area: Int[np.ndarray, " n_bus"] = eqx.field(converter=_i)
    name: tuple[str, ...] = eqx.field(static=True, default=())


class Branches(eqx.Module):
    """Series branches between bus positions `fr` and `to`: lines (tap = 1, shift = 0)
    and two-winding transformers. Series impedance r + j x (pu), total line charging
    b (pu, half at each end), off-nominal ratio `tap` on the from side and phase shift
    `shift` (rad): the from-end voltage is divided by tap e^{j shift}, the PSS/E and
    MATPOWER convention, so that

        I_fr =  (y + j b/2) / tap^2 V_fr - y / conj(a) V_to
        I_to = -y / a V_fr + (y + j b/2) V_to,    a = tap e^{j shift}, y = 1/(r + j x).

    `status` is 1 in service, 0 out. `ckt` is the PSS/E circuit id;
    `is_transformer` tells the two kinds apart."""

    fr: Int[np.ndarray, " n_br"] = eqx.field(converter=_i)
    to: Int[np.ndarray, " n_br"] = eqx.field(converter=_i)
    r: Float[Array, " n_br"] = eqx.field(converter=_f)
    x: Float[Array, " n_br"] = eqx.field(converter=_f)
    b: Float[Array, " n_br"] = eqx.field(converter=_f)
    tap: Float[Array, " n_br"] = eqx.field(converter=_f)
    shift: Float[Array, " n_br"] = eqx.field(converter=_f)
    status: Float[Array, " n_br"] = eqx.field(converter=_f)
    is_transformer: Int[np.ndarray, " n_br"] = eqx.field(converter=_i)
    ckt: tuple[str, ...] = eqx.field(static=True, default=())


class Shunts(eqx.Module):
    """Fixed shunts: admittance g + j b (pu at 1 pu voltage) at bus position `bus`
    (PSS/E fixed shunts GL, BL and switched shunts at their initial BINIT)."""

    bus: Int[np.ndarray, " n_sh"] = eqx.field(converter=_i)
    g: Float[Array, " n_sh"] = eqx.field(converter=_f)
    b: Float[Array, " n_sh"] = eqx.field(converter=_f)


class Loads(eqx.Module):
    """Loads at bus position `bus`: power p + j q (pu) in the power flow. In the
    dynamic simulation they are converted to constant impedance at the power-flow
    voltage, y = (p - j q) / |V|^2, as transient-stability programs do, unless a
    load model says otherwise (`grid.loads.LoadModel`). `p_i`, `q_i` (pu; empty:
    zeros) are the parts of p and q that the raw file gives as constant current
    (IP, IQ times the raw file's voltage VM), which a load model keeps as constant
    current; the rest of p, q is the raw file's constant power PL, QL (its
    constant admittance YP, YQ is a shunt)."""

    bus: Int[np.ndarray, " n_load"] = eqx.field(converter=_i)
    p: Float[Array, " n_load"] = eqx.field(converter=_f)
    q: Float[Array, " n_load"] = eqx.field(converter=_f)
    ident: tuple[str, ...] = eqx.field(static=True, default=())
    p_i: Float[Array, " n_load"] = eqx.field(converter=_f, default=())
    q_i: Float[Array, " n_load"] = eqx.field(converter=_f, default=())

    def current_parts(self):
        """(p_i, q_i) with zeros where none were given (pu)."""
        n = len(np.asarray(self.bus))
        pi = self.p_i if np.size(self.p_i) else np.zeros(n)
        qi = self.q_i if np.size(self.q_i) else np.zeros(n)
        return pi, qi


class Generators(eqx.Module):
    """Generators' power-flow data at bus position `bus`: scheduled active power p
    (pu), reactive power q (pu, the raw file's QG; the power flow's start), voltage set
    point v_set (pu), reactive limits qmin, qmax (pu; not enforced by the power flow),
    machine base mbase (MVA), status (1 in service) and the source impedance
    zsource = ZR + j ZX of the raw file (pu on mbase; GENCLS's X'd and every model's
    armature resistance come from it, as in PSS/E; empty = zero)."""

    bus: Int[np.ndarray, " n_gen"] = eqx.field(converter=_i)
    p: Float[Array, " n_gen"] = eqx.field(converter=_f)
    q: Float[Array, " n_gen"] = eqx.field(converter=_f)
    v_set: Float[Array, " n_gen"] = eqx.field(converter=_f)
    qmin: Float[Array, " n_gen"] = eqx.field(converter=_f)
    qmax: Float[Array, " n_gen"] = eqx.field(converter=_f)
    mbase: Float[Array, " n_gen"] = eqx.field(converter=_f)
    status: Float[Array, " n_gen"] = eqx.field(converter=_f)
    ident: tuple[str, ...] = eqx.field(static=True, default=())
    zsource: Complex[np.ndarray, " n_gen"] = eqx.field(
        converter=lambda z: np.asarray(z, dtype=np.complex128), default=()
    )

    def source_impedance(self) -> np.ndarray:
        """ZR + j ZX per generator (pu machine base); zeros if none was given."""
        z = np.asarray(self.zsource, dtype=np.complex128)
        return z if z.size else np.zeros(len(self.bus), dtype=np.complex128)


class System(eqx.Module):
    """A network with its power-flow data. `s_base` (MVA) and `f_base` (Hz) are the
    system's bases; `name` is free text (the case's title)."""

    buses: Buses
    branches: Branches
    shunts: Shunts
    loads: Loads
    generators: Generators
    s_base: float = eqx.field(static=True, default=100.0)
    f_base: float = eqx.field(static=True, default=60.0)
    name: str = eqx.field(static=True, default="")

    @property
    def n_bus(self) -> int:
        return len(self.buses.number)

    def bus_index(self, number: int) -> int:
        """Position of the bus with PSS/E number `number`; ValueError if none."""
        hits = np.flatnonzero(np.asarray(self.buses.number) == int(number))
        if hits.size == 0:
            raise ParameterError(f"bus {number} is not in the system")
        return int(hits[0])
