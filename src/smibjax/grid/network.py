"""The network solution: bus voltages from the devices' current injections, exactly,
at every right-hand-side evaluation.

With constant-impedance loads, machines as Norton sources and SVCs as shunt
admittances, the network is linear: Y(stage) V = I. The admittance matrix changes only
at switch times, so for each stage it is factored once, before the run, and reduced to
the *ports* (the buses where a device injects current or has a variable shunt):

    V_ports = A I_ports + c,        V_all = Z I_ports + c_all

where c carries the voltage sources held fixed (infinite buses, `Dirichlet` nodes). A
bolted fault holds its bus at V = 0 exactly (the bus's equation is replaced by V = 0);
a fault through an impedance is a shunt. With SVCs at ports k the vector field solves
the small system (1 + A diag(y_svc)) V_ports = A I_ports + c per evaluation (size the
number of ports); without SVCs it is a matrix-vector product.

Node layout: the n buses of the system, then one spare node per `LineFault` in the
scenario (the fault point; isolated, with V = 0, when no fault is on).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Complex, Float, Int

from .events import BranchClose, BranchTrip, BusFault, GenTrip, LineFault
from .system import System

__all__ = [
    "Grid",
    "StageConfig",
    "StageMatrices",
    "stage_configs",
    "stage_matrices",
    "solve_ports",
]


class Grid(eqx.Module):
    """What the network solution needs, fixed for a run: the system, the shunt
    admittance added at each bus (constant-impedance loads, fixed shunts: pu), each
    generator's Norton admittance (pu system base; zero for generators that are not
    Norton machines), the port buses, and the fixed-voltage (Dirichlet) buses with
    their voltages."""

    system: System
    bus_y: Complex[Array, " n"]
    gen_y: Complex[Array, " n_gen"]
    ports: Int[np.ndarray, " n_port"]
    dirichlet: Int[np.ndarray, " n_dir"]
    v_dirichlet: Complex[Array, " n_dir"]


class StageConfig(eqx.Module):
    """The network in one stage: branch status, fault shunts and bolted-fault masks
    per node, the split branches of line faults (one per spare node) and generator
    status."""

    branch_status: Float[Array, " n_br"]
    fault_y: Complex[Array, " N"]
    bolted: Bool[Array, " N"]
    seg_on: Float[Array, " n_lf"]
    seg_branch: Int[Array, " n_lf"]
    seg_frac: Float[Array, " n_lf"]
    gen_status: Float[Array, " n_gen"]


class StageMatrices(eqx.Module):
    """Per stage (leading axis): A (ports x ports), c (ports), Z (buses x ports),
    c_all (buses), generator status."""

    A: Complex[Array, "s p p"]
    c: Complex[Array, "s p"]
    Z: Complex[Array, "s n p"]
    c_all: Complex[Array, "s n"]
    gen_status: Float[Array, "s n_gen"]


def _fault_y(r, x):
    """(admittance, bolted) of a fault impedance r + j x: bolted when both are 0."""
    z = r + 1j * x
    bolted = (r == 0) & (x == 0)
    safe = jnp.where(bolted, 1.0 + 0j, z)
    return jnp.where(bolted, 0j, 1.0 / safe), bolted


def stage_configs(grid: Grid, events) -> StageConfig:
    """The network after each prefix of the events' switches: stage 0 is the
    pre-event network, stage j the network after the first j switch times. Works
    with traced event fields (positions included); returns stacked StageConfigs."""
    sys_ = grid.system
    n = sys_.n_bus
    n_lf = sum(isinstance(e, LineFault) for e in events)
    N = n + n_lf
    cfg = StageConfig(
        branch_status=jnp.asarray(sys_.branches.status, dtype=jnp.float64),
        fault_y=jnp.zeros(N, dtype=jnp.complex128),
        bolted=jnp.zeros(N, dtype=bool),
        seg_on=jnp.zeros(n_lf),
        seg_branch=jnp.zeros(n_lf, dtype=jnp.int32),
        seg_frac=jnp.full(n_lf, 0.5),
        gen_status=jnp.asarray(sys_.generators.status, dtype=jnp.float64),
    )
    out = [cfg]
    lf = 0
    for e in events:
        if isinstance(e, BusFault):
            y, b = _fault_y(e.r, e.x)
            on = eqx.tree_at(
                lambda c: (c.fault_y, c.bolted),
                cfg,
                (
                    cfg.fault_y.at[e.bus].add(y),
                    cfg.bolted.at[e.bus].set(b | cfg.bolted[e.bus]),
                ),
            )
            off = eqx.tree_at(
                lambda c: (c.fault_y, c.bolted),
                on,
                (
                    on.fault_y.at[e.bus].add(-y),
                    on.bolted.at[e.bus].set(cfg.bolted[e.bus]),
                ),
            )
            out += [on, off]
            cfg = off
        elif isinstance(e, LineFault):
            node = n + lf
            y, b = _fault_y(e.r, e.x)
            on = eqx.tree_at(
                lambda c: (c.fault_y, c.bolted, c.seg_on, c.seg_branch, c.seg_frac),
                cfg,
                (
                    cfg.fault_y.at[node].set(y),
                    cfg.bolted.at[node].set(b),
                    cfg.seg_on.at[lf].set(1.0),
                    cfg.seg_branch.at[lf].set(e.branch),
                    cfg.seg_frac.at[lf].set(e.frac),
                ),
            )
            off = eqx.tree_at(
                lambda c: (c.fault_y, c.bolted, c.seg_on),
                on,
                (
                    on.fault_y.at[node].set(0j),
                    on.bolted.at[node].set(False),
                    on.seg_on.at[lf].set(0.0),
                ),
            )
            out += [on, off]
            cfg = off
            lf += 1
        elif isinstance(e, BranchTrip | BranchClose):
            v = 0.0 if isinstance(e, BranchTrip) else 1.0
            cfg = eqx.tree_at(
                lambda c: c.branch_status, cfg, cfg.branch_status.at[e.branch].set(v)
            )
            out.append(cfg)
        elif isinstance(e, GenTrip):
            cfg = eqx.tree_at(
                lambda c: c.gen_status, cfg, cfg.gen_status.at[e.gen].set(0.0)
            )
            out.append(cfg)
        else:
            raise TypeError(f"not an event: {e!r}")
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *out)


def _stamp(Y, fr, to, r, x, b, tap, shift, status):
    """Add branches' pi-models (PSS/E tap convention, see `Branches`) to Y."""
    y = status / (r + 1j * x)
    a = tap * jnp.exp(1j * shift)
    ysh = status * 1j * b / 2
    Y = Y.at[fr, fr].add((y + ysh) / tap**2)
    Y = Y.at[to, to].add(y + ysh)
    Y = Y.at[fr, to].add(-y / jnp.conj(a))
    Y = Y.at[to, fr].add(-y / a)
    return Y


