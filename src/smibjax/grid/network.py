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
    "stage_matrices_dense",
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
    """Per stage (leading axis s): A (ports x ports) and c (ports), the port
    voltages V_ports = A I + c; generator status; and the bus voltages in low-rank
    form, V_bus = Zb (mask * I) + cb + U (Q[:, :p] I + Q[:, p]) (`bus_voltages`):
    Zb (buses x ports) the base network's response to the port currents (shared by
    every stage), mask the ports not held by a bolted fault, U (buses x K) the base
    response to the K nodes the events touch, Q (K x (ports + 1)) per stage."""

    A: Complex[Array, "s p p"]
    c: Complex[Array, "s p"]
    gen_status: Float[Array, "s n_gen"]
    Zb: Complex[Array, "n p"]
    mask: Float[Array, "s p"]
    cb: Complex[Array, "s n"]
    U: Complex[Array, "n k"]
    Q: Complex[Array, "s k p1"]

    def bus_voltages(
        self, stage: int, i_ports: Complex[Array, "*b p"]
    ) -> Complex[Array, "*b n"]:
        """Bus voltages (pu) in stage `stage` (a Python int) for port currents
        `i_ports` (pu, any leading axes): no (buses x ports) matrix per sample."""
        p = self.Zb.shape[1]
        q = self.Q[stage]
        v = (i_ports * self.mask[stage]) @ self.Zb.T + self.cb[stage]
        return v + (i_ports @ q[:, :p].T + q[:, p]) @ self.U.T

    @property
    def Z(self) -> Complex[Array, "s n p"]:
        """The dense per-stage bus response (buses x ports); for checks only."""
        p = self.Zb.shape[1]
        low = jnp.einsum("nk,skp->snp", self.U, self.Q[..., :p])
        return self.Zb[None] * self.mask[:, None, :] + low

    @property
    def c_all(self) -> Complex[Array, "s n"]:
        """The per-stage bus voltages at zero port current (pu)."""
        return self.cb + jnp.einsum("nk,sk->sn", self.U, self.Q[..., -1])


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
    """One stage reduced densely (the reference path): the full nodal matrix with its
    held rows, solved for every port and the fixed voltages."""
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


def stage_matrices_dense(grid: Grid, cfgs: StageConfig):
    """(A, c, Z, c_all) of every stage by a dense reduction of the whole network per
    stage (vmapped over the stage axis): the reference `stage_matrices` is checked
    against."""
    return jax.vmap(lambda cfg: _one_stage(grid, cfg))(cfgs)


# ---- the base network factored once, stages as low-rank updates (issue 46) ----


def _base_config(grid: Grid, n_lf: int) -> StageConfig:
    """The pre-event network with `n_lf` isolated spare nodes (no event data, so
    it stays unbatched under vmap over scenarios)."""
    sys_ = grid.system
    N = sys_.n_bus + n_lf
    return StageConfig(
        branch_status=jnp.asarray(sys_.branches.status, dtype=jnp.float64),
        fault_y=jnp.zeros(N, dtype=jnp.complex128),
        bolted=jnp.zeros(N, dtype=bool),
        seg_on=jnp.zeros(n_lf),
        seg_branch=jnp.zeros(n_lf, dtype=jnp.int32),
        seg_frac=jnp.full(n_lf, 0.5),
        gen_status=jnp.asarray(sys_.generators.status, dtype=jnp.float64),
    )


def _diagonal(grid: Grid, cfg: StageConfig):
    """The diagonal admittances of a stage's nodes (loads, shunts, machines in
    service, fault shunts, the spare nodes' isolation 1 when no fault is on)."""
    sys_ = grid.system
    n = sys_.n_bus
    n_lf = cfg.seg_on.shape[0]
    N = n + n_lf
    diag = jnp.zeros(N, dtype=jnp.complex128).at[:n].add(grid.bus_y) + cfg.fault_y
    gen_bus = jnp.asarray(sys_.generators.bus)
    diag = diag.at[gen_bus].add(grid.gen_y * cfg.gen_status)
    return diag.at[n:].add(1.0 - cfg.seg_on)


def _main_status(cfg: StageConfig):
    """Branch statuses with the branches split by a line fault taken out."""
    if cfg.seg_on.shape[0] == 0:
        return cfg.branch_status
    cut = jnp.zeros_like(cfg.branch_status).at[cfg.seg_branch].add(cfg.seg_on)
    return cfg.branch_status * (1 - jnp.minimum(cut, 1.0))


