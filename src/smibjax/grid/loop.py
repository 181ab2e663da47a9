"""The closed loop of a multi-machine system: initialization at the power-flow
operating point and the vector field (machines, network, controllers, SVCs).

Evaluation order in the vector field, per right-hand-side call:
1. every machine's Norton source -> the port currents;
2. the network solution of the stage in force (`network.solve_ports`);
3. every machine's measurements (angle, speed, powers, terminal voltage) into arrays
   over all generators, by generator position;
4. stabilizers (write "Vs"), then exciters (read "Vt", "Vs"; write "Efd"), then
   governors (read "omega"; write "Pm"): each controller group gathers its inputs at
   its generators' positions and scatters its command back;
5. the machines' and controllers' derivatives; the SVCs' from their bus voltages.
Commands no controller writes stay at their operating-point values (`held`).
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Complex, Float

from .devices.base import AbstractController, AbstractMachine, AbstractShuntDevice
from .network import Grid, StageMatrices, solve_ports
from .system import System

__all__ = ["Case", "Operating", "initialize", "vector_field", "MEASUREMENTS"]

MEASUREMENTS = ("delta", "omega", "Pe", "Qe", "Vt", "It", "Te")
_ORDER = {"Vs": 0, "Efd": 1, "Pm": 2}


class Case(eqx.Module):
    """A multi-machine case: the network and its device groups.

    `machines`: groups of `AbstractMachine`; `controllers`: groups of
    `AbstractController` (any order: the loop evaluates stabilizers, then exciters,
    then governors); `svcs`: groups of `AbstractShuntDevice`; `sources`: generator
    positions that are infinite buses (PSS/E GENCLS with H = 0: a fixed voltage behind
    no impedance), held at their power-flow voltage."""

    system: System
    machines: tuple[AbstractMachine, ...]
    controllers: tuple[AbstractController, ...] = ()
    svcs: tuple[AbstractShuntDevice, ...] = ()
    sources: np.ndarray = eqx.field(default_factory=lambda: np.zeros(0, np.int64))
    name: str = eqx.field(static=True, default="")

    @property
    def n_gen(self) -> int:
        return len(self.system.generators.bus)

    def ordered_controllers(self):
        return sorted(self.controllers, key=lambda c: _ORDER.get(c.output, 3))

    def ports(self) -> np.ndarray:
        gb = np.asarray(self.system.generators.bus)
        buses = [gb[np.asarray(m.gen)] for m in self.machines]
        buses += [np.asarray(s.bus) for s in self.svcs]
        return np.unique(np.concatenate(buses)) if buses else np.zeros(0, np.int64)


class Operating(eqx.Module):
    """A case at its operating point: the network's fixed data (`grid`), the
    operating-point commands of each machine group (`held`), each controller's and
    SVC's reference, the initial state y0 (flat) and the power-flow bus voltages."""

    grid: Grid
    held: tuple[dict, ...]
    refs: tuple[Any, ...]
    svc_refs: tuple[Any, ...]
    y0: Float[Array, " n_state"]
    v_bus: Complex[Array, " n"]
    sizes: tuple[int, ...] = eqx.field(static=True)


def _load_y(system: System, vm):
    ld = system.loads
    y = (ld.p - 1j * ld.q) / vm[np.asarray(ld.bus)] ** 2
    out = jnp.zeros(system.n_bus, dtype=jnp.complex128).at[np.asarray(ld.bus)].add(y)
    sh = system.shunts
    return out.at[np.asarray(sh.bus)].add(sh.g + 1j * sh.b)


def initialize(case: Case, vm, va, p_gen, q_gen) -> Operating:
    """Every device at an exact equilibrium of the power-flow solution: bus voltage
    magnitudes vm (pu) and angles va (rad), generator injections p_gen, q_gen (pu,
    system base). Loads become constant impedances at vm. Jittable and
    differentiable in the power-flow solution."""
    sys_ = case.system
    s_base = sys_.s_base
    v = vm * jnp.exp(1j * va)
    gbus = np.asarray(sys_.generators.bus)
    n_gen = case.n_gen
    s_gen = p_gen + 1j * q_gen
    gen_y = jnp.zeros(n_gen, dtype=jnp.complex128)
    held, blocks = [], []
    meas = {k: jnp.zeros(n_gen) for k in MEASUREMENTS}
    cmd = {"Efd": jnp.zeros(n_gen), "Pm": jnp.zeros(n_gen), "Vs": jnp.zeros(n_gen)}
    for m in case.machines:
        g = np.asarray(m.gen)
        x0, h = m.init(v[gbus[g]], s_gen[g], s_base)
        _, y = m.norton(x0, h, s_base)
        gen_y = gen_y.at[g].set(y)
        held.append(h)
        blocks.append(x0)
        for k, val in m.measure(x0, v[gbus[g]], h, s_base).items():
            if k in meas:
                meas[k] = meas[k].at[g].set(val)
        for k in ("Efd", "Pm"):
            cmd[k] = cmd[k].at[g].set(h[k])
    refs = []
    ctrl_blocks = []
    for c in case.controllers:
        g = np.asarray(c.gen)
        local = {k: meas[k][g] for k in meas} | {"Vs": cmd["Vs"][g]}
        x0, ref = c.init(cmd[c.output][g], local)
        refs.append(ref)
        ctrl_blocks.append(x0)
    svc_refs, svc_blocks = [], []
    for s in case.svcs:
        b = np.asarray(s.bus)
        q = jnp.zeros(sys_.n_bus).at[gbus].add(jnp.imag(s_gen))[b]
        x0, ref = s.init(v[b], q, s_base)
        svc_refs.append(ref)
        svc_blocks.append(x0)
    src = np.asarray(case.sources, dtype=np.int64)
    grid = Grid(
        system=sys_,
        bus_y=_load_y(sys_, vm),
        gen_y=gen_y,
        ports=case.ports(),
        dirichlet=gbus[src],
        v_dirichlet=v[gbus[src]],
    )
    allb = blocks + ctrl_blocks + svc_blocks
    sizes = tuple(int(np.prod(b.shape)) for b in allb)
    y0 = jnp.concatenate([b.reshape(-1) for b in allb]) if allb else jnp.zeros(0)
    return Operating(
        grid=grid,
        held=tuple(held),
        refs=tuple(refs),
        svc_refs=tuple(svc_refs),
        y0=y0,
        v_bus=v,
        sizes=sizes,
    )


