"""AC power flow: Newton-Raphson in polar coordinates, in JAX, with implicit
differentiation (optimistix), jittable and vmappable.

Unknowns: the angle va (rad) and magnitude vm (pu) of every bus, 2 n_bus of them; one
equation per unknown (so the shapes never depend on the bus types and the bus types
may be traced):

    slack bus:  va - va_set = 0,            vm - v_set = 0
    PV bus:     P(V) - (P_gen - P_load) = 0, vm - v_set = 0
    PQ bus:     P(V) - (P_gen - P_load) = 0, Q(V) - (Q_gen - Q_load) = 0

with P(V) + j Q(V) = V conj(Y V) the injection of the network (`ybus`: branches and
fixed shunts; loads are constant power, not in Y) and V = vm e^{j va}. Newton's
Jacobian is the exact derivative of these equations (forward-mode autodiff); the
linear solve is a dense LU. The derivative of the solution with respect to anything
the equations read (loads, generation, set points, branch and shunt parameters) is
the implicit-function theorem at the solution (`optx.ImplicitAdjoint`), not the
unrolled iterations.

Bus data: the slack angle is `Buses.va`; a PV or slack bus holds the mean `v_set` of
its in-service generators (PSS/E asks them to agree), or `Buses.vm` if it has none. A
PV bus without an in-service generator is solved as PQ. Generators at PQ buses inject
their scheduled p + j q. Reactive limits (`qmin`, `qmax`) are not enforced.

Sharing among the in-service generators of one bus: P is scheduled per generator; at
a slack bus the bus's generation is shared in proportion to `mbase`. Q at a PV or
slack bus with several generators: each keeps the case's own `q` (a solved case's
machine outputs, which a dynamic simulation starts from) plus a share of the
difference between the bus's solved Q and their sum, in proportion to the Q ranges,
q_i = q_i,case + (Q - sum q_case) (qmax_i - qmin_i) / sum (qmax - qmin), equally if a
range is not finite or the ranges sum to zero (with every q_case zero: MATPOWER's
rule for symmetric limits); a bus's only generator takes its Q.
"""

from __future__ import annotations

from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int

from .._errors import ParameterError
from .system import PQ, PV, SLACK, System
from .ybus import ybus

__all__ = [
    "PowerFlowError",
    "PowerFlowResult",
    "power_flow",
    "solve_power_flow",
    "scale_operating_point",
]

LOW_V = 0.5  # pu: below it a solution from the case's voltages is tried again flat

Start = Literal["case", "flat"]


class PowerFlowError(ParameterError):
    """The power flow did not converge (the message names the largest mismatch)."""


class PowerFlowResult(eqx.Module):
    """A power-flow solution (pu on the system base, angles in rad). If `converged`
    is false, vm and va are the last Newton iterate and the rest is computed from it.
    """

    vm: Float[Array, " n_bus"]  # bus voltage magnitudes (pu)
    va: Float[Array, " n_bus"]  # bus voltage angles (rad)
    p_gen: Float[Array, " n_gen"]  # generators' active power (pu; 0 when out)
    q_gen: Float[Array, " n_gen"]  # generators' reactive power (pu; 0 when out)
    p_slack: Float[Array, ""]  # active generation of the slack bus(es) (pu)
    dp: Float[Array, " n_bus"]  # P mismatch, computed minus scheduled (pu; 0 at slack)
    dq: Float[Array, " n_bus"]  # Q mismatch (pu; 0 at PV and slack buses)
    mismatch: Float[Array, ""]  # the largest mismatch by magnitude, signed (pu)
    mismatch_bus: Int[Array, ""]  # its bus number (PSS/E number, not the position)
    mismatch_is_q: Bool[Array, ""]  # whether it is a Q mismatch (else P)
    iterations: Int[Array, ""]  # Newton steps taken
    converged: Bool[Array, ""]  # Newton succeeded and |mismatch| <= tol

    @property
    def v(self):
        """Complex bus voltages vm e^{j va} (pu)."""
        return self.vm * jnp.exp(1j * self.va)


class _Schedule(eqx.Module):
    """Per-bus equations' data (see the module docstring)."""

    slack: Bool[Array, " n_bus"]
    fixed_v: Bool[Array, " n_bus"]  # slack or PV: vm is held
    va_set: Float[Array, " n_bus"]
    v_set: Float[Array, " n_bus"]
    p_sched: Float[Array, " n_bus"]  # P_gen - P_load (pu)
    q_sched: Float[Array, " n_bus"]  # Q_gen - Q_load (pu; used at PQ buses)
    p_load: Float[Array, " n_bus"]
    q_load: Float[Array, " n_bus"]


