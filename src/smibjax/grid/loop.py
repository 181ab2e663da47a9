"""The closed loop of a multi-machine system: initialization at the power-flow
operating point and the vector field (machines, network, controllers, SVCs).

Evaluation order in the vector field, per right-hand-side call:
1. every machine's Norton source -> the port currents;
2. the network solution of the stage in force (`network.solve_ports`);
3. every machine's measurements (angle, speed, powers, terminal voltage) into arrays
   over all generators, by generator position;
4. stabilizers (write "Vs"), then exciters (read "Vt", "Vs"; write "Efd"), then
   governors (read "omega"; write "Pm"): each controller group gathers its inputs at
   its generators' positions and scatters its command back; load/line-drop
   compensators (write "Vc", the voltage the exciters regulate; Vt where there is
   none) come first;
5. the machines' and controllers' derivatives; the SVCs' from their bus voltages.
   A tripped machine (generator status 0) injects nothing and its states and its
   controllers' states freeze.
With current injectors (`AbstractInjector`: loads other than impedances, inverter
based resources) step 2 is a Newton solve of the network with their currents
(`network.solve_injections`); without them it is the linear solution, unchanged.
Commands no controller writes stay at their operating-point values (`held`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Complex, Float

from .devices.base import (
    AbstractController,
    AbstractInjector,
    AbstractMachine,
    AbstractShuntDevice,
)
from .network import Grid, StageMatrices, solve_injections, solve_ports
from .system import System

__all__ = [
    "Case",
    "Operating",
    "with_injectors",
    "evaluate_all",
    "network_residual",
    "initialize",
    "vector_field",
    "MEASUREMENTS",
    "PHASORS",
    "terminal_phasors",
]

MEASUREMENTS = ("delta", "omega", "Pe", "Qe", "Vt", "It", "Te", "XadIfd")
# the terminal phasors, computed here for every machine model from its Norton form
# (`terminal_phasors`): voltage (pu) and current out of the terminal (pu, machine
# base), real and imaginary parts in the network frame
PHASORS = ("Vt_re", "Vt_im", "It_re", "It_im")
_ORDER = {"Vc": -1, "Vs": 0, "Efd": 1, "Pm": 2}


def terminal_phasors(m, i_n, y, vt, s_base):
    """The terminal voltage vt (pu) and the current out of the terminal of machine
    group `m`, (i_n - y vt) s_base / mbase (pu, machine base), from its Norton source
    i_n and admittance y (system base), as the measurements of `PHASORS`."""
    it = (i_n - y * vt) * (s_base / m.mbase)
    return {
        "Vt_re": jnp.real(vt),
        "Vt_im": jnp.imag(vt),
        "It_re": jnp.real(it),
        "It_im": jnp.imag(it),
    }


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where every device group sits, as hashable tuples fixed when the case is
    built (positions stay Python constants under jit, so a case can be passed to
    jitted functions whole): generator positions of each machine and controller
    group, the port of each machine and SVC, the port buses, infinite-bus
    generators and their buses."""

    ports: tuple[int, ...]
    machine_gen: tuple[tuple[int, ...], ...]
    machine_port: tuple[tuple[int, ...], ...]
    controller_gen: tuple[tuple[int, ...], ...]
    svc_bus: tuple[tuple[int, ...], ...]
    svc_port: tuple[tuple[int, ...], ...]
    source_gen: tuple[int, ...]
    source_bus: tuple[int, ...]
    gen_bus: tuple[int, ...]
    n_gen: int
    n_bus: int
    # current injectors (issue 47): per group, the bus positions, the port of each
    # device, its power-flow source position (a generator or a load, `source`), the
    # position of its port among the injector ports; and the injector ports (unique
    # port positions, in order)
    injector_bus: tuple[tuple[int, ...], ...] = ()
    injector_port: tuple[tuple[int, ...], ...] = ()
    injector_src: tuple[tuple[int, ...], ...] = ()
    injector_jpos: tuple[tuple[int, ...], ...] = ()
    inj_ports: tuple[int, ...] = ()


