"""Coordinated PSS tuning on a multi-machine case, baselines side by side (issue 30):
the case's textbook stabilizers, no stabilizers (KS = 0), the gradient tuner
(`python -m tuning.optimize` with the same config), CMA-ES (pycma) on the same loss
at an equal simulation budget (the gradient run's training scenarios: steps x batch;
CMA-ES evaluates the loss without gradients on batches of the same distribution), and
single-scenario, fixed-step gradient tuning in the style of the prior art (DiffPSSi):
the report's one fault at load factor 1, explicit Euler at `--single-dt` s, the
time-domain loss only (no modal term), one Adam step per simulation for the same
budget, its last parameters kept.

Every set is judged on one held-out Monte Carlo (`--n` scenarios of the config's
fault distribution and load range, a seed that neither tuner saw): stable fraction,
mean and p95 settling (COI angles and COI-referred speeds, as in the tuner's
validation), worst damping ratio of the electromechanical modes, of the inter-area
mode and of every oscillatory mode of 0.05-5 Hz over the config's
`validation.load_factors`, and the critical clearing time (s, `smibjax.grid.cct`:
bolted bus fault at 0.5 s, no tripping, 5 s horizon, bisection to 5 ms in [0, 1] s)
at three fault buses at load factor 1 (`--cct-buses`; default the first, middle and
last of `scenarios.buses`). Prints a table and writes
benchmarks/results/tuning_grid_<case>.json and tuning_grid_<case>.png.

    python benchmarks/tuning_grid.py [--config tuning/configs/kundur_pss.toml]
        [--n 64] [--seed 2026] [--steps N] [--batch B] [--popsize P]
        [--cct-buses 5,8,11] [--single-dt 0.01] [--reuse RESULT.json]

`--reuse` takes the gradient and CMA-ES gains (and their timings) from an earlier
result of the same config, steps and batch instead of tuning again (the held-out
numbers are recomputed).

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

import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _results import write_results  # noqa: E402

from tuning.grid_config import check_grid_config, load_grid_config  # noqa: E402
from tuning.grid_problem import (  # noqa: E402
    GridProblem,
    build_grid,
    make_loss,
    make_step,
    reference,
    reference_fault,
)
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


class FixedStepProblem(GridProblem):
    """A `GridProblem` whose runs use explicit Euler at a constant step (s)."""

    fixed_dt: float = eqx.field(static=True, default=0.01)

    def options(self, t_end):
        return {**GridProblem.options(self, t_end), "fixed_dt": self.fixed_dt}


def single_scenario_tune(cfg: dict, budget: int, dt: float):
    """Gradient tuning in the style of the prior art: one fault (the report's, at
    `report.load_factor`), explicit Euler at `dt` s, the time-domain loss terms only
    (damping weight 0), `budget` clipped Adam steps of one simulation each, the last
    parameters kept. Returns (raw, history, fault description)."""
    scfg = {
        **cfg,
        "batch": 1,
        "loss": {**cfg["loss"], "damping": 0.0, "damping_load_factors": [1.0]},
    }
    base = build_grid(scfg)
    problem = FixedStepProblem(
        cfg=base.cfg,
        case=base.case,
        space=base.space,
        dist=base.dist,
        opt=base.opt,
        fixed_dt=float(dt),
    )
    bus, events = reference_fault(problem.case, cfg["report"], problem.dist)
    events = jax.tree_util.tree_map(lambda x: jnp.asarray(x)[None], events)
    lfs = jnp.asarray([float(cfg["report"]["load_factor"])])
    step, _ = make_step(problem)
    raw = problem.space.to_raw(problem.space.start)
    refs = reference(problem, raw)
    opt_state = problem.opt.init(raw)
    hist = []
    for k in range(budget):
        raw, opt_state, val, info, gn, skipped = step(raw, opt_state, events, lfs, refs)
        hist.append({"step": k, "loss": float(val), "skipped": bool(skipped)})
        if k % 20 == 0 or k == budget - 1:
            print(f"  single-scenario step {k}: loss {float(val):.4f}", file=sys.stderr)
    fault = {
        "bus": bus,
        "t_fault": 0.5,
        "clear_after": float(cfg["report"]["clear_after"]),
        "load_factor": float(cfg["report"]["load_factor"]),
        "fixed_dt": float(dt),
        "solver": "explicit Euler",
    }
    return raw, hist, fault


def cct_of(problem, raw, buses) -> dict:
    """{bus: CCT (s) or None (stable at 1 s)} of the parameters `raw` at load
    factor 1 (`critical_clearing_times_grid`'s defaults)."""
    from smibjax.grid.cct import critical_clearing_times_grid
    from smibjax.grid.operating import operating_point

    case = problem.case_at(raw)
    op, _ = operating_point(case, load_factor=1.0, gen_factor=1.0)
    res = critical_clearing_times_grid(case, op, buses)
    return {str(b): v for b, v in res["cct"].items()}


def _rel(path) -> str:
    """`path` relative to the repository when inside it."""
    p = Path(path).resolve()
    return str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(path)


def _raw_of(space, values: dict) -> dict:
    return space.to_raw([float(values[n]) for n in space.names])


def plot(path, case_name: str, rows: dict, buses) -> None:
    """Bars per set: mean settling (s), worst damping ratio, CCT per bus (s)."""
    from smibjax._figures import save_figure, subplots

    labels = list(rows)
    x = np.arange(len(labels))
    fig, ax = subplots(1, 3, figsize=(14, 4.2))
    settle = [r["settling_mean"] for r in rows.values()]
    ax[0].bar(x, [s if math.isfinite(s) else 0.0 for s in settle])
    for k, s in enumerate(settle):
        if not math.isfinite(s):
            ax[0].text(k, 0.1, "never", ha="center", rotation=90)
    ax[0].set_ylabel("mean settling on held-out faults (s)")
    ax[1].bar(x, [r["worst_damping"] for r in rows.values()])
    ax[1].axhline(0.0, color="k", lw=0.5)
    ax[1].set_ylabel("worst electromechanical damping ratio")
    w = 0.8 / max(len(buses), 1)
    for j, b in enumerate(buses):
        v = [r["cct"][str(b)] for r in rows.values()]
        ax[2].bar(x + (j - (len(buses) - 1) / 2) * w, [c or 1.0 for c in v], w)
    ax[2].legend([f"bus {b}" for b in buses], fontsize=7)
    ax[2].set_ylabel("CCT at load factor 1 (s; 1 = stable at 1 s)")
    for a in ax:
        a.set_xticks(x)
        a.set_xticklabels(labels, rotation=30, ha="right", fontsize=7)
    fig.suptitle(f"{case_name}: tuned stabilizers vs baselines")
    fig.tight_layout()
    save_figure(fig, path)


# the held-out table's columns (synergy_grid.py adds the field-voltage peak)
KEYS = (
    "stable_fraction",
    "settling_mean",
    "settling_p95",
    "worst_damping",
    "worst_inter_area_damping",
    "worst_oscillatory_damping",
)


def _cct_text(c) -> str:
    """A CCT cell: s to the ms, '> 1' for a stable 1 s fault (None), '-' as given."""
    return "> 1" if c is None else (c if c == "-" else f"{c:.3f}")


def print_table(title: str, rows: dict, keys, buses, width: int = 28) -> None:
    """The held-out table: one row per set, the `keys` columns, then the CCT at each
    of `buses` ('-' where a set has none)."""
    print(f"\n{title}")
    print(
        f"{'set':<{width}}"
        + "".join(f"{k:>27}" for k in keys)
        + "".join(f"{'CCT bus ' + str(b):>14}" for b in buses)
    )
    for label, r in rows.items():
        cct = [r.get("cct", {}).get(str(b), "-") for b in buses]
        print(
            f"{label:<{width}}"
            + "".join(f"{r[k]:>27.4f}" for k in keys)
            + "".join(f"{_cct_text(c):>14}" for c in cct)
        )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=str(ROOT / "tuning/configs/kundur_pss.toml"))
    p.add_argument("--n", type=int, default=64, help="held-out scenarios")
    p.add_argument("--seed", type=int, default=2026, help="held-out seed")
    p.add_argument("--steps", type=int)
    p.add_argument("--batch", type=int)
    p.add_argument("--popsize", type=int, default=12)
    p.add_argument("--cct-buses", help="three fault buses, e.g. 5,8,11")
    p.add_argument(
        "--single-dt", type=float, default=0.01, help="Euler step (s), single-scenario"
    )
    p.add_argument("--reuse", help="earlier result JSON: its tuned gains, timings")
    p.add_argument("--out", default=str(ROOT / "benchmarks/results"))
    args = p.parse_args(argv)

    cfg = load_grid_config(args.config)
    for k in ("steps", "batch"):
        if getattr(args, k) is not None:
            cfg[k] = getattr(args, k)
    check_grid_config(cfg)
    budget = int(cfg["steps"]) * int(cfg["batch"])
    if args.cct_buses:
        buses = [int(b) for b in args.cct_buses.split(",")]
    else:
        sb = list(cfg["scenarios"]["buses"])
        buses = sorted({sb[0], sb[len(sb) // 2], sb[-1]}) if sb else []
    reuse = json.loads(Path(args.reuse).read_text()) if args.reuse else None
    if reuse and (
        reuse["config"]["steps"] != cfg["steps"]
        or reuse["config"]["batch"] != cfg["batch"]
    ):
        print(
            f"--reuse {args.reuse}: its steps x batch "
            f"({reuse['config']['steps']} x {reuse['config']['batch']}) differ from "
            f"this run's ({cfg['steps']} x {cfg['batch']})",
            file=sys.stderr,
        )
        return 2

    rows, timing = {}, {}
    if reuse:
        problem = build_grid(cfg)
        space = problem.space
        grad_raw = _raw_of(space, reuse["gains"]["gradient (tuned)"])
        cma_mean = _raw_of(space, reuse["gains"]["CMA-ES (mean)"])
        cma_best = _raw_of(space, reuse["gains"]["CMA-ES (best sample)"])
        cma_hist = reuse["cma_history"]
        timing.update(reuse["timing"])
        timing["gradient"]["reused_from"] = str(args.reuse)
        timing["cma_es"]["reused_from"] = str(args.reuse)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            t0, c0 = time.perf_counter(), cpu_seconds()
            problem, state = run_grid(cfg, Path(tmp), quiet=False)
            timing["gradient"] = {
                "wall_s": time.perf_counter() - t0,
                "cpu_s": cpu_seconds() - c0,
                "scenario_simulations": budget,
                "best_step": state.best.step,
            }
        grad_raw = state.best.raw
        space = problem.space
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

    t0, c0 = time.perf_counter(), cpu_seconds()
    single_raw, single_hist, single_fault = single_scenario_tune(
        cfg, budget, args.single_dt
    )
    timing["single_scenario"] = {
        "wall_s": time.perf_counter() - t0,
        "cpu_s": cpu_seconds() - c0,
        "scenario_simulations": budget,
        **single_fault,
    }

    raw0 = space.to_raw(space.start)
    held_cfg = {**cfg, "validation": {**cfg["validation"], "n": args.n}}
    held_problem = build_grid(held_cfg)
    held = held_problem.batch(0, n=args.n, seed=args.seed)
    val = _validation_fn(held_problem)

    sets = {
        "textbook PSS": raw0,
        "gradient (tuned)": grad_raw,
        "CMA-ES (mean)": cma_mean,
        "CMA-ES (best sample)": cma_best,
        "single-scenario fixed-step": single_raw,
    }
    t0, c0 = time.perf_counter(), cpu_seconds()
    for label, raw in sets.items():
        rows[label] = validate(held_problem, raw, val, held)
        rows[label]["cct"] = cct_of(held_problem, raw, buses)
        print(f"{label}: {rows[label]}", file=sys.stderr)
    # no PSS: every stabilizer's gain 0 (its output is then identically 0); the
    # case's other values, nothing trained
    if any(n.startswith("IEEEST") for n in space.names):
        c0_cfg = {
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
        p0 = build_grid(c0_cfg)
        r0 = p0.space.to_raw(p0.space.start)
        rows["no PSS (KS = 0)"] = validate(p0, r0, _validation_fn(p0), held)
        rows["no PSS (KS = 0)"]["cct"] = cct_of(p0, r0, buses)
        print(f"no PSS: {rows['no PSS (KS = 0)']}", file=sys.stderr)
    timing["judging"] = {
        "wall_s": time.perf_counter() - t0,
        "cpu_s": cpu_seconds() - c0,
    }

    print_table(
        f"{problem.case.name}: held-out Monte Carlo of {args.n} scenarios",
        rows,
        KEYS,
        buses,
    )
    for k, t in timing.items():
        print(f"{k}: {json.dumps(t)}")
    name = f"tuning_grid_{problem.case.name}"
    write_results(
        args.out,
        name,
        {
            "config": _rel(args.config),
            "n_held_out": args.n,
            "held_out_seed": args.seed,
            "steps": cfg["steps"],
            "batch": cfg["batch"],
            "popsize": args.popsize,
            "cct_buses": buses,
            "single_dt": args.single_dt,
        },
        {
            "rows": rows,
            "timing": timing,
            "cma_history": cma_hist,
            "single_scenario_history": single_hist,
            "gains": {
                label: {k: float(v) for k, v in space.values(raw).items()}
                for label, raw in sets.items()
            },
            "note": "wall times on a shared, loaded 2-core machine; cpu_s is this "
            "process's user+system CPU time; cct: s at load factor 1, null = stable "
            "with a 1 s fault",
        },
    )
    plot(Path(args.out) / f"{name}.png", problem.case.name, rows, buses)
    return 0


if __name__ == "__main__":
    sys.exit(main())