def _bus_sum(n, bus, x):
    return jnp.zeros(n, dtype=jnp.result_type(x, jnp.float64)).at[bus].add(x)


def _schedule(system: System) -> _Schedule:
    n = system.n_bus
    b, g, ld = system.buses, system.generators, system.loads
    kind = jnp.asarray(b.kind)
    gbus = jnp.asarray(g.bus)
    on = jnp.asarray(g.status)
    n_on = _bus_sum(n, gbus, on)
    has_gen = n_on > 0
    slack = kind == SLACK
    pv = (kind == PV) & has_gen
    v_gen = _bus_sum(n, gbus, on * jnp.asarray(g.v_set)) / jnp.maximum(n_on, 1.0)
    v_set = jnp.where(has_gen, v_gen, jnp.asarray(b.vm))
    lbus = jnp.asarray(ld.bus)
    p_load = _bus_sum(n, lbus, jnp.asarray(ld.p))
    q_load = _bus_sum(n, lbus, jnp.asarray(ld.q))
    p_gen = _bus_sum(n, gbus, on * jnp.asarray(g.p))
    q_gen = _bus_sum(n, gbus, on * jnp.asarray(g.q))
    return _Schedule(
        slack=slack,
        fixed_v=slack | pv,
        va_set=jnp.asarray(b.va),
        v_set=v_set,
        p_sched=p_gen - p_load,
        q_sched=q_gen - q_load,
        p_load=p_load,
        q_load=q_load,
    )


def _injection(Y, va, vm):
    v = vm * jnp.exp(1j * va)
    return v * jnp.conj(Y @ v)


def _residual(y, args):
    Y, s = args
    n = Y.shape[0]
    va, vm = y[:n], y[n:]
    inj = _injection(Y, va, vm)
    r_p = jnp.where(s.slack, va - s.va_set, jnp.real(inj) - s.p_sched)
    r_q = jnp.where(s.fixed_v, vm - s.v_set, jnp.imag(inj) - s.q_sched)
    return jnp.concatenate([r_p, r_q])


def _start(system: System, s: _Schedule, flat):
    """Newton's start: the raw file's vm, va, or (`flat`, a traced bool, so that both
    starts share one compile) vm = 1 and va = the slack angle; the set points at PV
    and slack buses either way."""
    b = system.buses
    n_slack = jnp.maximum(jnp.sum(s.slack), 1)
    va_ref = jnp.sum(jnp.where(s.slack, s.va_set, 0.0)) / n_slack
    va0 = jnp.where(flat, jnp.where(s.slack, s.va_set, va_ref), jnp.asarray(b.va))
    vm0 = jnp.where(s.fixed_v, s.v_set, jnp.where(flat, 1.0, jnp.asarray(b.vm)))
    return jnp.concatenate([va0, vm0]).astype(jnp.float64)


def _share(n, gbus, on, total, weight):
    """Each generator's part of its bus's `total` (n_bus,): in proportion to `weight`
    among the bus's in-service generators where their weights sum to a positive finite
    number, else equally; 0 for those out of service."""
    w = jnp.where(jnp.isfinite(weight), weight, 0.0)
    w_sum = _bus_sum(n, gbus, on * w)
    ok = (_bus_sum(n, gbus, on * ~jnp.isfinite(weight)) == 0) & (w_sum > 0)
    n_on = jnp.maximum(_bus_sum(n, gbus, on), 1.0)
    frac = jnp.where(ok[gbus], w / jnp.where(ok, w_sum, 1.0)[gbus], 1.0 / n_on[gbus])
    return on * total[gbus] * frac, ok


