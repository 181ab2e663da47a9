"""The operating point of a case: the power flow, then every device at equilibrium.

`operating_point` is the host-side entry (it raises `PowerFlowError` with one line);
`operating_point_traced` the jittable one (load and generation factors may be traced,
e.g. drawn per scenario; check `pf.converged`)."""

from __future__ import annotations

import equinox as eqx
import jax
import numpy as np

from .._errors import ParameterError
from .loop import Case, Operating, initialize
from .powerflow import (
    PowerFlowResult,
    power_flow,
    scale_operating_point,
    solve_power_flow,
)

__all__ = [
    "operating_point",
    "operating_point_traced",
    "scaled_power_flow",
    "check_islanding",
    "rest_residual",
    "not_at_rest",
]


def operating_point(
    case: Case, load_factor: float = 1.0, gen_factor: float = 1.0
) -> tuple[Operating, PowerFlowResult]:
    """(Operating, power flow) of `case` with its loads and non-slack generation
    scaled by the factors (1: the raw file's)."""
    scaled, pf = scaled_power_flow(case, load_factor, gen_factor)
    # one compiled program, not a hundred one-operation ones run eagerly (the case's
    # index arrays stay concrete in the closure)
    init = jax.jit(lambda vm, va, p, q: initialize(scaled, vm, va, p, q))
    op = init(pf.vm, pf.va, pf.p_gen, pf.q_gen)
    return op, pf


def scaled_power_flow(
    case: Case, load_factor: float = 1.0, gen_factor: float = 1.0
) -> tuple[Case, PowerFlowResult]:
    """(`case` with its loads and non-slack generation scaled by the factors, its
    power flow) on the host: `PowerFlowError` (one line) if Newton fails. The
    devices are not initialized (`initialize` does that from the power flow)."""
    system = case.system
    if load_factor != 1.0 or gen_factor != 1.0:
        system = scale_operating_point(system, load_factor, gen_factor)
    pf = solve_power_flow(system)
    return _with_system(case, system), pf


def _with_system(case: Case, system) -> Case:
    """`case` with its loads and schedules scaled (`system`): the loads become
    constant impedances from the scaled P + jQ, so that the state at rest is an
    equilibrium of the scaled network (with the raw file's loads it is not)."""
    return eqx.tree_at(lambda c: c.system, case, system)


def operating_point_traced(case: Case, load_factor=1.0, gen_factor=1.0):
    """`operating_point` without the host check: jittable and vmappable over the
    factors; differentiable through the power flow (implicit function theorem)."""
    system = scale_operating_point(case.system, load_factor, gen_factor)
    pf = power_flow(system)
    op = initialize(_with_system(case, system), pf.vm, pf.va, pf.p_gen, pf.q_gen)
    return op, pf


def check_islanding(case: Case, events) -> None:
    """ValueError (one line) if the branch trips among concrete `events`, applied
    in order, split the network into islands."""
    from .events import BranchClose, BranchTrip

    br = case.system.branches
    status = np.asarray(br.status).copy()
    nums = np.asarray(case.system.buses.number)
    for e in events:
        if isinstance(e, BranchTrip | BranchClose):
            try:
                k = int(e.branch)
            except TypeError:  # traced: nothing to check
                return
            status[k] = 0.0 if isinstance(e, BranchTrip) else 1.0
            if isinstance(e, BranchTrip):
                comp = _components(case.system.n_bus, br, status)
                if len(set(comp)) > 1:
                    a, b = int(nums[br.fr[k]]), int(nums[br.to[k]])
                    lone = [
                        int(nums[i]) for i in range(len(comp)) if comp[i] != comp[0]
                    ]
                    raise ParameterError(
                        f"tripping branch {a}-{b} islands the system (buses "
                        f"{lone[:8]}{' ...' if len(lone) > 8 else ''} separate)"
                    )


def _components(n, br, status):
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k in range(len(status)):
        if status[k] > 0:
            a, b = find(int(br.fr[k])), find(int(br.to[k]))
            parent[a] = b
    return [find(i) for i in range(n)]


def rest_residual(case: Case, op: Operating):
    """dy/dt at the operating point's state y0, in the network before any event
    (one per state, `loop.state_labels` order; per second). Zero to rounding where
    every device starts at rest; a device whose data put its operating point beyond
    its own limits (an exciter that cannot deliver the field voltage the power flow
    needs) is not at rest. Jittable."""
    from .loop import evaluate
    from .network import stage_configs, stage_matrices

    cfgs = stage_configs(op.grid, ())
    mats = stage_matrices(op.grid, cfgs, ())
    return evaluate(case, op, mats, 0, op.y0)[0]


def not_at_rest(case: Case, dy, tol: float = 1e-6) -> list[tuple[str, str, str, float]]:
    """(model, generator or bus, state, dy/dt) of the largest |dy/dt| > `tol` of each
    device that does not start at rest (`rest_residual`), largest first: what
    PSS/E lists as suspect initial conditions."""
    from .loop import state_labels

    dy = np.asarray(dy)
    worst: dict[tuple[str, str], tuple[str, float]] = {}
    for (model, where, state), v in zip(state_labels(case), dy, strict=True):
        if abs(v) > tol and abs(v) > abs(worst.get((model, where), ("", 0.0))[1]):
            worst[(model, where)] = (state, float(v))
    rows = [(m, w, st, v) for (m, w), (st, v) in worst.items()]
    return sorted(rows, key=lambda r: -abs(r[3]))
