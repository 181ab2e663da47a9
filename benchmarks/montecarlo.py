"""The Monte Carlo command's own throughput: N scenarios of 10 s (AFTSC, beta1 = beta2 =
-1, default adaptive Tsit5 rtol 1e-6 atol 1e-8) through `run_montecarlo`, chunks split
over all cores, files and all. Prints a table and writes
benchmarks/results/montecarlo.json and montecarlo.png (the run's own figure).

    python benchmarks/montecarlo.py [--n 100000] [--chunk 256] [--t-end 10]
        [--rtol 1e-6] [--atol 1e-8] [--tag NAME]

Target (issue 5): 100,000 scenarios at >= 300 scenarios/s on a 2-core machine.
"""

from __future__ import annotations

from smibjax import configure

configure(cache=False)  # as `python -m smibjax` does, before JAX starts its CPU backend

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import jax
from _common import add_tolerance_args, enable_cache, result_name, solver_of
from _results import write_results

import smibjax as sj
from smibjax._montecarlo import MonteCarloSpec, compute_chunk
from smibjax.cli.runs import run_montecarlo

TARGET = 300.0  # scenarios / s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--chunk", type=int, default=256)
    ap.add_argument("--t-end", type=float, default=10.0)
    add_tolerance_args(ap)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    # the persistent cache only where SMIBJAX_CACHE_DIR is set (the test suite's, so
    # that cluster_scaling.py's tiny run reads this one's programs); "first chunk"
    # is then a warm-cache figure, which the JSON says
    cache = enable_cache()
    result = result_name("montecarlo", args.tag)
    g = sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0)
    spec = MonteCarloSpec(
        n=args.n,
        chunk=min(args.chunk, args.n),
        gains={k: float(getattr(g, k)) for k in sj.GAIN_NAMES},
        t_end=args.t_end,
        solver=solver_of(args),
    )
    # compile once outside the timed run (a fresh process pays this once: reported)
    t0 = time.perf_counter()
    compute_chunk(spec, 0)
    first_chunk = time.perf_counter() - t0
    t0 = time.perf_counter()
    compute_chunk(spec, 0)
    warm_chunk = time.perf_counter() - t0
    tmp = Path(tempfile.mkdtemp(prefix="smibjax-mc-bench-"))
    try:
        t0 = time.perf_counter()
        rows, summary = run_montecarlo(spec, tmp / "run", title="benchmark")
        wall = time.perf_counter() - t0
        Path(args.out).mkdir(parents=True, exist_ok=True)
        shutil.copy(tmp / "run" / "montecarlo.png", Path(args.out) / f"{result}.png")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    rate = args.n / wall
    chunk_rate = spec.chunk / warm_chunk
    steps = summary["num_steps"]
    print(f"{'quantity':44} {'value':>12}")
    for name, v in (
        ("scenarios", f"{args.n}"),
        ("devices (cores)", f"{len(jax.devices())}"),
        ("chunk", f"{spec.chunk}"),
        ("first chunk incl. compile (s)", f"{first_chunk:.1f}"),
        ("warm chunk (s)", f"{warm_chunk:.2f}"),
        ("whole run, files included (s)", f"{wall:.1f}"),
        ("scenarios / s (whole run)", f"{rate:.0f}"),
        ("scenarios / s (one warm chunk)", f"{chunk_rate:.0f}"),
        ("target scenarios / s", f">= {TARGET:.0f}"),
        ("met", "yes" if rate >= TARGET else "no"),
        ("stable fraction", f"{summary['stable_fraction']:.4f}"),
        ("steps / scenario (mean, max)", f"{steps['mean']:.0f}, {steps['max']}"),
    ):
        print(f"{name:44} {v:>12}")
    write_results(
        args.out,
        result,
        {
            "n": args.n,
            "chunk": spec.chunk,
            "t_end": args.t_end,
            "controller": "aftsc, beta1 = beta2 = -1",
            "solver": f"Tsit5 adaptive, rtol {args.rtol:g}, atol {args.atol:g}",
            "persistent_compilation_cache": bool(cache),
        },
        {
            "devices": len(jax.devices()),
            "first_chunk_s": first_chunk,
            "warm_chunk_s": warm_chunk,
            "wall_s": wall,
            "scenarios_per_s": rate,
            "chunk_scenarios_per_s": chunk_rate,
            "target_scenarios_per_s": TARGET,
            "met": rate >= TARGET,
            "stable_fraction": summary["stable_fraction"],
            "steps_mean": steps["mean"],
            "steps_max": steps["max"],
        },
    )


if __name__ == "__main__":
    main()
