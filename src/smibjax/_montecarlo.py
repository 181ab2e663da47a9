"""Batch Monte Carlo over fault scenarios: seeded and chunked.

A run is described by a `MonteCarloSpec` (plain numbers and the solver's options,
JSON-able). Scenario i depends only on (seed, i) (see `sample_scenarios`), chunk k
holds scenarios [k chunk, (k + 1) chunk), and `compute_chunk(spec, k)` is a pure function of the two
(through the batch engine, `smibjax._batch`): chunks can run in any order, in any
process, and be retried. `summarize` reduces the rows. Run folders (chunk files,
resume, CSV and markdown) are the command line's: `smibjax.cli.runs`.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Iterable, Iterator

import jax
import jax.numpy as jnp
import numpy as np

from ._batch import Engine, Outcome, Scenarios
from ._closed_loop import require_start
from ._metrics import PHYSICS, physics_summary
from ._options import SolverOptions, adopt_legacy_solver
from ._parameters import InitialEstimates, OperatingPoint, ParameterError, Plant
from ._scenarios import ScenarioDistribution, sample_scenarios
from ._validate import (
    require_count,
    require_positive,
    require_samples,
)
from .controllers import CONTROLLERS, as_controller, parameter_set

__all__ = [
    "COLUMNS",
    "MonteCarloSpec",
    "MonteCarloResult",
    "monte_carlo",
    "compute_chunk",
    "summarize",
    "wilson_interval",
    "outcome_columns",
    "in_process_runner",
    "INT_COLUMNS",
]

# One row per scenario in scenarios.csv, in this order.
COLUMNS = (
    "index",
    "t_fault",  # s
    "t_clear",  # s
    "t_reclose",  # s
    "clear_duration",  # t_clear - t_fault (s)
    "fault_location",  # lam, from the SVC bus
    "fault_reactance",  # Xf (pu)
    "D",  # true damping of the scenario
    "Pm",  # true mechanical power (pu)
    "stable",  # 1: no loss of synchronism and delta in band at t_end
    "lost_sync",  # 1: the run left 0 < delta < pi (or the model's domain)
    "budget_exhausted",  # 1: the solver spent max_steps first (neither verdict)
    "t_stop",  # s: t_end, or when synchronism was lost
    "settling_time",  # delta, 0.01 rad band, from fault inception (s; inf: never)
    "settling_Vt",  # s
    "settling_omega",  # s
    "overshoot",  # first-swing max |delta - delta_e| (rad)
    "effort_uf",  # integral of u_f^2 (pu^2 s)
    "effort_ur",  # integral of u_r^2 (pu^2 s)
    "peak_uf",  # max |u_f| (pu)
    "peak_ur",  # max |u_r| (pu)
    "peak_B",  # max |B| (pu)
    "peak_uf_cmd",  # max |u_f| commanded, before the limits (pu)
    "peak_ur_cmd",  # max |u_r| commanded, before the limits (pu)
    "limit_time_uf",  # fraction of the run with u_f on a limit
    "limit_time_ur",  # fraction of the run with u_r on a limit
    "tv_uf",  # total variation of the applied u_f (pu): chatter
    "tv_ur",  # total variation of the applied u_r (pu)
    "Vt_min",  # range of the SVC-bus voltage (pu)
    "Vt_max",
    "B_min",  # range of the SVC susceptance (pu)
    "B_max",
    "E_min",  # range of E' (pu)
    "E_max",
    "num_steps",  # accepted solver steps
)
_PHYSICS = PHYSICS
INT_COLUMNS = ("index", "stable", "lost_sync", "budget_exhausted", "num_steps")


@dataclasses.dataclass(frozen=True)
class MonteCarloSpec:
    """Everything that determines the rows of a Monte Carlo run.

    `gains`, `plant`, `op`, `init` are flat name -> value tables (the controller's
    parameters, plant overrides, operating point, initial estimates); `controller`
    is a registry name (`smibjax.controllers`; "" : the paper's law, AFTSC or ASC by
    alpha) and `options` its options (the paper's law: projection, phi_layer, as in a
    gains file); `dist` is a `ScenarioDistribution.to_dict()`; `t_end`, `dt_save`
    (s): horizon and sampling of every run; `solver`: a `SolverOptions`, passed whole
    to the batch engine (in `to_dict`: a table of its fields). The chunk size is part
    of the spec only because chunk files are named by index; the rows do not depend
    on it.

    The keywords `rtol`, `atol`, `max_steps` of 0.1 still work, with a
    `DeprecationWarning`, for one release (they build `solver`).
    """

    n: int
    seed: int = 0
    chunk: int = 1024
    gains: dict = dataclasses.field(default_factory=dict)
    plant: dict = dataclasses.field(default_factory=dict)
    op: dict = dataclasses.field(default_factory=dict)
    init: dict = dataclasses.field(default_factory=dict)
    dist: dict = dataclasses.field(
        default_factory=lambda: ScenarioDistribution().to_dict()
    )
    adaptation: str = "oracle"
    controller: str = ""
    options: dict = dataclasses.field(default_factory=dict)
    t_end: float = 10.0
    dt_save: float = 0.01
    solver: SolverOptions = dataclasses.field(default_factory=SolverOptions)
    rtol: dataclasses.InitVar[float | None] = None  # deprecated: solver.rtol
    atol: dataclasses.InitVar[float | None] = None  # deprecated: solver.atol
    max_steps: dataclasses.InitVar[int | None] = None  # deprecated

    def __post_init__(self, rtol, atol, max_steps):
        for name in ("n", "chunk"):
            require_count(name, getattr(self, name))
        adopt_legacy_solver(self, rtol, atol, max_steps)
        if self.adaptation not in ("oracle", "realizable"):
            raise ParameterError(
                f"adaptation = {self.adaptation!r} is not allowed: must be 'oracle' "
                "or 'realizable'"
            )
        for name in ("t_end", "dt_save"):
            require_positive(name, getattr(self, name))
        require_samples(self.t_end, self.dt_save)
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, numbers.Integral)
            or not 0 <= self.seed < 2**32
        ):
            raise ParameterError(
                f"seed = {self.seed!r} is not allowed: must be an integer in [0, 2**32)"
            )
        faults = ScenarioDistribution.from_dict(self.dist).faults  # validates
        latest = faults.t_fault[1] + faults.clear_duration[1]
        if not latest < self.t_end:
            raise ParameterError(
                f"t_end = {self.t_end:g} is not allowed: must be > {latest:g} s, the "
                "latest clearing time of the scenario distribution (t_fault + "
                "clear_duration): every fault must happen and clear within the run"
            )
        self.parameters()  # validates the parameter tables

    @property
    def n_chunks(self) -> int:
        return -(-self.n // self.chunk)

    def chunk_range(self, k: int) -> tuple[int, int]:
        """Scenario indices [start, stop) of chunk k."""
        return k * self.chunk, min(self.n, (k + 1) * self.chunk)

    def distribution(self) -> ScenarioDistribution:
        return ScenarioDistribution.from_dict(self.dist)

    def controller_name(self) -> str:
        """The registry name of the controller ("" is the paper's AFTSC)."""
        return self.controller or "aftsc"

    def controller_of(self, params):
        """The controller with parameter set `params` (`parameters()[0]`), under
        the spec's adaptation mode and options."""
        return as_controller(params, self.adaptation, self.options)

    def parameters(self) -> tuple:
        """The parameter sets (values may be given as numbers or 'inf' strings): the
        controller's (`Gains` for the paper's law), Plant, OperatingPoint,
        InitialEstimates."""

        def f(d):
            return {k: float(v) for k, v in d.items()}

        if self.controller not in ("", *CONTROLLERS):
            raise ParameterError(
                f"controller = {self.controller!r} is not allowed: must be one of "
                f"{', '.join(CONTROLLERS)}"
            )
        name = self.controller_name()
        CONTROLLERS[name].check_options(name, dict(self.options))
        params = parameter_set(name, f(self.gains))
        plant, op = Plant(**f(self.plant)), OperatingPoint(**f(self.op))
        require_start(plant, op)
        return (params, plant, op, InitialEstimates(**f(self.init)))

    def to_dict(self) -> dict:
        """JSON-able (infinite values as the strings 'inf' and '-inf')."""

        def clean(v):
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            if isinstance(v, (list, tuple)):
                return [clean(x) for x in v]
            if isinstance(v, float) and math.isinf(v):
                return "inf" if v > 0 else "-inf"
            return v

        return clean(dataclasses.asdict(self))

    @staticmethod
    def upgrade(d: dict) -> dict:
        """A spec's dict in today's layout: one written before 0.2 had the solver's
        `rtol`, `atol`, `max_steps` at the top level; they move into its `solver`
        table (the other solver options at their defaults, as those runs had)."""
        d = dict(d)
        flat = {k: d.pop(k) for k in ("rtol", "atol", "max_steps") if k in d}
        if flat:
            base = dataclasses.asdict(SolverOptions())
            d["solver"] = {**base, **d.get("solver", {}), **flat}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> MonteCarloSpec:
        """The inverse of `to_dict` (also reads the layout before 0.2: `upgrade`)."""
        d = cls.upgrade(d)
        if isinstance(d.get("solver"), dict):
            d["solver"] = SolverOptions(**d["solver"])
        return cls(**d)


def compute_chunk(spec: MonteCarloSpec, k: int, devices=None) -> dict[str, np.ndarray]:
    """The rows of chunk `k` (a dict of `COLUMNS` -> arrays), split over `devices`
    (default: every JAX device of this process). A pure function of (spec, k)."""
    if not 0 <= k < spec.n_chunks:
        raise ParameterError(
            f"chunk {k} is not allowed: the run has chunks 0 to {spec.n_chunks - 1}"
        )
    start, stop = spec.chunk_range(k)
    params = spec.parameters()
    faults, D, Pm = sample_scenarios(
        spec.seed, start, stop, spec.distribution(), params[1]
    )
    scen = (faults, D, Pm)
    # Pad the last chunk so that every chunk has one compiled shape, and never run a
    # batch of one: XLA compiles a batch of one to a different program, whose rounding
    # (and step count) differs from a larger batch's.
    width = max(spec.chunk, 2)
    if stop - start < width:
        scen = jax.tree_util.tree_map(
            lambda a: jnp.concatenate(
                [a, jnp.repeat(a[-1:], width - (stop - start), axis=0)]
            ),
            scen,
        )
    draw = any(k in spec.dist for k in ("D", "Pm"))
    params, plant, op, init = params
    engine = Engine(
        plant,
        op,
        init,
        t_end=spec.t_end,
        dt_save=spec.dt_save,
        solver=spec.solver,
    )
    out = outcome_columns(
        engine.run(
            spec.controller_of(params),
            Scenarios(*scen) if draw else Scenarios(scen[0]),
            devices=devices,
        )
    )
    m = stop - start
    rows = {k_: np.asarray(v)[:m] for k_, v in out.items()}
    rows["index"] = np.arange(start, stop)
    rows["t_fault"] = np.asarray(faults.t_fault)
    rows["t_clear"] = np.asarray(faults.t_clear)
    rows["t_reclose"] = np.asarray(faults.t_reclose)
    rows["clear_duration"] = rows["t_clear"] - rows["t_fault"]
    rows["fault_location"] = np.asarray(faults.lam)
    rows["fault_reactance"] = np.asarray(faults.Xf)
    rows["D"] = np.asarray(D)
    rows["Pm"] = np.asarray(Pm)
    return {c: rows[c].astype(int) if c in INT_COLUMNS else rows[c] for c in COLUMNS}


def outcome_columns(out: Outcome) -> dict:
    """The computed columns of Monte Carlo rows from the engine's `Outcome`."""
    m = out.metrics
    return {
        "stable": m.stable,
        "lost_sync": out.lost_sync,
        "budget_exhausted": out.budget_exhausted,
        "t_stop": out.t_stop,
        "settling_time": m.settling_delta,
        "settling_Vt": m.settling_Vt,
        "settling_omega": m.settling_omega,
        "overshoot": m.overshoot,
        "effort_uf": m.effort_uf,
        "effort_ur": m.effort_ur,
        "peak_uf": m.peak_uf,
        "peak_ur": m.peak_ur,
        "peak_B": m.peak_B,
        **{k: getattr(m, k) for k in _PHYSICS},
        "num_steps": out.num_steps,
    }


def in_process_runner(
    spec: MonteCarloSpec, chunks: Iterable[int]
) -> Iterator[tuple[int, dict]]:
    """Run chunks one after another in this process (each spread over all devices)."""
    for k in chunks:
        yield k, compute_chunk(spec, k)


@dataclasses.dataclass(frozen=True)
class MonteCarloResult:
    """A finished Monte Carlo run: its spec and one row per scenario (`rows`: column
    name -> array over the scenarios in index order, the columns of `COLUMNS`)."""

    spec: MonteCarloSpec
    rows: dict[str, np.ndarray]

    def summary(self) -> dict:
        """The run's summary (`summarize`): stable fraction with its 95% Wilson
        interval, loss-of-synchronism count, quantiles over the stable scenarios."""
        return summarize(self.rows)

    def to_dict(self) -> dict:
        """JSON-able: {"spec": the spec's dict, "summary": `summary()`}."""
        return {"spec": self.spec.to_dict(), "summary": self.summary()}


def monte_carlo(
    spec: MonteCarloSpec,
    runner: Callable[[MonteCarloSpec, Iterable[int]], Iterator[tuple[int, dict]]]
    | None = None,
) -> MonteCarloResult:
    """Run every chunk of `spec` (`runner(spec, chunks)` yields (k, rows of chunk k)
    in any order; default: `in_process_runner`) and join the rows in index order."""
    runner = runner or in_process_runner
    parts = dict(runner(spec, range(spec.n_chunks)))
    rows = {c: np.concatenate([parts[k][c] for k in sorted(parts)]) for c in COLUMNS}
    return MonteCarloResult(spec, rows)


def wilson_interval(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion k/n (95% by default)."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z**2 / n
    mid = (p + z**2 / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def _quantiles(x: np.ndarray) -> dict:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"count": 0}
    q = np.quantile(x, [0.05, 0.5, 0.9, 0.95, 0.99])
    return {
        "count": int(x.size),
        "mean": float(x.mean()),
        "p05": float(q[0]),
        "p50": float(q[1]),
        "p90": float(q[2]),
        "p95": float(q[3]),
        "p99": float(q[4]),
        "max": float(x.max()),
    }


def summarize(rows: dict[str, np.ndarray]) -> dict:
    """Stable fraction (with its 95% Wilson interval), loss-of-synchronism fraction,
    and quantiles of settling times and overshoot over the stable scenarios."""
    stable = rows["stable"].astype(bool)
    n, k = int(stable.size), int(stable.sum())
    lo, hi = wilson_interval(k, n)
    return {
        "n": n,
        "stable": k,
        "stable_fraction": k / n if n else 0.0,
        "stable_fraction_ci95": [lo, hi],
        "lost_sync": int(rows["lost_sync"].sum()),
        "budget_exhausted": int(rows["budget_exhausted"].sum()),
        "settling_time": _quantiles(rows["settling_time"][stable]),
        "settling_Vt": _quantiles(rows["settling_Vt"][stable]),
        "overshoot": _quantiles(rows["overshoot"][stable]),
        "physics": _physics(rows),
        "num_steps": {
            "mean": float(rows["num_steps"].mean()),
            "max": int(rows["num_steps"].max()),
        },
    }


def _physics(rows) -> dict:
    """`metrics.physics_summary` of the rows ({} for rows from before these columns
    existed)."""
    return physics_summary(rows) if "peak_uf_cmd" in rows else {}