def _generators(system: System, s: _Schedule, inj):
    """(p_gen, q_gen, p_slack) from the bus injections `inj` at the solution."""
    n = system.n_bus
    g = system.generators
    gbus = jnp.asarray(g.bus)
    on = jnp.asarray(g.status)
    p_bus = jnp.real(inj) + s.p_load  # the generation each bus needs
    q_bus = jnp.imag(inj) + s.q_load
    p_shared, _ = _share(n, gbus, on, p_bus, jnp.asarray(g.mbase))
    p_gen = jnp.where(s.slack[gbus], p_shared, on * jnp.asarray(g.p))
    # Q at PV and slack buses: each generator keeps the case's own q (a solved case's
    # machine outputs) plus a share of the difference between the bus's Q and their
    # sum, in proportion to the Q ranges (equally if a range is not finite or they
    # sum to zero); a bus's only generator thus takes its Q. With every q zero (an
    # unsolved case) that is MATPOWER's rule for symmetric limits.
    rng = jnp.asarray(g.qmax) - jnp.asarray(g.qmin)
    q_case = on * jnp.asarray(g.q)
    rest = q_bus - _bus_sum(n, gbus, q_case)
    rest_rng, ok_rest = _share(n, gbus, on, rest, rng)
    rest_eq, _ = _share(n, gbus, on, rest, jnp.zeros_like(on))
    q_shared = q_case + jnp.where(ok_rest[gbus], rest_rng, rest_eq)
    q_gen = jnp.where(s.fixed_v[gbus], q_shared, on * jnp.asarray(g.q))
    p_slack = jnp.sum(jnp.where(s.slack, p_bus, 0.0))
    return p_gen, q_gen, p_slack


def power_flow(
    system: System,
    *,
    start: Start = "case",
    tol: float = 1e-10,
    max_iter: int = 30,
    branch_status: Float[Array, " n_br"] | None = None,
) -> PowerFlowResult:
    """Solve the AC power flow of `system` (the core, jitted with `eqx.filter_jit` and
    usable inside jit and vmap: it never raises on non-convergence but returns
    `converged = False`; `solve_power_flow` raises).

    `start`: "case" starts from the raw file's vm, va ("flat": vm = 1, va = the slack
    angle), with the set points at PV and slack buses either way. Newton stops when
    the largest mismatch (pu) and the last step are below `tol`, or after `max_iter`
    steps. `branch_status` (n_br,) overrides `Branches.status` (an outage case).
    Differentiable (implicit function theorem) in the loads, generation, set points
    and network parameters; jittable and vmappable (nothing here depends on the
    values of the bus types)."""
    if start not in ("case", "flat"):
        raise ParameterError(f"power flow: start {start!r} is not 'case' or 'flat'")
    # one compile per shape, whether the leaves are NumPy or JAX arrays
    system = jax.tree.map(jnp.asarray, system)
    flat = jnp.asarray(start == "flat")
    return _power_flow(
        system, flat, tol=tol, max_iter=max_iter, branch_status=branch_status
    )


@eqx.filter_jit
def _power_flow(system, flat, *, tol, max_iter, branch_status):
    s = _schedule(system)
    Y = ybus(system, branch_status)
    y0 = _start(system, s, flat)
    solver = optx.Newton(
        rtol=tol, atol=tol, linear_solver=lx.AutoLinearSolver(well_posed=None)
    )
    sol = optx.root_find(_residual, solver, y0, (Y, s), max_steps=max_iter, throw=False)
    n = system.n_bus
    va, vm = sol.value[:n], sol.value[n:]
    inj = _injection(Y, va, vm)
    solved = sol.result == optx.RESULTS.successful
    return result_of(system, s, va, vm, inj, sol.stats["num_steps"], solved, tol)


def result_of(system, s, va, vm, inj, iterations, solved, tol) -> PowerFlowResult:
    """The `PowerFlowResult` of a Newton iterate (angles va in rad, magnitudes vm in
    pu, bus injections inj in pu): the mismatches (pu) of the scheduled P and Q, the
    largest and its bus, the generators' outputs; converged where the solver says
    `solved` and the largest mismatch is within `tol` (pu). Shared by the dense and
    the sparse solvers."""
    n = system.n_bus
    dp = jnp.where(s.slack, 0.0, jnp.real(inj) - s.p_sched)
    dq = jnp.where(s.fixed_v, 0.0, jnp.imag(inj) - s.q_sched)
    d = jnp.concatenate([dp, dq])
    worst = jnp.argmax(jnp.where(jnp.isnan(d), jnp.inf, jnp.abs(d)))
    mismatch = d[worst]
    p_gen, q_gen, p_slack = _generators(system, s, inj)
    return PowerFlowResult(
        vm=vm,
        va=va,
        p_gen=p_gen,
        q_gen=q_gen,
        p_slack=p_slack,
        dp=dp,
        dq=dq,
        mismatch=mismatch,
        mismatch_bus=jnp.asarray(system.buses.number)[worst % n],
        mismatch_is_q=worst >= n,
        iterations=iterations,
        converged=solved & (jnp.abs(mismatch) <= tol),
    )