def admittance(grid: Grid, cfg: StageConfig) -> Complex[Array, "N N"]:
    """The full nodal admittance matrix (buses and spare fault nodes) of one stage,
    with loads, shunts, machine admittances and fault shunts (bolted faults are
    applied in `stage_matrices`)."""
    sys_ = grid.system
    br = sys_.branches
    n = sys_.n_bus
    n_lf = cfg.seg_on.shape[0]
    N = n + n_lf
    Y = jnp.zeros((N, N), dtype=jnp.complex128)
    status = cfg.branch_status
    if n_lf:
        cut = jnp.zeros_like(status).at[cfg.seg_branch].add(cfg.seg_on)
        status_main = status * (1 - jnp.minimum(cut, 1.0))
    else:
        status_main = status
    Y = _stamp(Y, br.fr, br.to, br.r, br.x, br.b, br.tap, br.shift, status_main)
    for k in range(n_lf):
        j = cfg.seg_branch[k]
        lam = cfg.seg_frac[k]
        on = cfg.seg_on[k] * status[j]
        node = n + k
        Y = _stamp(
            Y,
            br.fr[j],
            node,
            br.r[j] * lam,
            br.x[j] * lam,
            br.b[j] * lam,
            br.tap[j],
            br.shift[j],
            on,
        )
        Y = _stamp(
            Y,
            node,
            br.to[j],
            br.r[j] * (1 - lam),
            br.x[j] * (1 - lam),
            br.b[j] * (1 - lam),
            1.0,
            0.0,
            on,
        )
        Y = Y.at[node, node].add(1.0 - cfg.seg_on[k])  # isolated when no fault
    diag = jnp.zeros(N, dtype=jnp.complex128).at[:n].add(grid.bus_y) + cfg.fault_y
    gen_bus = jnp.asarray(sys_.generators.bus)
    diag = diag.at[gen_bus].add(grid.gen_y * cfg.gen_status)
    return Y + jnp.diag(diag)


def _one_stage(grid: Grid, cfg: StageConfig):
    n = grid.system.n_bus
    Y = admittance(grid, cfg)
    N = Y.shape[0]
    fixed = (
        jnp.zeros(N, dtype=bool)
        .at[jnp.asarray(grid.dirichlet, dtype=jnp.int32)]
        .set(True)
    )
    v_fixed = (
        jnp.zeros(N, dtype=jnp.complex128)
        .at[jnp.asarray(grid.dirichlet, dtype=jnp.int32)]
        .set(grid.v_dirichlet)
    )
    hold = fixed | cfg.bolted
    eye = jnp.eye(N, dtype=jnp.complex128)
    M = jnp.where(hold[:, None], eye, Y)
    ports = jnp.asarray(grid.ports, dtype=jnp.int32)
    inj = jnp.zeros((N, ports.shape[0]), dtype=jnp.complex128)
    inj = inj.at[ports, jnp.arange(ports.shape[0])].set(1.0)
    inj = jnp.where(hold[:, None], 0.0, inj)
    src = jnp.where(cfg.bolted, 0.0, v_fixed)
    X = jnp.linalg.solve(M, jnp.concatenate([inj, src[:, None]], axis=1))
    Zp, cp = X[:, :-1], X[:, -1]
    return Zp[ports], cp[ports], Zp[:n], cp[:n]


def stage_matrices(grid: Grid, cfgs: StageConfig) -> StageMatrices:
    """Factor and reduce every stage's network (vmapped over the stage axis)."""
    A, c, Z, c_all = jax.vmap(lambda cfg: _one_stage(grid, cfg))(cfgs)
    return StageMatrices(A=A, c=c, Z=Z, c_all=c_all, gen_status=cfgs.gen_status)


def solve_ports(
    A: Complex[Array, "p p"],
    c: Complex[Array, " p"],
    i_ports: Complex[Array, " p"],
    y_shunt: Complex[Array, " p"] | None = None,
) -> Complex[Array, " p"]:
    """Port voltages V = A (I - y_shunt V) + c, i.e. (1 + A diag(y_shunt)) V = A I + c
    (a matrix-vector product when there is no variable shunt)."""
    rhs = A @ i_ports + c
    if y_shunt is None:
        return rhs
    M = jnp.eye(A.shape[0], dtype=A.dtype) + A * y_shunt[None, :]
    return jnp.linalg.solve(M, rhs)