def _two_port(r, x, b, tap, shift):
    """A branch's 2x2 admittance block [[ff, ft], [tf, tt]] (see `_stamp`)."""
    y = 1.0 / (r + 1j * x)
    a = tap * jnp.exp(1j * shift)
    ysh = 1j * b / 2
    return jnp.array(
        [[(y + ysh) / tap**2, -y / jnp.conj(a)], [-y / a, y + ysh]],
        dtype=jnp.complex128,
    )


def _slots(grid: Grid, events):
    """The nodes an event sequence touches, one slot each (a node may hold several
    slots): (nodes (K,), branch blocks [(branch, slot_fr, slot_to)], segment blocks
    [(line-fault k, slot_fr, slot_node, slot_to)])."""
    sys_ = grid.system
    n = sys_.n_bus
    fr = jnp.asarray(sys_.branches.fr)
    to = jnp.asarray(sys_.branches.to)
    gbus = jnp.asarray(sys_.generators.bus)
    nodes, branches, segments = [], [], []
    lf = 0
    for e in events:
        k = len(nodes)
        if isinstance(e, BusFault):
            nodes.append(jnp.asarray(e.bus))
        elif isinstance(e, LineFault):
            nodes += [fr[e.branch], to[e.branch], jnp.asarray(n + lf)]
            branches.append((e.branch, k, k + 1))
            segments.append((lf, k, k + 1, k + 2))
            lf += 1
        elif isinstance(e, BranchTrip | BranchClose):
            nodes += [fr[e.branch], to[e.branch]]
            branches.append((e.branch, k, k + 1))
        elif isinstance(e, GenTrip):
            nodes.append(gbus[e.gen])
        else:
            raise TypeError(f"not an event: {e!r}")
    nodes = (
        jnp.stack([jnp.asarray(v, dtype=jnp.int32) for v in nodes])
        if nodes
        else (jnp.zeros(0, dtype=jnp.int32))
    )
    return nodes, branches, segments


def _first(keys):
    """Whether each entry is the first of its value (K,) -> (K,) bool."""
    k = keys.shape[0]
    same = (keys[:, None] == keys[None, :]) & (
        jnp.arange(k)[None, :] < jnp.arange(k)[:, None]
    )
    return ~jnp.any(same, axis=1)


def _update(grid, cfg, base, nodes, branches, segments, first_node):
    """The stage's admittance change on the slots, D (K, K): ΔY = E D E^T with E the
    slots' unit vectors (duplicate nodes allowed)."""
    br = grid.system.branches
    r, x, bb = jnp.asarray(br.r), jnp.asarray(br.x), jnp.asarray(br.b)
    tap, shift = jnp.asarray(br.tap), jnp.asarray(br.shift)
    D = jnp.diag(
        jnp.where(first_node, (_diagonal(grid, cfg) - _diagonal(grid, base))[nodes], 0)
    )
    st, st0 = _main_status(cfg), _main_status(base)
    if branches:
        idx = jnp.stack([jnp.asarray(b, dtype=jnp.int32) for b, _, _ in branches])
        first_br = _first(idx)
        for m, (b, i, j) in enumerate(branches):
            blk = _two_port(r[b], x[b], bb[b], tap[b], shift[b])
            w = jnp.where(first_br[m], st[b] - st0[b], 0.0)
            sl = jnp.array([i, j])
            D = D.at[sl[:, None], sl[None, :]].add(w * blk)
    for k, i, j, m in segments:  # slots: from bus, to bus, fault node
        b = cfg.seg_branch[k]
        lam = cfg.seg_frac[k]
        on = cfg.seg_on[k] * cfg.branch_status[b]
        one = _two_port(r[b] * lam, x[b] * lam, bb[b] * lam, tap[b], shift[b])
        two = _two_port(r[b] * (1 - lam), x[b] * (1 - lam), bb[b] * (1 - lam), 1.0, 0.0)
        a = jnp.array([i, m])
        c = jnp.array([m, j])
        D = D.at[a[:, None], a[None, :]].add(on * one)
        D = D.at[c[:, None], c[None, :]].add(on * two)
    return D