def make_layout(
    system: System, machines, controllers, svcs, sources, injectors=()
) -> Layout:
    gb = np.asarray(system.generators.bus)
    mg = [tuple(int(i) for i in np.asarray(m.gen)) for m in machines]
    sb = [tuple(int(i) for i in np.asarray(s.bus)) for s in svcs]
    ib = [tuple(int(i) for i in np.asarray(d.bus)) for d in injectors]
    buses = [gb[list(g)] for g in mg] + [
        np.array(b, dtype=np.int64) for b in (*sb, *ib)
    ]
    ports = tuple(int(b) for b in np.unique(np.concatenate(buses))) if buses else ()
    pmap = {b: k for k, b in enumerate(ports)}
    src = tuple(int(i) for i in np.asarray(sources))
    iport = tuple(tuple(pmap[b] for b in g) for g in ib)
    jports = tuple(sorted({p for g in iport for p in g}))
    jmap = {p: k for k, p in enumerate(jports)}
    isrc = tuple(
        tuple(int(i) for i in np.asarray(getattr(d, d.source))) for d in injectors
    )
    return Layout(
        injector_bus=tuple(ib),
        injector_port=iport,
        injector_src=isrc,
        injector_jpos=tuple(tuple(jmap[p] for p in g) for g in iport),
        inj_ports=jports,
        ports=ports,
        machine_gen=tuple(mg),
        machine_port=tuple(tuple(pmap[int(gb[i])] for i in g) for g in mg),
        controller_gen=tuple(
            tuple(int(i) for i in np.asarray(c.gen)) for c in controllers
        ),
        svc_bus=tuple(sb),
        svc_port=tuple(tuple(pmap[b] for b in g) for g in sb),
        source_gen=src,
        source_bus=tuple(int(gb[i]) for i in src),
        gen_bus=tuple(int(b) for b in gb),
        n_gen=len(gb),
        n_bus=system.n_bus,
    )


class Case(eqx.Module):
    """A multi-machine case: the network and its device groups.

    `machines`: groups of `AbstractMachine`; `controllers`: groups of
    `AbstractController` (any order: the loop evaluates stabilizers, then exciters,
    then governors); `svcs`: groups of `AbstractShuntDevice`; `sources`: generator
    positions that are infinite buses (PSS/E GENCLS with H = 0: a fixed voltage behind
    no impedance), held at their power-flow voltage; `injectors`: groups of
    `AbstractInjector` (current injectors solved with the network by Newton's method;
    none: the linear network). A case with new device groups needs a new layout:
    build it anew (`with_injectors`) rather than `eqx.tree_at`."""

    system: System
    machines: tuple[AbstractMachine, ...]
    controllers: tuple[AbstractController, ...] = ()
    svcs: tuple[AbstractShuntDevice, ...] = ()
    sources: tuple[int, ...] = eqx.field(static=True, default=())
    name: str = eqx.field(static=True, default="")
    layout: Layout = eqx.field(static=True, default=None)
    injectors: tuple[AbstractInjector, ...] = ()

    def __post_init__(self):
        if self.layout is None:
            lay = make_layout(
                self.system,
                self.machines,
                self.controllers,
                self.svcs,
                self.sources,
                self.injectors,
            )
            object.__setattr__(self, "layout", lay)

    @property
    def n_gen(self) -> int:
        return self.layout.n_gen

    def ports(self) -> np.ndarray:
        return np.asarray(self.layout.ports, dtype=np.int64)


def with_injectors(case: Case, injectors) -> Case:
    """`case` with its injector groups replaced by `injectors` (a new layout)."""
    return Case(
        system=case.system,
        machines=case.machines,
        controllers=case.controllers,
        svcs=case.svcs,
        sources=case.sources,
        name=case.name,
        injectors=tuple(injectors),
    )