def _check(system: System) -> None:
    """One line for data the power flow cannot take."""
    b, br = system.buses, system.branches
    kind = np.asarray(b.kind)
    bad = np.flatnonzero(~np.isin(kind, (PQ, PV, SLACK)))
    if bad.size:
        i = bad[0]
        raise ParameterError(
            f"power flow: bus {int(b.number[i])} has type {int(kind[i])}; "
            "the power flow takes 1 (PQ), 2 (PV) and 3 (slack)"
        )
    if not np.any(kind == SLACK):
        raise ParameterError("power flow: the system has no slack bus (type 3)")
    on = np.asarray(br.status) > 0
    zero = np.flatnonzero(on & (np.asarray(br.r) == 0) & (np.asarray(br.x) == 0))
    if zero.size:
        i = zero[0]
        raise ParameterError(
            f"power flow: branch {int(b.number[br.fr[i]])}-{int(b.number[br.to[i]])} "
            "has zero impedance (r = x = 0)"
        )
    tap = np.asarray(br.tap)
    if np.any(~np.isfinite(tap) | (tap <= 0)):
        i = int(np.flatnonzero(~np.isfinite(tap) | (tap <= 0))[0])
        raise ParameterError(
            f"power flow: branch {int(b.number[br.fr[i]])}-{int(b.number[br.to[i]])} "
            f"has tap {tap[i]}; it must be positive"
        )


def solve_power_flow(
    system: System,
    *,
    start: Start = "case",
    tol: float = 1e-10,
    max_iter: int = 30,
    method: Literal["sparse", "dense"] = "sparse",
) -> PowerFlowResult:
    """`power_flow` on the host (one compile per case shape): checks the data
    and raises `PowerFlowError` with one line naming the largest mismatch (pu, MW or
    Mvar) and its bus number if Newton does not converge.

    From the case's voltages (`start="case"`), when Newton fails there or lands on
    a low-voltage solution (some |V| below LOW_V = 0.5 pu: an unsolved raw file's
    voltages can lead it to the power flow's other, inoperable branch), Newton runs
    again from a flat start, whose solution is kept if it converged with a higher
    lowest voltage.

    `method`: "sparse" (default; `powerflow_sparse.power_flow_sparse`: analytic
    Jacobian, sparse LU) or "dense" (`power_flow`); the same equations and
    solution."""
    _check(system)
    if method not in ("sparse", "dense"):
        raise ValueError(f"power flow: method {method!r} is not 'sparse' or 'dense'")
    solve = power_flow
    if method == "sparse":
        from .powerflow_sparse import power_flow_sparse as solve
    res = solve(system, start=start, tol=tol, max_iter=max_iter)
    low = lambda r: float(jnp.min(r.vm))  # noqa: E731
    if start == "case" and (not bool(res.converged) or low(res) < LOW_V):
        flat = solve(system, start="flat", tol=tol, max_iter=max_iter)
        if bool(flat.converged) and (not bool(res.converged) or low(flat) > low(res)):
            res = flat
    if not bool(res.converged):
        m = float(res.mismatch)
        what, unit = ("Q", "Mvar") if bool(res.mismatch_is_q) else ("P", "MW")
        raise PowerFlowError(
            f"power flow did not converge in {int(res.iterations)} iterations: "
            f"largest mismatch {what} = {m:.4g} pu ({m * system.s_base:.4g} {unit}) "
            f"at bus {int(res.mismatch_bus)}"
        )
    return res


def scale_operating_point(system: System, load_factor=1.0, gen_factor=1.0) -> System:
    """`system` with every load's p and q times `load_factor` and the scheduled p of
    every generator not at a slack bus times `gen_factor` (the slack balances).
    Traceable: the factors may be JAX scalars (vmap over them)."""
    ld, g = system.loads, system.generators
    at_slack = jnp.asarray(system.buses.kind)[jnp.asarray(g.bus)] == SLACK
    gf = jnp.where(at_slack, 1.0, gen_factor)
    if np.size(ld.p_i):  # the constant-current parts scale with the loads
        system = eqx.tree_at(
            lambda s: (s.loads.p_i, s.loads.q_i),
            system,
            (jnp.asarray(ld.p_i) * load_factor, jnp.asarray(ld.q_i) * load_factor),
        )
    return eqx.tree_at(
        lambda s: (s.loads.p, s.loads.q, s.generators.p),
        system,
        (
            jnp.asarray(ld.p) * load_factor,
            jnp.asarray(ld.q) * load_factor,
            jnp.asarray(g.p) * gf,
        ),
    )
