"""The memory plan of a grid run: what a run (or a batch of runs) of a case needs,
computed before it runs, so that a run that cannot fit is refused in one line and a
batch's chunk is sized to the memory available (issue 46; the SMIB's plan is
`_validate.require_memory`).

An estimate for planning, not a measurement (float64; complex128 for network
quantities): per run, the saved states and outputs and the recording's per-stage
temporaries (samples x (states + buses + ports + generator outputs)) and the stages'
reduced matrices (ports^2 and the low-rank factors); shared by a batch, the base
network's dense factorization (N^2) and its port responses (N x ports).
"""

from __future__ import annotations

import math

from .._validate import ParameterError, memory_budget

__all__ = ["RunSize", "run_size", "require_fit", "chunk_that_fits"]

_F, _C = 8, 16  # bytes of a float64, a complex128
_SLACK = 2.0  # XLA's temporaries and copies around the estimate


class RunSize:
    """Bytes one run needs (`per_run`) and a batch shares once (`shared`)."""

    def __init__(self, per_run: float, shared: float):
        self.per_run = float(per_run)
        self.shared = float(shared)

    def batch(self, runs: float) -> float:
        """Bytes a batch of `runs` runs needs."""
        return self.shared + float(runs) * self.per_run


def run_size(case, n_samples: float, n_events: int = 1, n_lf: int = 0) -> RunSize:
    """The memory plan of runs of `case` saving `n_samples` samples, with `n_events`
    events (each up to three touched nodes and two stages) of which `n_lf` are line
    faults (one spare node each)."""
    n = case.system.n_bus
    N = n + n_lf
    p = len(case.layout.ports)
    g = case.n_gen
    n_state = 0
    for grp in (*case.machines, *case.controllers, *case.svcs, *case.injectors):
        k = len(getattr(grp, "gen", getattr(grp, "bus", ())))
        n_state += len(grp.state_names) * max(k, 1)
    stages = 1 + 2 * n_events
    K = 3 * n_events
    T = float(n_samples)
    per_sample = (
        2 * n_state * _F  # diffrax's saved states, and their NaN-masked copy
        + n * (_C + 4 * _F)  # one stage's bus voltages, |V|, the kept ones, output
        + 2 * p * _C  # the port currents of a stage pass
        + 3 * 12 * g * _F  # the measurements (pass, kept, output)
    )
    stage = stages * (p * p + K * (p + 1) + p + n) * _C + N * K * _C
    per_run = _SLACK * (T * per_sample + stage)
    shared = _SLACK * (3 * N * N * _C + N * (p + 1) * _C)
    return RunSize(per_run, shared)


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g} GiB"


def require_fit(what: str, size: RunSize, runs: float, hint: str) -> None:
    """`ParameterError` (one line) unless a batch of `runs` runs fits
    `memory_budget()`; `what` names the input, `hint` says what to change."""
    need = size.batch(runs)
    budget = memory_budget()
    if not need <= budget:
        raise ParameterError(
            f"{what} is not allowed: {float(runs):.4g} run(s) need about "
            f"{_gib(need)}, more than the {_gib(budget)} available (half the memory; "
            f"SMIBJAX_MEMORY_LIMIT overrides): {hint}"
        )


def chunk_that_fits(size: RunSize, limit: int) -> int:
    """The largest batch (at most `limit`) that fits `memory_budget()`; 0 if not
    even one run does."""
    room = memory_budget() - size.shared
    if room < size.per_run:
        return 0
    return int(min(limit, math.floor(room / size.per_run)))
