"""Monte Carlo over fault scenarios of a multi-machine case: seeded and chunked.

The n scenarios of (`FaultDistribution`, n, seed) are drawn at once
(`scenarios.sample_events`), so scenario i is the same in every run of those three;
chunk k holds scenarios [k chunk, (k + 1) chunk) and `compute_chunk` is a pure
function of the chunk's scenarios: chunks can be computed in any order, in any
process, retried, and a run killed between chunks finished from the chunks it
wrote. The last chunk is padded to the chunk size by repeating its final scenario
(one compiled program per run) and the padding dropped. Rows name the fault by its
PSS/E bus numbers (`fault_bus`, or `from_bus`, `to_bus`, `circuit` for a line) and
hold the scenario's times (s) and fault impedance (pu) with its `GridMetrics`.
`summarize` reduces the rows. Run folders (chunk files, resume, CSV, markdown) are
the command line's (`smibjax.cli.grid`): nothing here prints or writes files.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math

import jax
import numpy as np

from .._montecarlo import wilson_interval
from .loop import Case, Operating
from .metrics import GridMetrics, batch_metrics
from .scenarios import FaultDistribution, sample_events

__all__ = [
    "GridMonteCarloSpec",
    "GridChunkJob",
    "grid_chunk",
    "draw",
    "scenario_rows",
    "chunk_runner",
    "summarize",
    "METRIC_COLUMNS",
]

METRIC_COLUMNS = GridMetrics.FIELDS


@dataclasses.dataclass(frozen=True)
class GridMonteCarloSpec:
    """What a run computes, as plain numbers (JSON-able: a resumed run must match
    the spec it was started with): the draw (`n` scenarios, `seed`), the chunk
    size, the horizon `t_end` and sampling `dt_save` (s), the tolerances, and the
    fault distribution's fields (`distribution`, a dict of `FaultDistribution`)."""

    n: int
    seed: int
    chunk: int
    t_end: float
    dt_save: float
    rtol: float
    atol: float
    distribution: dict

    @property
    def n_chunks(self) -> int:
        return math.ceil(self.n / self.chunk)

    def chunk_range(self, k: int) -> tuple[int, int]:
        return k * self.chunk, min((k + 1) * self.chunk, self.n)

    def fault_distribution(self) -> FaultDistribution:
        d = {
            k: tuple(v) if isinstance(v, list) else v
            for k, v in self.distribution.items()
        }
        for k in ("buses", "branches"):
            d[k] = tuple(tuple(x) if isinstance(x, list) else x for x in d.get(k, ()))
        return FaultDistribution(**d)

    def solver(self) -> dict:
        return dict(
            t_end=self.t_end, dt_save=self.dt_save, rtol=self.rtol, atol=self.atol
        )

    def to_dict(self) -> dict:
        return json_ready(dataclasses.asdict(self))


