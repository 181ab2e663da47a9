"""Scenarios per second for 10 s fault scenarios, AFTSC (alpha = 5/7) and ASC
(alpha = 1), against batch size, on one core and on all cores (issue 6).

The headline rows ("montecarlo") run a Monte Carlo batch: scenarios 0..batch-1 of
`python -m smibjax montecarlo --seed SEED` (the default ScenarioDistribution, drawn by
`smibjax._scenarios.sample_scenarios`, exactly the rows the command computes). A second
kind of row ("identical", at batch >= 1024 only) runs the batch's first scenario in
every lane: no lane waits for a slower one, an upper bound that a Monte Carlo does not
reach. Gains beta1 = beta2 = -1, the default adaptive solver of `simulate` (Tsit5, rtol
1e-6, atol 1e-8). The batch is one
jit(vmap(simulate + metrics)) call per host device (`smibjax._parallel.device_map`),
returning the stable flag, the settling time and the step count; the time is the best
of --repeat calls after a warm-up (compiling) call. The accuracy of delta is checked
on the first --n-check scenarios against a tight-tolerance run (rtol 1e-10, atol
1e-12). Prints a table against the targets (at batch >= 1024 on 2+ devices: AFTSC >=
600, ASC >= 1800 scenarios/s; delta within 1e-5 rad) and writes
benchmarks/results/throughput.json and throughput.png.

    python benchmarks/throughput.py [--batches 1 16 256 1024 4096] [--devices 1 2]
        [--rtol 1e-6] [--atol 1e-8]
"""

from __future__ import annotations

import sys
from pathlib import Path

from smibjax import configure

# As an entry point: one host device per core (at least two), float64, equinox's
# checks as NaNs, before JAX loads (the cache: _common.enable_cache).
configure(min_devices=2, cache=False)
sys.path.insert(0, str(Path(__file__).resolve().parent))

import argparse

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _common import (
    ALPHA,
    CONTROLLERS,
    DEFAULT_OUT,
    REFERENCE,
    add_tolerance_args,
    batched_metrics,
    deltas,
    enable_cache,
    gains,
    host_devices,
    montecarlo_faults,
    result_name,
    solver_of,
    status,
    take,
    timed,
)
from _results import write_results

from smibjax.cli.plotting import save_figure

TARGET = {"aftsc": 600.0, "asc": 1800.0}  # scenarios/s, batch >= 1024, 2+ devices
TARGET_BATCH, TARGET_DEVICES, TARGET_DELTA = 1024, 2, 1e-5


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 16, 256, 1024, 4096])
    ap.add_argument(
        "--devices",
        type=int,
        nargs="+",
        default=[1, 2],
        help="host device counts to run on (1 = one core)",
    )
    ap.add_argument(
        "--controllers", nargs="+", choices=CONTROLLERS, default=CONTROLLERS
    )
    ap.add_argument("--repeat", type=int, default=2, help="timed calls (best kept)")
    ap.add_argument(
        "--n-check", type=int, default=4, help="scenarios checked for accuracy"
    )
    ap.add_argument("--t-end", type=float, default=10.0, help="scenario length (s)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--kinds",
        nargs="+",
        choices=["montecarlo", "identical"],
        default=["montecarlo", "identical"],
        help="montecarlo: the Monte Carlo's own scenarios (the headline); identical: "
        "its first scenario in every lane (batch >= 1024 only)",
    )
    add_tolerance_args(ap)
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    return ap.parse_args(argv)