def stage_matrices(grid: Grid, cfgs: StageConfig, events=()) -> StageMatrices:
    """Every stage's reduced network, from one factorization of the base (pre-event)
    network: the events' changes (fault shunts, branch trips and closes, the split
    branch of a line fault, generator trips) are exact low-rank (Woodbury) updates on
    the K nodes the events touch, and bolted faults hold their node at V = 0 by a
    Schur complement on those nodes. `cfgs` are `stage_configs(grid, events)`.

    With Z0 = M0^-1 (M0: the base admittance, fixed-voltage rows held), X = Z0 E
    (E: the touched nodes' unit vectors, N x K) and R0 the base responses to the port
    injections and fixed voltages, each stage's responses are R0 + X Q[stage]:
    Q = -G + (1 - H) mu with G = S^-1 D R0_T, H = S^-1 D X_T, S = 1 + D X_T and mu
    the bolted nodes' currents. Cost per scenario: K solves with the base factors
    and K x K systems per stage (not a factorization per stage). Jittable,
    vmappable (the base factorization is shared by a batch) and differentiable."""
    sys_ = grid.system
    n = sys_.n_bus
    n_lf = cfgs.seg_on.shape[-1]
    N = n + n_lf
    base = _base_config(grid, n_lf)
    Y0 = admittance(grid, base)
    dirichlet = jnp.asarray(grid.dirichlet, dtype=jnp.int32)
    fixed = jnp.zeros(N, dtype=bool).at[dirichlet].set(True)
    M0 = jnp.where(fixed[:, None], jnp.eye(N, dtype=jnp.complex128), Y0)
    lu = jax.scipy.linalg.lu_factor(M0)
    ports = jnp.asarray(grid.ports, dtype=jnp.int32)
    p = ports.shape[0]
    n_dir = dirichlet.shape[0]
    E = jnp.zeros((N, p + n_dir), dtype=jnp.complex128)
    E = E.at[ports, jnp.arange(p)].set(1.0)
    E = jnp.where(fixed[:, None], 0.0, E)
    E = E.at[dirichlet, p + jnp.arange(n_dir)].set(1.0)
    W = jax.scipy.linalg.lu_solve(lu, E)  # (N, p + n_dir)
    Wp, Wd = W[:, :p], W[:, p:]
    bolted_port = cfgs.bolted[:, ports]  # (s, p)
    mask = jnp.where(bolted_port, 0.0, 1.0)
    src = jnp.where(cfgs.bolted[:, dirichlet], 0.0, grid.v_dirichlet)  # (s, n_dir)
    cN = src @ Wd.T  # (s, N)
    nodes, branches, segments = _slots(grid, events)
    K = nodes.shape[0]
    n_stage = cfgs.gen_status.shape[0]
    if n_stage != 1 + sum(
        2 if isinstance(e, BusFault | LineFault) else 1 for e in events
    ):
        raise ValueError(
            f"stage_matrices: {n_stage} stages for {len(events)} events; pass the "
            "events that made the stage configurations"
        )
    if K == 0:
        X = jnp.zeros((N, 0), dtype=jnp.complex128)
        Q = jnp.zeros((n_stage, 0, p + 1), dtype=jnp.complex128)
    else:
        ET = jnp.zeros((N, K), dtype=jnp.complex128).at[nodes, jnp.arange(K)].set(1.0)
        X = jax.scipy.linalg.lu_solve(lu, ET)  # (N, K)
        XT = X[nodes]
        first_node = _first(nodes)
        held_row = fixed[nodes]
        eye = jnp.eye(K, dtype=jnp.complex128)

        def per_stage(cfg, m, c):
            D = _update(grid, cfg, base, nodes, branches, segments, first_node)
            D = jnp.where(held_row[:, None], 0.0, D)
            R0T = jnp.concatenate([Wp[nodes] * m[None, :], c[nodes][:, None]], axis=1)
            S = eye + D @ XT
            G = jnp.linalg.solve(S, D @ R0T)
            H = jnp.linalg.solve(S, D @ XT)
            b = cfg.bolted[nodes] & first_node
            Z1R_T = R0T - XT @ G
            Z1T_TT = XT @ (eye - H)
            both = b[:, None] & b[None, :]
            Gm = jnp.where(both, Z1T_TT, eye)
            mu = -jnp.linalg.solve(Gm, jnp.where(b[:, None], Z1R_T, 0.0))
            mu = jnp.where(b[:, None], mu, 0.0)
            return -G + (eye - H) @ mu

        Q = jax.vmap(per_stage)(cfgs, mask, cN)
    A = Wp[ports][None] * mask[:, None, :] + jnp.einsum(
        "ik,skj->sij", X[ports], Q[..., :p]
    )
    c = cN[:, ports] + jnp.einsum("ik,sk->si", X[ports], Q[..., p])
    return StageMatrices(
        A=A,
        c=c,
        gen_status=cfgs.gen_status,
        Zb=Wp[:n],
        mask=mask,
        cb=cN[:, :n],
        U=X[:n],
        Q=Q,
    )


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


