"""The device interface: how a group of devices of one model meets the network and the
other devices.

A device group is an equinox Module holding its parameters as arrays with a device
axis (shape (k,)), the positions of the devices it is attached to (`gen`: positions
in `System.generators`; `bus`: positions in `System.buses`) and nothing else. Its
states are an array of shape (n_states, k): `x[i]` is state `state_names[i]` of every
device in the group. All methods are pure and vectorized over the device axis; no
Python loop over devices.

Units: network quantities (bus voltages, currents, admittances) in pu on the system
base; a machine's own quantities (Pe, Qe, Pm, Efd, currents in `measure`) in pu on its
machine base `mbase`; speeds as per-unit deviations from synchronous speed (omega = 0
at synchronism); angles in rad in the network's synchronous frame; times in s.

Machines (`AbstractMachine`) are sources behind an admittance (Norton form) at their
terminal bus: they inject I = i_norton(x) and add y to the bus's self-admittance.
Controllers (`AbstractController`) read measurements by name and write one command by
name: an exciter reads "Vt" (and "Vs", the stabilizer's output) and writes "Efd"; a
stabilizer reads "omega" or "Pe" and writes "Vs"; a governor reads "omega" and writes
"Pm". The closed loop adds, for every machine model, the terminal voltage and current
phasors "Vt_re", "Vt_im", "It_re", "It_im" (current out of the terminal, machine
base; `loop.terminal_phasors`), and "Vc", the voltage an exciter regulates: a load
compensator's output (IEEEVC writes "Vc"), else Vt. The closed loop gathers each
controller's inputs at its devices' positions and scatters its output back, so
nothing indexes another model's states.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Complex, Float, Int

__all__ = [
    "AbstractMachine",
    "AbstractController",
    "AbstractShuntDevice",
    "AbstractInjector",
    "f64",
    "i64",
]

States = Float[Array, "n_states k"]
Vec = Float[Array, " k"]
CVec = Complex[Array, " k"]


def f64(x):
    """Parameter converter: a float64 array (numpy at build time; JAX arrays pass)."""
    if isinstance(x, np.ndarray | float | int | list | tuple):
        return np.asarray(x, dtype=np.float64)
    return jnp.asarray(x, dtype=jnp.float64)


def i64(x):
    return np.asarray(x, dtype=np.int64)


class AbstractMachine(eqx.Module):
    """A group of synchronous machines (or sources) of one model at positions `gen`
    of `System.generators`. `mbase` (MVA) is each machine's base; the closed loop
    gives every method the system base through `s_base` (MVA)."""

    gen: eqx.AbstractVar[Int[np.ndarray, " k"]]
    mbase: eqx.AbstractVar[Vec]
    state_names: ClassVar[tuple[str, ...]]
    # which states are the rotor angle and the speed deviation (COI, metrics)
    delta_index: ClassVar[int] = 0
    omega_index: ClassVar[int] = 1

    @abc.abstractmethod
    def norton(
        self, x: States, held: dict[str, Vec], s_base: float
    ) -> tuple[CVec, CVec]:
        """(i, y): the injected current source (pu, system base, network frame) and
        the shunt admittance (pu, system base) at the terminal bus. `held` is the
        commands' operating-point values from `init` (GENCLS takes its constant EMF
        from held["Efd"]); the network solution must not depend on this step's
        commands."""

    @abc.abstractmethod
    def rhs(
        self,
        x: States,
        v: CVec,
        cmd: dict[str, Vec],
        held: dict[str, Vec],
        s_base: float,
    ) -> States:
        """dx/dt given the terminal voltages v (pu, network frame) and the commands
        cmd["Efd"] (field voltage, pu) and cmd["Pm"] (mechanical power, pu machine
        base)."""

    @abc.abstractmethod
    def measure(
        self, x: States, v: CVec, held: dict[str, Vec], s_base: float
    ) -> dict[str, Vec]:
        """Measurements: "delta" (rad), "omega" (pu deviation), "Pe", "Qe" (pu machine
        base, out of the terminal), "Vt" (pu), "It" (pu machine base), "Te" (air-gap
        torque, pu machine base), "XadIfd" (field current on the Xad base, pu: Efd at
        rest; a classical machine gives its constant |E'|)."""

    @abc.abstractmethod
    def init(self, v: CVec, s: CVec, s_base: float) -> tuple[States, dict[str, Vec]]:
        """(x0, cmd0): the equilibrium states for terminal voltages v and power
        injections s = P + jQ (pu, system base) from the power flow, and the commands
        ("Efd", "Pm") that hold them."""


class AbstractController(eqx.Module):
    """A group of controllers of one model. `gen` (or, for bus devices, `bus`) says
    where each device sits; `inputs` names the measurements it reads, `output` the
    command it writes. `ref` is whatever the group's `init` computed to start at
    equilibrium (a voltage reference, a load reference), passed back to every call."""

    inputs: ClassVar[tuple[str, ...]]
    output: ClassVar[str]
    state_names: ClassVar[tuple[str, ...]]

    @abc.abstractmethod
    def init(self, y0: Vec, meas: dict[str, Vec]) -> tuple[States, Vec]:
        """(x0, ref): states and reference for which the output is y0 at rest, given
        the measurements at the operating point."""

    @abc.abstractmethod
    def rhs(self, x: States, meas: dict[str, Vec], ref: Vec) -> States:
        """dx/dt."""

    @abc.abstractmethod
    def out(self, x: States, meas: dict[str, Vec], ref: Vec) -> Vec:
        """The command (after the device's own output limits)."""


class AbstractShuntDevice(eqx.Module):
    """A group of voltage-dependent shunt devices (SVCs) at bus positions `bus`: a
    variable admittance y(x) at the bus, solved with the network at every evaluation.
    """

    bus: eqx.AbstractVar[Int[np.ndarray, " k"]]
    state_names: ClassVar[tuple[str, ...]]

    @abc.abstractmethod
    def admittance(self, x: States, s_base: float) -> CVec:
        """The shunt admittance (pu, system base)."""

    @abc.abstractmethod
    def rhs(self, x: States, vm: Vec, cmd: Vec, ref: Vec) -> States:
        """dx/dt given the bus voltage magnitude vm (pu) and an external command."""

    @abc.abstractmethod
    def init(self, v: CVec, q: Vec, s_base: float) -> tuple[States, Vec]:
        """(x0, ref) for bus voltages v and reactive injection q (pu, system base)."""


class AbstractInjector(eqx.Module):
    """A group of current injectors of one model at bus positions `bus`: devices
    whose current into the network depends on their bus voltage (and their own
    states), solved with the network by Newton's method at every evaluation
    (`network.solve_injections`). Loads other than constant impedances (`ZIPLoad`)
    and inverter-based resources are injectors.

    The contract (every method pure, vectorized over the device axis k):

    - `bus` (k,): bus positions in `System.buses`, fixed when the case is built
      (the loop makes every injector bus a port of the reduced network).
    - `source` (ClassVar): where the device's power-flow injection comes from:
      "gen" (the generator at position `gen[i]` of `System.generators`, s0 =
      P_gen + j Q_gen; a tripped generator (`GenTrip`) injects nothing and its
      injector's states freeze) or "load" (the load at position `load[i]` of
      `System.loads`, s0 = -(p + j q): the load is then taken out of the constant
      impedances the loop adds to the network, and the device's `admittance` put
      in its place). The group holds `gen` or `load` (k,) accordingly.
    - `state_names` (ClassVar): its states, x of shape (n_states, k); zero states
      allowed (x of shape (0, k)).
    - `init(v0, s0, s_base) -> (x0, ref)`: v0 (k,) complex bus voltages (pu) and
      s0 (k,) complex power injected INTO the network (pu, system base) at the
      power-flow solution; returns the states at rest and whatever reference the
      device needs (any pytree of arrays with a trailing device axis), such that
      `v0 * conj(current(x0, v0, ref, s_base) + admittance(ref, s_base) * v0)`
      equals s0 and `rhs(x0, v0, ref, s_base)` is zero.
    - `current(x, v, ref, s_base) -> (k,) complex`: the current injected into the
      network (pu, system base, network frame) at bus voltages v (pu). It must
      depend on each device's own v[i] only (the Newton solve takes the per-device
      derivatives with respect to Re v and Im v by two forward-mode products), be
      finite for every v including 0, and be differentiable.
    - `rhs(x, v, ref, s_base) -> (n_states, k)`: dx/dt at bus voltages v.
    - `admittance(ref, s_base) -> (k,) complex`: a constant shunt admittance
      (pu, system base) the device adds to its bus for the whole run (the linear
      part of a load; default zero); it is solved with the linear network, not by
      Newton.
    """

    bus: eqx.AbstractVar[Int[np.ndarray, " k"]]
    state_names: ClassVar[tuple[str, ...]]
    source: ClassVar[str] = "gen"

    @abc.abstractmethod
    def init(self, v0: CVec, s0: CVec, s_base: float) -> tuple[States, object]:
        """(x0, ref) at rest for bus voltages v0 (pu) and power injected into the
        network s0 (pu, system base)."""

    @abc.abstractmethod
    def current(self, x: States, v: CVec, ref, s_base: float) -> CVec:
        """The current injected into the network (pu, system base)."""

    def rhs(self, x: States, v: CVec, ref, s_base: float) -> States:
        """dx/dt (default: no states)."""
        return jnp.zeros_like(x)

    def admittance(self, ref, s_base: float) -> CVec:
        """A constant shunt admittance added at the bus (pu, system base)."""
        return jnp.zeros(len(self.bus), dtype=jnp.complex128)
