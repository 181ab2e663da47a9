"""Shared by the issue-6 benchmark scripts: the benchmark scenarios and gains, the
batched simulation, timing and the tight-tolerance accuracy check.

Importing this imports JAX, so a script sets XLA_FLAGS (one host device per core)
before importing it.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import jax
import numpy as np

import smibjax as sj
from smibjax._batch import Engine, Scenarios
from smibjax._process import enable_compilation_cache
from smibjax._scenarios import FaultDistribution, sample_faults

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = Path(__file__).resolve().parent / "results"
CONTROLLERS = ("aftsc", "asc")
ALPHA = {"aftsc": "5/7", "asc": "1"}
# Tight-tolerance reference of the accuracy checks (adaptive Tsit5, same model).
REF_RTOL, REF_ATOL, REF_MAX_STEPS = 1e-10, 1e-12, 400_000
REFERENCE = sj.SolverOptions(rtol=REF_RTOL, atol=REF_ATOL, max_steps=REF_MAX_STEPS)
# The solver tolerances of the timed runs: simulate's defaults unless --rtol/--atol.
RTOL, ATOL = 1e-6, 1e-8


def solver_of(args) -> sj.SolverOptions:
    """The solver options of the timed runs: the adaptive solver at --rtol, --atol."""
    return sj.SolverOptions(rtol=args.rtol, atol=args.atol)


def add_tolerance_args(ap) -> None:
    """--rtol/--atol of the timed runs (and of SciPy's, where a script has one)."""
    ap.add_argument(
        "--rtol", type=float, default=RTOL, help="solver rtol (simulate's default 1e-6)"
    )
    ap.add_argument(
        "--atol", type=float, default=ATOL, help="solver atol (simulate's default 1e-8)"
    )
    ap.add_argument(
        "--tag",
        default="",
        help="suffix of the result files (NAME_TAG.json), e.g. for another tolerance",
    )


def result_name(name: str, tag: str) -> str:
    """NAME, or NAME_TAG."""
    return f"{name}_{tag}" if tag else name


def enable_cache() -> str | None:
    """The persistent compilation cache, as the CLI sets it, but only where
    SMIBJAX_CACHE_DIR is set (the tests use it to skip recompiles); returns the folder.
    Timed calls are second calls, which the cache does not change."""
    return enable_compilation_cache(os.environ.get("SMIBJAX_CACHE_DIR", ""))


def gains(controller: str) -> sj.Gains:
    """The paper's gains with the stabilizing beta1 = beta2 = -1."""
    return sj.Gains.paper(controller, beta1=-1.0, beta2=-1.0)


def scenarios(seed: int, n: int) -> sj.Fault:
    """`n` faults from the default distribution; the first k do not depend on n."""
    return sample_faults(jax.random.PRNGKey(seed), n, FaultDistribution())


def montecarlo_faults(seed: int, n: int) -> sj.Fault:
    """Scenarios 0..n-1 of `python -m smibjax montecarlo --seed SEED` (the default
    ScenarioDistribution: D and Pm are not drawn), as a batched `Fault`."""
    from smibjax._scenarios import ScenarioDistribution, sample_scenarios

    return sample_scenarios(seed, 0, n, ScenarioDistribution(), sj.Plant())[0]


def take(tree, n: int):
    """The first n scenarios of a batched pytree."""
    return jax.tree_util.tree_map(lambda a: a[:n], tree)


def row(tree, i: int):
    """Scenario i of a batched pytree (unbatched)."""
    return jax.tree_util.tree_map(lambda a: a[i], tree)


def host_devices(k: int) -> list:
    """The first k CPU devices (k = 1: one core)."""
    devs = jax.devices()
    if not 1 <= k <= len(devs):
        raise SystemExit(
            f"--devices {k}: this process has {len(devs)} host devices (set by "
            "XLA_FLAGS --xla_force_host_platform_device_count)"
        )
    return devs[:k]


def batched_metrics(t_end: float, solver: sj.SolverOptions | None = None):
    """The batch engine (`smibjax._batch.Engine`, the one every batched caller uses)
    as (gains, faults, devices) -> (stable, settling time of delta (s), accepted
    steps), with `solver` (default: simulate's); alpha = 1 (ASC) is compiled in by
    the engine."""
    engine = Engine(t_end=t_end, solver=solver or sj.SolverOptions())

    def fn(g, faults, devices=None):
        out = engine.run(g, Scenarios(faults), devices=devices)
        return out.metrics.stable, out.metrics.settling_delta, out.num_steps

    return fn


def timed(fn, repeat: int):
    """(first-call seconds, best of `repeat` later calls, last output); `fn` blocks."""
    t0 = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t0
    best = float("inf")
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return first, best, out


def deltas(
    g: sj.Gains,
    faults: sj.Fault,
    n: int,
    t_end: float,
    solver: sj.SolverOptions,
):
    """(delta (n, samples), lost_sync (n,)) of the first n scenarios, one unbatched
    run each with `solver` (`REFERENCE`: the tight reference, rtol 1e-10, atol
    1e-12)."""
    save = sj.SaveOptions(t_end=t_end)
    runs = [sj.simulate(g, row(faults, i), solver=solver, save=save) for i in range(n)]
    return (
        np.stack([np.asarray(tr.delta) for tr in runs]),
        np.array([bool(tr.lost_sync) for tr in runs]),
    )


def status(value: float, target: float, higher_is_better: bool = True) -> str:
    ok = value >= target if higher_is_better else value <= target
    return "met" if ok else "MISSED"