def unpack(case: Case, op: Operating, y):
    """The flat state as blocks (n_states, k) per group: machines, controllers, SVCs."""
    groups = [*case.machines, *case.controllers, *case.svcs]
    out, i = [], 0
    for g, size in zip(groups, op.sizes, strict=True):
        ns = len(g.state_names)
        out.append(y[i : i + size].reshape(ns, size // max(ns, 1)) if ns else y[i:i])
        i += size
    nm, nc = len(case.machines), len(case.controllers)
    return out[:nm], out[nm : nm + nc], out[nm + nc :]


def port_index(case: Case) -> dict:
    """Generator position -> port position, bus position -> port position."""
    ports = case.ports()
    return {int(b): k for k, b in enumerate(ports)}


def evaluate(case: Case, op: Operating, mats: StageMatrices, stage, y):
    """(dy/dt, measurements over all generators, net port currents) in stage
    `stage`; the bus voltages are then Z[stage] i + c_all[stage]."""
    sys_ = case.system
    s_base = sys_.s_base
    gbus = np.asarray(sys_.generators.bus)
    pmap = port_index(case)
    xm, xc, xs = unpack(case, op, y)
    A, c = mats.A[stage], mats.c[stage]
    gst = mats.gen_status[stage]
    n_port = len(pmap)
    i_p = jnp.zeros(n_port, dtype=jnp.complex128)
    for m, x, h in zip(case.machines, xm, op.held, strict=True):
        g = np.asarray(m.gen)
        i_n, _ = m.norton(x, h, s_base)
        pidx = np.array([pmap[int(b)] for b in gbus[g]], dtype=np.int64)
        i_p = i_p.at[pidx].add(i_n * gst[g])
    y_sh = None
    if case.svcs:
        y_sh = jnp.zeros(n_port, dtype=jnp.complex128)
        for s, x in zip(case.svcs, xs, strict=True):
            pidx = np.array([pmap[int(b)] for b in np.asarray(s.bus)], dtype=np.int64)
            y_sh = y_sh.at[pidx].add(s.admittance(x, s_base))
    v_p = solve_ports(A, c, i_p, y_sh)
    n_gen = case.n_gen
    meas = {k: jnp.zeros(n_gen) for k in MEASUREMENTS}
    vgen = []
    for m, x, h in zip(case.machines, xm, op.held, strict=True):
        g = np.asarray(m.gen)
        pidx = np.array([pmap[int(b)] for b in gbus[g]], dtype=np.int64)
        vt = v_p[pidx]
        vgen.append(vt)
        for k, val in m.measure(x, vt, h, s_base).items():
            if k in meas:
                meas[k] = meas[k].at[g].set(val)
    cmd = {"Vs": jnp.zeros(n_gen), "Efd": jnp.zeros(n_gen), "Pm": jnp.zeros(n_gen)}
    for m, h in zip(case.machines, op.held, strict=True):
        g = np.asarray(m.gen)
        for k in ("Efd", "Pm"):
            cmd[k] = cmd[k].at[g].set(h[k])
    dctrl = [None] * len(case.controllers)
    order = sorted(
        range(len(case.controllers)),
        key=lambda i: _ORDER.get(case.controllers[i].output, 3),
    )
    for i in order:
        ctl, x, ref = case.controllers[i], xc[i], op.refs[i]
        g = np.asarray(ctl.gen)
        local = {k: meas[k][g] for k in meas} | {"Vs": cmd["Vs"][g]}
        cmd[ctl.output] = cmd[ctl.output].at[g].set(ctl.out(x, local, ref))
        dctrl[i] = ctl.rhs(x, local, ref)
    dm = []
    for m, x, h, vt in zip(case.machines, xm, op.held, vgen, strict=True):
        g = np.asarray(m.gen)
        local = {k: cmd[k][g] for k in ("Efd", "Pm")}
        dm.append(m.rhs(x, vt, local, h, s_base) * gst[g])
    ds = []
    for s, x, ref in zip(case.svcs, xs, op.svc_refs, strict=True):
        pidx = np.array([pmap[int(b)] for b in np.asarray(s.bus)], dtype=np.int64)
        ds.append(s.rhs(x, jnp.abs(v_p[pidx]), jnp.zeros(len(pidx)), ref))
    blocks = dm + dctrl + ds
    dy = jnp.concatenate([b.reshape(-1) for b in blocks]) if blocks else jnp.zeros(0)
    meas = meas | {"Efd": cmd["Efd"], "Pm": cmd["Pm"], "Vs": cmd["Vs"]}
    i_net = i_p if y_sh is None else i_p - y_sh * v_p
    return dy, meas, i_net


def vector_field(case: Case, op: Operating, mats: StageMatrices, t_switch):
    """The diffrax vector field f(t, y, args): the stage in force at t is the number
    of switch times <= t."""

    def f(t, y, args):
        stage = jnp.sum(t >= t_switch) if t_switch.shape[0] else 0
        return evaluate(case, op, mats, stage, y)[0]

    return f