def json_ready(x):
    """Tuples as lists, recursively (what a JSON round trip gives back)."""
    if isinstance(x, dict):
        return {k: json_ready(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_ready(v) for v in x]
    return x


def draw(case: Case, spec: GridMonteCarloSpec):
    """The run's n scenarios: a tuple of events with a leading batch axis (numpy)."""
    events = sample_events(case.system, spec.fault_distribution(), spec.n, spec.seed)
    return jax.tree_util.tree_map(np.asarray, events)


def scenario_rows(case: Case, events) -> dict[str, np.ndarray]:
    """The scenario columns of every drawn scenario: `index`; `fault_bus` (PSS/E
    number) for bus faults, else `from_bus`, `to_bus`, `circuit` and
    `fault_location` (fraction from the from-bus); `t_fault`, `t_clear`,
    `t_reclose` (s; inf: none); `fault_r`, `fault_x` (pu, system base)."""
    sys_ = case.system
    first = events[0]
    n = len(np.atleast_1d(first.t_on))
    nums = np.asarray(sys_.buses.number)
    rows: dict[str, np.ndarray] = {"index": np.arange(n)}
    if hasattr(first, "bus"):
        rows["fault_bus"] = nums[np.asarray(first.bus)]
    else:
        br = np.asarray(first.branch)
        rows["from_bus"] = nums[np.asarray(sys_.branches.fr)[br]]
        rows["to_bus"] = nums[np.asarray(sys_.branches.to)[br]]
        ckt = getattr(sys_.branches, "ckt", None) or ("1",) * len(sys_.branches.r)
        rows["circuit"] = np.array([str(ckt[int(b)]).strip() for b in br])
        rows["fault_location"] = np.asarray(first.frac, dtype=float)
    rows["t_fault"] = np.asarray(first.t_on, dtype=float)
    rows["t_clear"] = np.asarray(first.t_off, dtype=float)
    close = [e for e in events if type(e).__name__ == "BranchClose"]
    rows["t_reclose"] = (
        np.asarray(close[0].t, dtype=float) if close else np.full(n, np.inf)
    )
    rows["fault_r"] = np.asarray(first.r, dtype=float)
    rows["fault_x"] = np.asarray(first.x, dtype=float)
    return rows


def chunk_runner(case: Case, op: Operating, spec: GridMonteCarloSpec, events=None):
    """A function `k -> rows of chunk k` (scenario columns and `GridMetrics`
    columns, numpy), every chunk through one compiled program (`batch_metrics`)."""
    events = draw(case, spec) if events is None else events
    scen = scenario_rows(case, events)
    run = batch_metrics(case, op, **spec.solver())

    def compute(k: int) -> dict[str, np.ndarray]:
        start, stop = spec.chunk_range(k)
        idx = np.minimum(np.arange(start, start + spec.chunk), stop - 1)
        ev = jax.tree_util.tree_map(lambda a: np.asarray(a)[idx], events)
        m = run(ev)
        rows = {c: v[start:stop] for c, v in scen.items()}
        for f in METRIC_COLUMNS:
            rows[f] = np.asarray(getattr(m, f))[: stop - start]
        return rows

    return compute


def _round(x, digits: int = 6):
    """A float to `digits` significant digits (None and inf kept)."""
    if x is None or not math.isfinite(x):
        return x
    return float(f"{x:.{digits}g}")


def _quantiles(a: np.ndarray) -> dict:
    if not a.size:
        return {"mean": None, "p50": None, "p95": None, "max": None}
    return {
        "mean": _round(float(np.mean(a))),
        "p50": _round(float(np.percentile(a, 50))),
        "p95": _round(float(np.percentile(a, 95))),
        "max": _round(float(np.max(a))),
    }


def summarize(rows: dict[str, np.ndarray]) -> dict:
    """The run's figures, rounded to 6 significant digits: stable fraction with its
    95% Wilson interval, runs that spent the step budget, the fraction of stable
    runs that settle (`grid.metrics`: in band for the last second), and quantiles of
    the settling time (s, over the settled runs), overshoot (rad, over the stable
    runs), largest |angle - COI| (rad), lowest bus voltage (pu) and peak field
    voltage (pu)."""
    st = np.asarray(rows["stable"], dtype=bool)
    n = int(st.size)
    ex = np.asarray(rows["exhausted"], dtype=bool)
    settle = np.asarray(rows["settling_angle"], dtype=float)
    settled = st & np.isfinite(settle)
    lo, hi = wilson_interval(int(st.sum()), n)
    return {
        "n": n,
        "stable_fraction": _round(float(st.mean())) if n else None,
        "stable_interval_95": [_round(lo), _round(hi)],
        "lost_synchronism": int(np.sum(~st & ~ex)),
        "exhausted": int(ex.sum()),
        "settled_fraction_of_stable": _round(float(settled.sum() / st.sum()))
        if st.any()
        else None,
        "settling_angle_s": _quantiles(settle[settled]),
        "overshoot_rad": _quantiles(np.asarray(rows["overshoot"], float)[st]),
        "max_spread_rad": _quantiles(np.asarray(rows["max_spread"], float)),
        "v_min_pu": _quantiles(np.asarray(rows["v_min"], float)),
        "efd_max_pu": _quantiles(np.asarray(rows["efd_max"], float)),
    }


@dataclasses.dataclass(frozen=True)
class GridChunkJob:
    """What a process needs to compute chunks of a run on its own (a Dask worker):
    the run's `spec` and the `context` that rebuilds its case, as plain values:
    `case_files` ([raw file or built-in case name, dyr file or None]),
    `skip_unsupported`, `params` (name -> value, `grid.params`) and `load_factor`.
    Its `to_dict()` names the chunks' Dask keys (`cli.cluster.chunk_key`): another
    case or parameter set never shares a key."""

    context: dict
    spec: GridMonteCarloSpec

    @property
    def seed(self) -> int:
        return self.spec.seed

    def to_dict(self) -> dict:
        keep = ("case_files", "skip_unsupported", "params", "load_factor")
        ctx = {k: self.context.get(k) for k in keep}
        return json_ready({"context": ctx, "spec": self.spec.to_dict()})


@functools.lru_cache(maxsize=2)
def _prepared(job_text: str):
    """(case, operating point, chunk function) of a job, once per process."""
    from .case import load_case
    from .operating import operating_point
    from .params import set_params

    job = json.loads(job_text)
    ctx, spec = job["context"], GridMonteCarloSpec(**job["spec"])
    raw, dyr = ctx["case_files"]
    case = load_case(raw, dyr, skip_unsupported=bool(ctx["skip_unsupported"]))
    if ctx.get("params"):
        case = set_params(case, ctx["params"])
    lf = float(ctx.get("load_factor", 1.0))
    op, _ = operating_point(case, lf, lf)
    return chunk_runner(case, op, spec)


def grid_chunk(job: GridChunkJob, k: int) -> dict[str, np.ndarray]:
    """The rows of chunk k of `job`, computed in this process from the job alone
    (the case rebuilt from its files once per process): the rows `chunk_runner`
    gives in the process that drew the run."""
    text = json.dumps(job.to_dict(), sort_keys=True)
    return _prepared(text)(k)