class Operating(eqx.Module):
    """A case at its operating point: the network's fixed data (`grid`), the
    operating-point commands of each machine group (`held`), each controller's and
    SVC's reference, the initial state y0 (flat) and the power-flow bus voltages;
    with injectors, each group's reference (`inj_refs`) and the injectors'
    equivalent admittance at rest per injector port (`inj_y0`, pu: the Newton
    solve's start)."""

    grid: Grid
    held: tuple[dict, ...]
    refs: tuple[Any, ...]
    svc_refs: tuple[Any, ...]
    y0: Float[Array, " n_state"]
    v_bus: Complex[Array, " n"]
    sizes: tuple[int, ...] = eqx.field(static=True)
    inj_refs: tuple[Any, ...] = ()
    inj_y0: Complex[Array, " J"] | None = None


def _load_y(system: System, vm, keep=None):
    """Loads as constant impedances at the voltages vm (pu), except those a
    "load" injector holds (`keep`: 0 there), plus the fixed shunts, per bus (pu)."""
    ld = system.loads
    y = (ld.p - 1j * ld.q) / vm[np.asarray(ld.bus)] ** 2
    if keep is not None:
        y = y * keep
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
    lay = case.layout
    gbus = np.asarray(lay.gen_bus, dtype=np.int64)
    n_gen = case.n_gen
    s_gen = p_gen + 1j * q_gen
    gen_y = jnp.zeros(n_gen, dtype=jnp.complex128)
    held, blocks = [], []
    meas = {k: jnp.zeros(n_gen) for k in MEASUREMENTS + PHASORS}
    cmd = {"Efd": jnp.zeros(n_gen), "Pm": jnp.zeros(n_gen), "Vs": jnp.zeros(n_gen)}
    for m, gt in zip(case.machines, lay.machine_gen, strict=True):
        g = np.asarray(gt, dtype=np.int64)
        x0, h = m.init(v[gbus[g]], s_gen[g], s_base)
        i_n, y = m.norton(x0, h, s_base)
        gen_y = gen_y.at[g].set(y)
        held.append(h)
        blocks.append(x0)
        ms = m.measure(x0, v[gbus[g]], h, s_base)
        ms |= terminal_phasors(m, i_n, y, v[gbus[g]], s_base)
        for k, val in ms.items():
            if k in meas:
                meas[k] = meas[k].at[g].set(val)
        for k in ("Efd", "Pm"):
            cmd[k] = cmd[k].at[g].set(h[k])
    cmd["Vc"] = meas["Vt"]
    refs = [None] * len(case.controllers)
    ctrl_blocks = [None] * len(case.controllers)
    # in evaluation order: a compensator's Vc0 reaches the exciters' init
    for i in sorted(
        range(len(case.controllers)),
        key=lambda i: _ORDER.get(case.controllers[i].output, 3),
    ):
        c, gt = case.controllers[i], lay.controller_gen[i]
        g = np.asarray(gt, dtype=np.int64)
        local = {k: meas[k][g] for k in meas} | {
            "Vs": cmd["Vs"][g],
            "Vc": cmd["Vc"][g],
            "Efd_cmd": jnp.zeros(len(g)),
        }
        x0, ref = c.init(cmd[c.output][g], local)
        if c.output == "Vc":
            cmd["Vc"] = cmd["Vc"].at[g].set(c.out(x0, local, ref))
        refs[i] = ref
        ctrl_blocks[i] = x0
    svc_refs, svc_blocks = [], []
    for s, bt in zip(case.svcs, lay.svc_bus, strict=True):
        b = np.asarray(bt, dtype=np.int64)
        q = jnp.zeros(sys_.n_bus).at[gbus].add(jnp.imag(s_gen))[b]
        x0, ref = s.init(v[b], q, s_base)
        svc_refs.append(ref)
        svc_blocks.append(x0)
    inj_refs, inj_blocks, bus_y, inj_y0, load_y = _init_injectors(case, v, s_gen, vm)
    src = np.asarray(lay.source_gen, dtype=np.int64)
    grid = Grid(
        system=sys_,
        bus_y=bus_y,
        gen_y=gen_y,
        ports=case.ports(),
        dirichlet=gbus[src],
        v_dirichlet=v[gbus[src]],
        load_y=load_y,
    )
    allb = blocks + ctrl_blocks + svc_blocks + inj_blocks
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
        inj_refs=inj_refs,
        inj_y0=inj_y0,
    )


