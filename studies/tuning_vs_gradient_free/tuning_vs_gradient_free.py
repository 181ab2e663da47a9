"""Gradient (Adam through the differentiable simulator, the default tuning run) against
gradient-free tuning (CMA-ES from pycma as the tuner's [search] stage runs it, SciPy's
Nelder-Mead) of the default problem (realistic limits, realizable adaptation,
projection, D drawn), from the paper's gains, with the same budget of scenario
simulations; every result scored on the same validation set with the exact metrics.

- Adam: `tuning.optimize.run` on the default config with `steps = budget / batch`
  (fresh batches, limit continuation, model selection on validation as in the tuner:
  the validation simulations are not counted, as for the others' final scoring);
- CMA-ES, Nelder-Mead: minimize the exact score of a fixed batch of
  `--search-batch` scenarios (mean delta settling, 20 s for an unstable run), one
  candidate = `--search-batch` simulations, until the budget is spent.

Prints a table, writes tuning_vs_gradient_free.json and .png beside this script.

    python studies/tuning_vs_gradient_free/tuning_vs_gradient_free.py \
        [--budget 3840] [--search-batch 24]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))  # the tuning package
sys.path.insert(0, str(ROOT / "benchmarks"))  # _results

from smibjax._process import configure, enable_compilation_cache

configure(cache=False)  # one host device per core, before JAX starts its CPU backend

import jax
import matplotlib
import numpy as np
from scipy.optimize import minimize

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _results import write_results

from smibjax.cli.plotting import save_figure
from tuning.config import load_config
from tuning.loop import run
from tuning.problem import build
from tuning.search import cma_search, make_population_score
from tuning.train import draw_scenarios, make_validate, summarize


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=int, default=3840, help="scenario simulations")
    ap.add_argument("--batch", type=int, default=32, help="Adam's batch")
    ap.add_argument("--search-batch", type=int, default=24)
    ap.add_argument("--population", type=int, default=24)
    ap.add_argument("--validation", type=int, default=256)
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args(argv)
    enable_compilation_cache()
    cfg = load_config()
    cfg["steps"] = max(1, args.budget // args.batch)
    cfg["batch"] = args.batch
    cfg["validation"]["n"] = args.validation
    cfg["validation"]["every"] = max(1, cfg["steps"] // 4)
    init, space, setup, dist, _ = build(cfg)
    raw0 = space.to_raw(init)
    names = list(raw0)
    val = draw_scenarios(
        jax.random.PRNGKey(int(cfg["validation"]["seed"])),
        args.validation,
        dist,
        setup.plant,
    )
    validate = make_validate(setup)
    results, curves = {}, {}

    def score_final(raw):
        return summarize(
            jax.tree_util.tree_map(np.asarray, validate(space.to_gains(raw), val))
        )

    # --- Adam: the default tuning run itself
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        state = run(cfg, Path(tmp), quiet=True)
    results["adam (default run)"] = {
        "simulations": cfg["steps"] * args.batch,
        "wall_s": time.perf_counter() - t0,
        **score_final(state.best.raw),
    }
    curves["adam (default run)"] = [
        (r["step"] * args.batch, r["loss"]) for r in state.history
    ]

    # --- gradient-free on the exact score of a fixed batch
    score = make_population_score(setup, unstable_cost=20.0)
    faults = draw_scenarios(
        jax.random.PRNGKey(42), args.search_batch, dist, setup.plant
    )
    n_cand = args.budget // args.search_batch

    def to_raw(x):
        return {k: jax.numpy.asarray(v) for k, v in zip(names, x, strict=True)}

    x0 = np.array([float(raw0[k]) for k in names])

    # CMA-ES (pycma) as the tuner's [search] stage runs it (tuning/search.py)
    t0 = time.perf_counter()
    gens = max(1, n_cand // args.population)
    raw_cma, hist = cma_search(
        space,
        raw0,
        score,
        faults,
        generations=gens,
        population=args.population,
        sigma=0.7,
        seed=7,
    )
    results["cma-es (pycma)"] = {
        "simulations": len(hist) * args.population * args.search_batch,
        "wall_s": time.perf_counter() - t0,
        **score_final(raw_cma),
    }
    curves["cma-es (pycma)"] = [
        (r["generation"] * args.population * args.search_batch, r["best_score"])
        for r in hist
    ]

    # Nelder-Mead (SciPy), one candidate at a time
    t0, curve, count = time.perf_counter(), [], [0]
    best_nm = [np.inf, x0]

    def objective(x):
        c = float(score([space.to_gains(to_raw(x))], faults)[0][0])
        count[0] += 1
        if c < best_nm[0]:
            best_nm[:] = [c, np.array(x)]
        curve.append((count[0] * args.search_batch, best_nm[0]))
        return c

    minimize(
        objective,
        x0,
        method="Nelder-Mead",
        options={
            "maxfev": n_cand,
            "initial_simplex": x0
            + 0.7 * np.vstack([np.zeros(len(x0)), np.eye(len(x0))]),
        },
    )
    results["nelder-mead (scipy)"] = {
        "simulations": count[0] * args.search_batch,
        "wall_s": time.perf_counter() - t0,
        **score_final(to_raw(best_nm[1])),
    }
    curves["nelder-mead (scipy)"] = curve

    cols = (
        "stable_fraction",
        "settling_delta_mean",
        "settling_delta_p95",
        "tv_uf_mean",
    )
    print(
        f"{'method':22} {'sims':>6} {'wall s':>7} " + " ".join(f"{c:>20}" for c in cols)
    )
    for k, r in results.items():
        print(
            f"{k:22} {r['simulations']:6d} {r['wall_s']:7.0f} "
            + " ".join(f"{r[c]:20.3f}" for c in cols)
        )
    write_results(
        args.out,
        "tuning_vs_gradient_free",
        {
            "budget_simulations": args.budget,
            "adam_batch": args.batch,
            "search_batch": args.search_batch,
            "population": args.population,
            "validation": args.validation,
        },
        {"rows": results, "curves": curves},
    )
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for k, c in curves.items():
        target = ax[0] if k.startswith("adam") else ax[1]
        target.plot([a for a, _ in c], [b for _, b in c], label=k)
    ax[0].set_ylabel("Adam: training loss (continuation, fresh batches)")
    ax[1].set_ylabel("best exact score so far (s)")
    for a in ax:
        a.set_xlabel("scenario simulations")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("Tuning from the paper's gains at equal simulation budget")
    fig.tight_layout()
    save_figure(fig, Path(args.out) / "tuning_vs_gradient_free.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
