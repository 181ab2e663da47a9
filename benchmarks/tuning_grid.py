"""Coordinated PSS tuning on a multi-machine case, baselines side by side (issue 30):
the case's textbook stabilizers, no stabilizers (KS = 0), the gradient tuner
(`python -m tuning.optimize` with the same config) and CMA-ES (pycma) on the same loss
at an equal simulation budget (the gradient run's training scenarios: steps x batch;
CMA-ES evaluates the loss without gradients on batches of the same distribution).

Every set is judged on one held-out Monte Carlo (`--n` scenarios of the config's
fault distribution and load range, a seed that neither tuner saw): stable fraction,
mean and p95 settling (COI angles and COI-referred speeds, as in the tuner's
validation), worst damping ratio of the electromechanical modes, of the inter-area
mode and of every oscillatory mode of 0.05-5 Hz over load factors 0.8, 1.0, 1.2.
Prints a table and writes benchmarks/results/tuning_grid_<case>.json.

    python benchmarks/tuning_grid.py [--config tuning/configs/kundur_pss.toml]
        [--n 64] [--seed 2026] [--steps N] [--batch B] [--popsize P]

Wall times are this machine's, loaded or not (the JSON says which CPU-seconds too).
"""

from __future__ import annotations

from smibjax import configure

configure()

import argparse
import json
import math
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _results import write_results  # noqa: E402