def _init_injectors(case: Case, v, s_gen, vm):
    """Each injector group at rest: (refs, state blocks, the bus admittances of the
    loads left as impedances, the shunts and the injectors' own admittances (pu),
    the injectors' equivalent admittance at rest per injector port (None without
    injectors), each load's constant-impedance part (pu))."""
    sys_ = case.system
    s_base = sys_.s_base
    lay = case.layout
    ld = sys_.loads
    load_y = (jnp.asarray(ld.p) - 1j * jnp.asarray(ld.q)) / vm[np.asarray(ld.bus)] ** 2
    if not case.injectors:
        return (), [], _load_y(sys_, vm), None, load_y
    keep = np.ones(len(np.asarray(ld.bus)))
    s_load = -(jnp.asarray(ld.p) + 1j * jnp.asarray(ld.q))
    refs, blocks = [], []
    y_start = jnp.zeros(len(lay.inj_ports), dtype=jnp.complex128)
    extra = jnp.zeros(sys_.n_bus, dtype=jnp.complex128)
    for k, d in enumerate(case.injectors):
        b = np.asarray(lay.injector_bus[k], dtype=np.int64)
        src = np.asarray(lay.injector_src[k], dtype=np.int64)
        if d.source == "load":
            keep[src] = 0.0
            s0 = s_load[src]
        else:
            s0 = s_gen[src]
        x0, ref = d.init(v[b], s0, s_base)
        i0 = d.current(x0, v[b], ref, s_base)
        jp = np.asarray(lay.injector_jpos[k], dtype=np.int64)
        y_start = y_start.at[jp].add(-i0 / v[b])
        y_d = d.admittance(ref, s_base)
        extra = extra.at[b].add(y_d)
        if d.source == "load":
            load_y = load_y.at[src].set(y_d)
        refs.append(ref)
        blocks.append(x0)
    bus_y = _load_y(sys_, vm, jnp.asarray(keep)) + extra
    return tuple(refs), blocks, bus_y, y_start, load_y


def unpack(case: Case, op: Operating, y):
    """The flat state as blocks (n_states, k) per group: machines, controllers, SVCs
    (`unpack_injectors`: the injectors' blocks, which follow)."""
    return _unpack(case, op, y)[:3]


def unpack_injectors(case: Case, op: Operating, y):
    """The injectors' state blocks (n_states, k) per group."""
    return _unpack(case, op, y)[3]