def main(argv=None) -> None:
    args = parse_args(argv)
    cache = enable_cache()
    pool = montecarlo_faults(args.seed, max(max(args.batches), args.n_check))
    rows, accuracy = [], {}
    for ctrl in args.controllers:
        g = gains(ctrl)
        fn = batched_metrics(args.t_end, solver_of(args))
        if args.n_check > 0:
            err = np.abs(
                deltas(g, pool, args.n_check, args.t_end, solver_of(args))[0]
                - deltas(g, pool, args.n_check, args.t_end, REFERENCE)[0]
            )
            accuracy[ctrl] = {
                "n": args.n_check,
                "max_abs_delta_error_rad": float(err.max()),
                "per_scenario": [float(e) for e in err.max(axis=1)],
            }
        for ndev in args.devices:
            devs = host_devices(ndev)
            for kind, batch in [
                (k, b)
                for b in args.batches
                for k in args.kinds
                if k == "montecarlo" or b >= TARGET_BATCH
            ]:
                faults = take(pool, batch)
                if kind == "identical":
                    faults = jax.tree_util.tree_map(
                        lambda a, batch=batch: jnp.repeat(a[:1], batch), faults
                    )

                def call(g=g, faults=faults, devs=devs, fn=fn):
                    return jax.block_until_ready(fn(g, faults, devs))

                first, best, (stable, settling, steps) = timed(call, args.repeat)
                steps = np.asarray(steps)
                rate = batch / best
                r = {
                    "kind": kind,
                    "controller": ctrl,
                    "devices": ndev,
                    "batch": batch,
                    "scenarios_per_s": rate,
                    "seconds": best,
                    "first_call_s": first,
                    "mean_steps": float(steps.mean()),
                    "max_steps": int(steps.max()),
                    "us_per_scenario_step": 1e6 * best / (steps.max() * batch),
                    "stable_fraction": float(np.mean(np.asarray(stable))),
                    "mean_settling_s": float(
                        np.mean(np.asarray(settling)[np.asarray(stable)])
                    )
                    if np.any(np.asarray(stable))
                    else None,
                }
                judged = (
                    batch >= TARGET_BATCH
                    and ndev >= TARGET_DEVICES
                    and kind == "montecarlo"
                )
                r["target_scenarios_per_s"] = TARGET[ctrl] if judged else None
                r["status"] = status(rate, TARGET[ctrl]) if judged else "-"
                rows.append(r)
                print(
                    f"  {ctrl} {kind} devices={ndev} batch={batch}: {rate:.1f} scen/s "
                    f"(first call {first:.1f} s)",
                    flush=True,
                )

    print()
    print(
        f"{'controller':10} {'kind':>10} {'dev':>3} {'batch':>6} {'scen/s':>9} {'target':>7} "
        f"{'status':>7} {'mean st':>8} {'max st':>7} {'us/sc-st':>8} {'stable':>6}"
    )
    for r in rows:
        tgt = r["target_scenarios_per_s"]
        print(
            f"{r['controller']:10} {r['kind']:>10} {r['devices']:3d} {r['batch']:6d} "
            f"{r['scenarios_per_s']:9.1f} {'' if tgt is None else f'{tgt:.0f}':>7} "
            f"{r['status']:>7} {r['mean_steps']:8.0f} {r['max_steps']:7d} "
            f"{r['us_per_scenario_step']:8.3f} {r['stable_fraction']:6.2f}"
        )
    for ctrl, a in accuracy.items():
        e = a["max_abs_delta_error_rad"]
        a["status"] = status(e, TARGET_DELTA, higher_is_better=False)
        print(
            f"{ctrl}: max |delta - tight reference| over {a['n']} scenarios = "
            f"{e:.2e} rad (target <= {TARGET_DELTA:g}: {a['status']})"
        )

    config = {
        "scenario_s": args.t_end,
        "faults": f"montecarlo: sample_scenarios({args.seed}, 0, n, "
        "ScenarioDistribution(), Plant()) (rows 0..n-1 of `montecarlo --seed "
        f"{args.seed}`); identical: its first scenario in every lane",
        "kinds": args.kinds,
        "gains": "Gains.paper(controller, beta1=-1, beta2=-1)",
        "solver": f"adaptive Tsit5, rtol {args.rtol:g}, atol {args.atol:g} "
        "(simulate's defaults: 1e-6, 1e-8)",
        "rtol": args.rtol,
        "atol": args.atol,
        "batches": args.batches,
        "devices": args.devices,
        "host_devices": len(jax.devices()),
        "repeat": args.repeat,
        "timing": "best of repeat calls after a warm-up call, wall time of "
        "device_map(jit(vmap(simulate + metrics)))",
        "us_per_scenario_step": "seconds / (max steps * batch) * 1e6",
        "reference": "simulate(rtol=1e-10, atol=1e-12), first n_check scenarios",
        "n_check": args.n_check,
        "targets": {
            "scenarios_per_s": TARGET,
            "at": f"batch >= {TARGET_BATCH}, devices >= {TARGET_DEVICES}",
            "max_abs_delta_error_rad": TARGET_DELTA,
        },
        "persistent_cache": cache,
    }
    name = result_name("throughput", args.tag)
    path = write_results(args.out, name, config, {"rows": rows, "accuracy": accuracy})

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for ctrl in args.controllers:
        for ndev in args.devices:
            rr = [
                r
                for r in rows
                if r["controller"] == ctrl
                and r["devices"] == ndev
                and r["kind"] == "montecarlo"
            ]
            ax.plot(
                [r["batch"] for r in rr],
                [r["scenarios_per_s"] for r in rr],
                marker="o" if ndev > 1 else "s",
                mfc=None if ndev > 1 else "none",
                ls="-" if ndev > 1 else "--",
                color="C0" if ctrl == "aftsc" else "C1",
                label=f"{ctrl.upper()} (alpha = {ALPHA[ctrl]}), {ndev} core"
                + ("s" if ndev > 1 else ""),
            )
        ax.axhline(
            TARGET[ctrl],
            color="C0" if ctrl == "aftsc" else "C1",
            ls=":",
            lw=1,
            label=f"{ctrl.upper()} target",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("batch size (scenarios)")
    ax.set_ylabel("scenarios / s")
    ax.set_title(
        f"{args.t_end:g} s scenarios, adaptive Tsit5 rtol {args.rtol:g}, "
        f"atol {args.atol:g}"
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, Path(args.out) / f"{name}.png")
    print(f"wrote {path} and {name}.png")


if __name__ == "__main__":
    main()