from tuning.grid_config import check_grid_config, load_grid_config  # noqa: E402
from tuning.grid_problem import build_grid, make_loss, reference  # noqa: E402
from tuning.grid_run import _validation_fn, run_grid, validate  # noqa: E402


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def cma_tune(problem, budget: int, batch: int, popsize: int, seed: int):
    """CMA-ES (pycma) on the raw parameters (the tuner's transforms and bounds),
    minimizing the tuner's loss on batches of `batch` training scenarios, until
    `budget` scenario simulations; the damping reference is refreshed with the mean
    every generation. Returns (best raw, history)."""
    import cma

    space = problem.space
    raw0 = space.to_raw(space.start)
    names = space.names
    x0 = np.array([float(raw0[n]) for n in names])
    lo, hi = space.raw_bounds()
    loss = jax.jit(make_loss(problem))
    es = cma.CMAEvolutionStrategy(
        x0,
        0.2,
        {
            "popsize": popsize,
            "bounds": [list(lo), list(hi)],
            "seed": seed + 1,
            "verbose": -9,
        },
    )
    used, gen, hist = 0, 0, []
    best_x, best_f = x0, math.inf
    while used + popsize * batch <= budget:
        refs = reference(
            problem, dict(zip(names, map(jnp.asarray, es.mean), strict=True))
        )
        events, lfs = problem.batch(10_000 + gen, n=batch)
        xs = es.ask()
        fs = []
        for x in xs:
            raw = {n: jnp.asarray(v) for n, v in zip(names, x, strict=True)}
            f = float(loss(raw, events, lfs, refs)[0])
            fs.append(f if math.isfinite(f) else 1e6)
        es.tell(xs, fs)
        used += popsize * batch
        k = int(np.argmin(fs))
        if fs[k] < best_f:
            best_f, best_x = fs[k], xs[k]
        hist.append({"generation": gen, "best": float(min(fs)), "sims": used})
        print(f"  CMA-ES generation {gen}: best loss {min(fs):.4f}", file=sys.stderr)
        gen += 1
    # the distribution's mean is CMA-ES's estimate; keep the best sample as well
    return (
        {n: jnp.asarray(v) for n, v in zip(names, es.mean, strict=True)},
        {n: jnp.asarray(v) for n, v in zip(names, best_x, strict=True)},
        hist,
        used,
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=str(ROOT / "tuning/configs/kundur_pss.toml"))
    p.add_argument("--n", type=int, default=64, help="held-out scenarios")
    p.add_argument("--seed", type=int, default=2026, help="held-out seed")
    p.add_argument("--steps", type=int)
    p.add_argument("--batch", type=int)
    p.add_argument("--popsize", type=int, default=12)
    p.add_argument("--out", default=str(ROOT / "benchmarks/results"))
    args = p.parse_args(argv)

    cfg = load_grid_config(args.config)
    for k in ("steps", "batch"):
        if getattr(args, k) is not None:
            cfg[k] = getattr(args, k)
    check_grid_config(cfg)
    budget = int(cfg["steps"]) * int(cfg["batch"])

    rows, timing = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), cpu_seconds()
        problem, state = run_grid(cfg, Path(tmp), quiet=False)
        timing["gradient"] = {
            "wall_s": time.perf_counter() - t0,
            "cpu_s": cpu_seconds() - c0,
            "scenario_simulations": budget,
            "best_step": state.best.step,
        }
    space = problem.space
    raw0 = space.to_raw(space.start)
    held_cfg = {**cfg, "validation": {**cfg["validation"], "n": args.n}}
    held_problem = build_grid(held_cfg)
    held = held_problem.batch(0, n=args.n, seed=args.seed)
    val = _validation_fn(held_problem)

    t0, c0 = time.perf_counter(), cpu_seconds()
    cma_mean, cma_best, cma_hist, used = cma_tune(
        problem, budget, int(cfg["batch"]), args.popsize, int(cfg["seed"])
    )
    timing["cma_es"] = {
        "wall_s": time.perf_counter() - t0,
        "cpu_s": cpu_seconds() - c0,
        "scenario_simulations": used,
        "popsize": args.popsize,
        "generations": len(cma_hist),
    }

    sets = {
        "textbook PSS": raw0,
        "gradient (tuned)": state.best.raw,
        "CMA-ES (mean)": cma_mean,
        "CMA-ES (best sample)": cma_best,
    }
    for label, raw in sets.items():
        rows[label] = validate(held_problem, raw, val, held)
        print(f"{label}: {rows[label]}", file=sys.stderr)
    # no PSS: every stabilizer's gain 0 (its output is then identically 0); the
    # case's other values, nothing trained
    if any(n.startswith("IEEEST") for n in space.names):
        c0 = {
            **held_cfg,
            "case": {
                **cfg["case"],
                "set": {**cfg["case"]["set"], "IEEEST.KS": 0.0},
            },
            "gains": {
                "names": ["IEEEST.T1"],
                "per_device": False,
                "bounds": {},
                "transform": {},
                "tie": {},
            },
        }
        p0 = build_grid(c0)
        r0 = p0.space.to_raw(p0.space.start)
        rows["no PSS (KS = 0)"] = validate(p0, r0, _validation_fn(p0), held)
        print(f"no PSS: {rows['no PSS (KS = 0)']}", file=sys.stderr)

    keys = (
        "stable_fraction",
        "settling_mean",
        "settling_p95",
        "worst_damping",
        "worst_inter_area_damping",
        "worst_oscillatory_damping",
    )
    print(f"\n{problem.case.name}: held-out Monte Carlo of {args.n} scenarios")
    print(f"{'set':<22}" + "".join(f"{k:>27}" for k in keys))
    for label, r in rows.items():
        print(f"{label:<22}" + "".join(f"{r[k]:>27.4f}" for k in keys))
    for k, t in timing.items():
        print(f"{k}: {json.dumps(t)}")
    write_results(
        args.out,
        f"tuning_grid_{problem.case.name}",
        {
            "config": args.config,
            "n_held_out": args.n,
            "held_out_seed": args.seed,
            "steps": cfg["steps"],
            "batch": cfg["batch"],
        },
        {
            "rows": rows,
            "timing": timing,
            "cma_history": cma_hist,
            "gains": {
                label: {k: float(v) for k, v in space.values(raw).items()}
                for label, raw in sets.items()
            },
            "note": "wall times on a shared, loaded 2-core machine; cpu_s is this "
            "process's user+system CPU time",
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