def _unpack(case: Case, op: Operating, y):
    groups = [*case.machines, *case.controllers, *case.svcs, *case.injectors]
    out, i = [], 0
    for g, size in zip(groups, op.sizes, strict=True):
        ns = len(g.state_names)
        out.append(y[i : i + size].reshape(ns, size // max(ns, 1)) if ns else y[i:i])
        i += size
    nm, nc, ns = len(case.machines), len(case.controllers), len(case.svcs)
    return (
        out[:nm],
        out[nm : nm + nc],
        out[nm + nc : nm + nc + ns],
        out[nm + nc + ns :],
    )


def gen_names(case: Case) -> tuple[str, ...]:
    """'bus:id' per generator (PSS/E bus number and machine id)."""
    sys_ = case.system
    nums = np.asarray(sys_.buses.number)[np.asarray(case.layout.gen_bus, dtype=int)]
    ids = sys_.generators.ident or ("1",) * len(nums)
    return tuple(f"{int(b)}:{str(i).strip()}" for b, i in zip(nums, ids, strict=True))


def state_labels(case: Case) -> tuple[tuple[str, str, str], ...]:
    """(device group model, generator or bus name, state name) of every entry of the
    flat state, in order."""
    names = gen_names(case)
    bus_nums = np.asarray(case.system.buses.number)
    out = []
    lay = case.layout
    groups = (
        [(m, lay.machine_gen[k], "gen") for k, m in enumerate(case.machines)]
        + [(c, lay.controller_gen[k], "gen") for k, c in enumerate(case.controllers)]
        + [(s, lay.svc_bus[k], "bus") for k, s in enumerate(case.svcs)]
        + [(d, lay.injector_bus[k], "bus") for k, d in enumerate(case.injectors)]
    )
    for dev, where, kind in groups:
        label = [names[i] if kind == "gen" else str(int(bus_nums[i])) for i in where]
        for st in dev.state_names:
            out += [(type(dev).__name__, lab, st) for lab in label]
    return tuple(out)


def evaluate(case: Case, op: Operating, mats: StageMatrices, stage, y, u=None):
    """`evaluate_all` without the network residual."""
    return evaluate_all(case, op, mats, stage, y, u)[:3]


def network_residual(case: Case, op: Operating, mats: StageMatrices, stage, y):
    """The residual of the network solution with injectors (pu voltage, max over the
    injector ports; 0 without injectors): above `network.COLLAPSE_TOL` the network
    has no solution at state y (voltage collapse)."""
    return evaluate_all(case, op, mats, stage, y)[3]


def evaluate_all(case: Case, op: Operating, mats: StageMatrices, stage, y, u=None):
    """(dy/dt, measurements over all generators, net port currents) in stage
    `stage`; the bus voltages are then `mats.bus_voltages(stage, i)`. `u`: optional
    additive inputs by name over all generators: "Efd" and "Pm" (added to the
    machines' commands), "Vs" (added to the stabilizer signal the exciters read),
    "Efd_cmd" (the external command a DirectField exciter reads; 0 without it);
    "Bsvc" over all buses (added to the SVCs' external command). A fourth output:
    the network residual (`network_residual`)."""
    u = {} if u is None else u
    sys_ = case.system
    s_base = sys_.s_base
    lay = case.layout
    xm, xc, xs, xi = _unpack(case, op, y)
    A, c = mats.A[stage], mats.c[stage]
    gst = mats.gen_status[stage]
    n_port = len(lay.ports)
    i_p = jnp.zeros(n_port, dtype=jnp.complex128)
    nortons = []
    for k, (m, x, h) in enumerate(zip(case.machines, xm, op.held, strict=True)):
        g = np.asarray(lay.machine_gen[k], dtype=np.int64)
        i_n, y_n = m.norton(x, h, s_base)
        nortons.append((i_n, y_n))
        pidx = np.asarray(lay.machine_port[k], dtype=np.int64)
        i_p = i_p.at[pidx].add(i_n * gst[g])
    y_sh = None
    if case.svcs:
        y_sh = jnp.zeros(n_port, dtype=jnp.complex128)
        for k, (s, x) in enumerate(zip(case.svcs, xs, strict=True)):
            pidx = np.asarray(lay.svc_port[k], dtype=np.int64)
            y_sh = y_sh.at[pidx].add(s.admittance(x, s_base))
    res = jnp.zeros(())
    if case.injectors:
        scale = None if mats.load_scale is None else mats.load_scale[stage]
        inj_on = [
            gst[np.asarray(lay.injector_src[k], dtype=np.int64)]
            if d.source == "gen"
            else (
                jnp.ones(len(lay.injector_src[k]))
                if scale is None
                else scale[np.asarray(lay.injector_src[k], dtype=np.int64)]
            )
            for k, d in enumerate(case.injectors)
        ]

        def inj_current(vj):
            tot = jnp.zeros(len(lay.inj_ports), dtype=jnp.complex128)
            for k, (d, x, ref) in enumerate(
                zip(case.injectors, xi, op.inj_refs, strict=True)
            ):
                jp = np.asarray(lay.injector_jpos[k], dtype=np.int64)
                tot = tot.at[jp].add(d.current(x, vj[jp], ref, s_base) * inj_on[k])
            return tot

        v_p, _, res = solve_injections(
            A, c, i_p, y_sh, lay.inj_ports, inj_current, op.inj_y0
        )
        vj = v_p[np.asarray(lay.inj_ports, dtype=np.int64)]
        i_p = i_p.at[np.asarray(lay.inj_ports, dtype=np.int64)].add(inj_current(vj))
    else:
        v_p = solve_ports(A, c, i_p, y_sh)
    n_gen = case.n_gen
    meas = {k: jnp.zeros(n_gen) for k in MEASUREMENTS + PHASORS}
    vgen = []
    for k, (m, x, h) in enumerate(zip(case.machines, xm, op.held, strict=True)):
        g = np.asarray(lay.machine_gen[k], dtype=np.int64)
        vt = v_p[np.asarray(lay.machine_port[k], dtype=np.int64)]
        vgen.append(vt)
        on = gst[g]
        ms = m.measure(x, vt, h, s_base)
        ms |= terminal_phasors(m, *nortons[k], vt, s_base)
        for k, val in ms.items():
            if k in meas:
                val = (
                    val * on if k in ("Pe", "Qe", "It", "Te", "It_re", "It_im") else val
                )
                meas[k] = meas[k].at[g].set(val)
    cmd = {"Vs": jnp.zeros(n_gen), "Efd": jnp.zeros(n_gen), "Pm": jnp.zeros(n_gen)}
    cmd["Vc"] = meas["Vt"]
    for gt, h in zip(lay.machine_gen, op.held, strict=True):
        g = np.asarray(gt, dtype=np.int64)
        for k in ("Efd", "Pm"):
            cmd[k] = cmd[k].at[g].set(h[k])
    dctrl = [None] * len(case.controllers)
    order = sorted(
        range(len(case.controllers)),
        key=lambda i: _ORDER.get(case.controllers[i].output, 3),
    )
    for i in order:
        ctl, x, ref = case.controllers[i], xc[i], op.refs[i]
        g = np.asarray(lay.controller_gen[i], dtype=np.int64)
        vs = cmd["Vs"][g] + (u["Vs"][g] if "Vs" in u else 0.0)
        if mats.vref_add is not None:  # a Vref step enters where Vs does
            vs = vs + mats.vref_add[stage][g]
        if mats.pref_add is not None and ctl.output == "Pm":
            ref = ref + mats.pref_add[stage][g]
        efd_cmd = u["Efd_cmd"][g] if "Efd_cmd" in u else jnp.zeros(len(g))
        local = {k: meas[k][g] for k in meas} | {
            "Vs": vs,
            "Vc": cmd["Vc"][g],
            "Efd_cmd": efd_cmd,
        }
        cmd[ctl.output] = cmd[ctl.output].at[g].set(ctl.out(x, local, ref))
        d = ctl.rhs(x, local, ref)  # (n_states, k); a tripped machine's stop:
        dctrl[i] = (jnp.reshape(d, (-1, len(g))) * gst[g]).reshape(jnp.shape(d))
    dm = []
    for k, (m, x, h, vt) in enumerate(
        zip(case.machines, xm, op.held, vgen, strict=True)
    ):
        g = np.asarray(lay.machine_gen[k], dtype=np.int64)
        local = {k: cmd[k][g] + (u[k][g] if k in u else 0.0) for k in ("Efd", "Pm")}
        dm.append(m.rhs(x, vt, local, h, s_base) * gst[g])
    ds = []
    for k, (s, x, ref) in enumerate(zip(case.svcs, xs, op.svc_refs, strict=True)):
        pidx = np.asarray(lay.svc_port[k], dtype=np.int64)
        ext = u["Bsvc"][np.asarray(lay.svc_bus[k])] if "Bsvc" in u else 0.0
        ds.append(s.rhs(x, jnp.abs(v_p[pidx]), jnp.zeros(len(pidx)) + ext, ref))
    di = []
    for k, (d, x, ref) in enumerate(zip(case.injectors, xi, op.inj_refs, strict=True)):
        vb = v_p[np.asarray(lay.injector_port[k], dtype=np.int64)]
        if hasattr(d, "signals"):  # issue 47: a renewable's signals, recorded
            sig = d.signals(x, vb, ref)
            dx = sig["dx"]
            meas = _ibr_measure(meas, sig, lay.injector_src[k], inj_on[k], vb)
        else:
            dx = d.rhs(x, vb, ref, s_base)
        di.append((jnp.reshape(dx, (-1, len(vb))) * inj_on[k]).reshape(jnp.shape(dx)))
    blocks = dm + dctrl + ds + di
    dy = jnp.concatenate([b.reshape(-1) for b in blocks]) if blocks else jnp.zeros(0)
    meas = meas | {"Efd": cmd["Efd"], "Pm": cmd["Pm"], "Vs": cmd["Vs"]}
    i_net = i_p if y_sh is None else i_p - y_sh * v_p
    return dy, meas, i_net, res


# issue 47: what the renewables (`devices.renewable`) record, by generator position
# (pu on the machine base; "Va" the terminal voltage's angle, rad); NaN at the
# generators that are not renewables
IBR_MEASUREMENTS = (
    "Ip",
    "Iq",
    "Ipcmd",
    "Iqcmd",
    "LVPL",
    "Ipmax",
    "Iqmax",
    "Qe",
    "Pref",
    "Qext",
    "Va",
)


def has_renewables(case: Case) -> bool:
    """Whether the case has renewables (an injector group with `signals`)."""
    return any(hasattr(d, "signals") for d in case.injectors)


def _ibr_measure(meas, sig, gens, on, vb):
    """`meas` with a renewable group's signals written at its generators: Pe and Vt
    (as a machine's), and `IBR_MEASUREMENTS` (zero current while tripped)."""
    g = np.asarray(gens, dtype=np.int64)
    n = meas["Pe"].shape[0]
    meas = dict(meas)
    for k in IBR_MEASUREMENTS:
        if k not in meas:
            meas[k] = jnp.full(n, jnp.nan)
    vals = dict(sig, Va=jnp.angle(vb))
    for k in ("Pe", "Vt", *IBR_MEASUREMENTS):
        val = vals[k] * on if k in ("Pe", "Qe", "Ip", "Iq") else vals[k]
        meas[k] = meas[k].at[g].set(val)
    return meas


def _rhs(case: Case, op: Operating, mats: StageMatrices, t_switch, t, y):
    stage = jnp.sum(t >= t_switch) if t_switch.shape[0] else 0
    return evaluate(case, op, mats, stage, y)[0]


# traced once per run: diffrax calls the vector field from several places (the
# term check, the initial step, the step itself, the dense output), and a nested jit
# turns each later call into a cached jaxpr instead of a Python re-trace of every
# device group (tracing is most of the cost of a cached compile)
_rhs_jit = eqx.filter_jit(_rhs)


def vector_field(case: Case, op: Operating, mats: StageMatrices, t_switch):
    """The diffrax vector field f(t, y, args): the stage in force at t is the number
    of switch times <= t."""

    def f(t, y, args):
        return _rhs_jit(case, op, mats, t_switch, t, y)

    return f
