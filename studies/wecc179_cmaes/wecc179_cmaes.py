"""WECC 179's 29 stabilizers: the gradient tuner against CMA-ES at the same budget.

    python studies/wecc179_cmaes/wecc179_cmaes.py --gains runs/wecc179/gains.json

The gradient set is the result of `python -m tuning.optimize --config
tuning/configs/wecc179_pss.toml --out runs/wecc179` (`--gains`: its gains.json; its
budget, the count of modal evaluations, is the config's `steps`). CMA-ES (pycma) runs
on the same loss (the config's modal term: the squared hinge below zeta = 0.12 over
the electromechanical modes at load factors 0.9, 1.0, 1.1, mean over the load
factors), the same raw parameters (the tuner's transforms) and bounds, without
gradients, for the same count of loss evaluations (`--evals`, default `steps`) and,
with `--evals-cpu`, for more. The reference modes are refreshed from the mean at every
generation, as in `benchmarks/tuning_grid.py`. Every set is judged on the modes at the
three load factors and on `--n` held-out faults (seed `--seed`, none of the tuners
saw them; 20 s runs): stable fraction and settling. Results: `wecc179_cmaes.json`
beside this script.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tuning.grid_config import check_grid_config, load_grid_config  # noqa: E402
from tuning.grid_problem import build_grid, damping_term, reference  # noqa: E402
from tuning.grid_run import _validation_fn, validate  # noqa: E402


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def cma_tune(problem, evals: int, popsize: int, seed: int, sigma: float):
    """CMA-ES on the raw parameters within the raw bounds, `evals` evaluations of
    the modal loss; returns (mean raw, best raw, history)."""
    import cma

    space = problem.space
    names = space.names
    x0 = np.array([float(v) for v in space.to_raw(space.start).values()])
    lo, hi = space.raw_bounds()
    w = float(problem.cfg["loss"]["damping"])
    f_jit = jax.jit(lambda raw, refs: w * damping_term(problem, raw, refs)[0])
    es = cma.CMAEvolutionStrategy(
        x0,
        sigma,
        {
            "popsize": popsize,
            "bounds": [list(lo), list(hi)],
            "seed": seed + 1,
            "verbose": -9,
        },
    )
    used, gen, hist = 0, 0, []
    best_x, best_f = x0, math.inf
    while used + popsize <= evals:
        refs = reference(
            problem, dict(zip(names, map(jnp.asarray, es.mean), strict=True))
        )
        xs = es.ask()
        fs = []
        for x in xs:
            raw = {n: jnp.asarray(v) for n, v in zip(names, x, strict=True)}
            f = float(f_jit(raw, refs))
            fs.append(f if math.isfinite(f) else 1e6)
        es.tell(xs, fs)
        used += popsize
        k = int(np.argmin(fs))
        if fs[k] < best_f:
            best_f, best_x = fs[k], xs[k]
        hist.append({"generation": gen, "best": float(min(fs)), "evals": used})
        print(
            f"  CMA-ES generation {gen}: best loss {min(fs):.4f} ({used} evals)",
            file=sys.stderr,
            flush=True,
        )
        gen += 1
    as_raw = lambda x: {n: jnp.asarray(v) for n, v in zip(names, x, strict=True)}  # noqa: E731
    return as_raw(es.mean), as_raw(best_x), hist, used


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "tuning/configs/wecc179_pss.toml"))
    ap.add_argument("--gains", default="", help="the gradient run's gains.json")
    ap.add_argument(
        "--reuse",
        default="",
        help="an earlier JSON of this script: its sets and rows are kept (no CMA-ES "
        "run); only the sets it lacks are judged",
    )
    ap.add_argument("--evals", type=int, default=0, help="0: the config's steps")
    ap.add_argument("--evals-cpu", type=int, default=0, help="a second, larger budget")
    ap.add_argument("--popsize", type=int, default=8)
    ap.add_argument("--sigma", type=float, default=0.2)
    ap.add_argument("--n", type=int, default=16, help="held-out faults (0: modes only)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--out", default=str(Path(__file__).with_suffix(".json")))
    args = ap.parse_args(argv)

    cfg = load_grid_config(args.config)
    cfg["validation"]["n"] = max(args.n, 1)
    cfg["validation"]["seed"] = args.seed
    check_grid_config(cfg)
    problem = build_grid(cfg)
    space = problem.space
    evals = args.evals or int(cfg["steps"])
    sets = {"shipped": space.to_raw(space.start)}
    if args.gains:
        gains = json.loads(Path(args.gains).read_text())
        sets["gradient"] = space.to_raw([float(gains[n]) for n in space.names])
    timing, rows = {}, {}
    if args.reuse:
        old = json.loads(Path(args.reuse).read_text())
        timing = old["timing"]
        rows = old["sets"]
        for label, vals in old["values"].items():
            if label not in sets:
                sets[label] = space.to_raw([float(vals[n]) for n in space.names])
    for label, budget in (("", evals), (" (larger budget)", args.evals_cpu)):
        if not budget or args.reuse:
            continue
        t0, c0 = time.perf_counter(), cpu_seconds()
        mean, best, hist, used = cma_tune(
            problem, budget, args.popsize, args.seed, args.sigma
        )
        timing[f"CMA-ES{label}"] = {
            "evals": used,
            "wall_s": time.perf_counter() - t0,
            "cpu_s": cpu_seconds() - c0,
            "history": hist,
        }
        sets[f"CMA-ES mean{label}"] = mean
        sets[f"CMA-ES best sample{label}"] = best
    from tuning.grid_run import _held_out, _modes_at

    run_fn = _validation_fn(problem) if args.n else None
    held = _held_out(problem) if args.n else None
    for label, raw in sets.items():
        if label in rows:
            continue
        t0 = time.perf_counter()
        v = validate(problem, raw, run_fn, held) if args.n else {}
        modes = _modes_at(problem, raw, cfg["validation"]["load_factors"])
        v["worst_damping_per_load_factor"] = {
            str(m["load_factor"]): min(d["damping"] for d in m["modes"]) for m in modes
        }
        v["modes_below_0.10"] = sum(
            d["damping"] < 0.10 for m in modes for d in m["modes"]
        )
        v["judge_wall_s"] = time.perf_counter() - t0
        rows[label] = v
        print(
            f"{label:32s} stable {v.get('stable_fraction', math.nan):.3f}  settling "
            f"mean {v.get('settling_mean', math.nan):.3f} s  worst EM damping "
            + " / ".join(
                f"{z:.4f}" for z in v["worst_damping_per_load_factor"].values()
            )
            + f"  modes < 0.10: {v['modes_below_0.10']}",
            flush=True,
        )
    out = {
        "config": str(Path(args.config).resolve().relative_to(ROOT)),
        "gains": args.gains or None,
        "gradient_evals": int(cfg["steps"]),
        "held_out": {
            "n": args.n,
            "seed": args.seed,
            "t_end": cfg["validation"]["t_end"],
        },
        "timing": timing,
        "sets": rows,
        "values": {
            label: {k: float(x) for k, x in space.values(raw).items()}
            for label, raw in sets.items()
        },
    }
    Path(args.out).write_text(json.dumps(out, indent=1, default=float) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