# ---- injectors: the nonlinear network (issue 47) ----

NEWTON_ITERS = 6  # Newton iterations per network solution with injectors
COLLAPSE_TOL = 1e-6  # |residual| (pu voltage) above which the network has no solution


def solve_injections(
    A: Complex[Array, "p p"],
    c: Complex[Array, " p"],
    i_ports: Complex[Array, " p"],
    y_shunt: Complex[Array, " p"] | None,
    inj_ports,
    current,
    y_start: Complex[Array, " J"],
    iters: int | None = None,
) -> tuple[Complex[Array, " p"], Complex[Array, " J"], Float[Array, ""]]:
    """The port voltages with current injectors at ports `inj_ports` (J static port
    positions, unique): V = A (I + P I_inj(V_J) - y_shunt V) + c, P the injector
    ports' unit vectors. `current(v_J) -> (J,)` is the injectors' current into the
    network summed per injector port (pu); each port's injection must depend on
    that port's voltage only.

    Reduced to the injector ports: with M = 1 + A diag(y_shunt) (the identity
    without shunts), W = M^-1 A P and V_lin = M^-1 (A I + c), V_J solves
    g(V_J) = V_J - W_J I_inj(V_J) - V_lin,J = 0, and V = V_lin + W I_inj(V_J).
    Newton's method on the 2J real unknowns (Re, Im) from the linear solution with
    the injectors replaced by admittances `y_start` (their t = 0 equivalent: the
    start solves (1 + W_J diag(y_start)) V_J = V_lin,J); a fixed number `iters` of
    iterations (None: `NEWTON_ITERS`; jittable, vmappable; differentiable by unrolling, which at
    convergence is the implicit-function derivative). The Jacobian is exact: the
    injectors' per-port derivatives dI/dRe V and dI/dIm V come from two
    forward-mode products. A non-finite step is not taken.

    Returns (V (p,), V_J (J,), residual): residual = max |g(V_J)| (pu) at the
    returned voltages; above `COLLAPSE_TOL` (or not finite) the network has no
    solution the iteration could reach (voltage collapse)."""
    J = jnp.asarray(inj_ports, dtype=jnp.int32)
    n_j = J.shape[0]
    rhs = A @ i_ports + c
    if y_shunt is None:
        v_lin = rhs
        W = A[:, J]
    else:
        M = jnp.eye(A.shape[0], dtype=A.dtype) + A * y_shunt[None, :]
        X = jnp.linalg.solve(M, jnp.concatenate([rhs[:, None], A[:, J]], axis=1))
        v_lin, W = X[:, 0], X[:, 1:]
    WJ = W[J]
    d = v_lin[J]
    eye = jnp.eye(n_j, dtype=A.dtype)
    vj = jnp.linalg.solve(eye + WJ * y_start[None, :], d)
    ones = jnp.ones(n_j, dtype=A.dtype)
    eye2 = jnp.eye(2 * n_j)

    def step(_, vj):
        i0, a = jax.jvp(current, (vj,), (ones,))
        _, b = jax.jvp(current, (vj,), (1j * ones,))
        g = vj - WJ @ i0 - d
        Wa, Wb = WJ * a[None, :], WJ * b[None, :]
        jac = eye2 - jnp.block(
            [[jnp.real(Wa), jnp.real(Wb)], [jnp.imag(Wa), jnp.imag(Wb)]]
        )
        dx = jnp.linalg.solve(jac, -jnp.concatenate([jnp.real(g), jnp.imag(g)]))
        new = vj + dx[:n_j] + 1j * dx[n_j:]
        return jnp.where(jnp.all(jnp.isfinite(new)), new, vj)

    iters = NEWTON_ITERS if iters is None else iters
    vj = jax.lax.fori_loop(0, iters, step, vj)
    i_j = current(vj)
    res = jnp.max(jnp.abs(vj - WJ @ i_j - d))
    res = jnp.where(jnp.isfinite(res), res, jnp.inf)
    return v_lin + W @ i_j, vj, res
