"""smibjax against a plain per-scenario scipy.integrate.solve_ivp loop (LSODA and
Radau) on the same 10 s fault scenarios at the same tolerances (issue 6).

The SciPy side is the independent NumPy implementation of the model in
tests/reference.py (its right-hand side and network stages), integrated the way a user
would write it: one solve_ivp per network stage, sampled on the same 10 ms grid, one
scenario after another. The smibjax side is the throughput benchmark's batch call
(jit(vmap(simulate + metrics)) over --devices host devices) at batch --batch. Both at
rtol 1e-6, atol 1e-8 (simulate's defaults; --rtol/--atol set both; --smibjax-rtol/
--smibjax-atol set smibjax's alone, for a comparison at equal accuracy: the agreement
columns then say whether smibjax at its looser tolerance is still at least as close
to the reference as SciPy at its own). The agreement
is measured on the scenarios both ran: max |delta| difference between SciPy and
smibjax, and each against a tight-tolerance reference (smibjax at rtol 1e-10,
atol 1e-12, or --reference scipy: DOP853 at that tolerance). Targets: smibjax at
least 300x the SciPy loop's scenarios/s for AFTSC and 150x for ASC (against the
faster SciPy method). Prints a table and writes benchmarks/results/vs_scipy.json and
vs_scipy.png (vs_scipy_TAG.* with --tag).

    python benchmarks/vs_scipy.py [--n-scipy 8] [--batch 1024] [--devices 2]
        [--rtol 1e-6] [--atol 1e-8] [--smibjax-rtol R --smibjax-atol A] [--tag NAME]
"""

from __future__ import annotations

import sys
from pathlib import Path

from smibjax import configure

# As an entry point: one host device per core (at least two), float64, equinox's
# checks as NaNs, before JAX loads (the cache: _common.enable_cache).
configure(min_devices=2, cache=False)
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # reference.py, the SciPy model

import argparse
import math
import time

import jax
import matplotlib
import numpy as np
from scipy.integrate import solve_ivp

import reference

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _common import (
    ALPHA,
    CONTROLLERS,
    DEFAULT_OUT,
    REF_ATOL,
    REF_RTOL,
    REFERENCE,
    add_tolerance_args,
    batched_metrics,
    deltas,
    enable_cache,
    gains,
    host_devices,
    result_name,
    row,
    scenarios,
    status,
    take,
    timed,
)
from _results import write_results

import smibjax as sj
from smibjax._closed_loop import DELTA_MARGIN
from smibjax.cli.plotting import save_figure

TARGET_RATIO = {"aftsc": 300.0, "asc": 150.0}


def scipy_scenario(g: dict, p: dict, fl: dict, method: str, t_end: float, tol):
    """delta on the 10 ms grid for one scenario with tests/reference.py's model: one
    solve_ivp per network stage, as reference.simulate does but with `method`.
    Like smibjax, a run stops once delta leaves (DELTA_MARGIN, pi - DELTA_MARGIN)
    (loss of synchronism). Returns (delta, ok); NaN after a stop or a failure."""
    xs = p["Xdp"] + p["XT"] + p["XL"]
    d0 = reference.DELTA_E
    y = np.array(
        [d0, 0.0, reference.PM_REF * xs / (p["V"] * math.sin(d0)), p["B0"]]
        + list(reference.TH0)
    )
    n = int(round(t_end / 0.01)) + 1
    ts = np.linspace(0.0, t_end, n)
    out = np.full(n, np.nan)
    bounds = [0.0, fl["t_fault"], fl["t_clear"], fl["t_reclose"], np.inf]
    for i, st in enumerate(reference.stages(p, fl)):
        a, b = max(bounds[i], 0.0), min(bounds[i + 1], t_end)
        if b <= a:
            continue
        sel = (ts >= a) & ((ts < b) | ((b == t_end) & (ts <= b)))
        sol = solve_ivp(
            reference.rhs,
            (a, b),
            y,
            method=method,
            rtol=tol[0],
            atol=tol[1],
            args=(p, g, st, True),
            dense_output=True,
            events=_lost_sync,
        )
        if not sol.success or sol.status == 1:
            return out, False
        if sel.any():
            out[sel] = sol.sol(ts[sel])[0]
        y = sol.y[:, -1]
    return out, True


def _lost_sync(t, y, *args):
    return min(y[0] - DELTA_MARGIN, math.pi - DELTA_MARGIN - y[0])


_lost_sync.terminal = True


def fault_dict(f: sj.Fault) -> dict:
    return {n: float(getattr(f, n)) for n in sj.FAULT_NAMES}


def check_same_model():
    """tests/reference.py hard-codes the operating point and initial estimates."""
    op, est = sj.OperatingPoint(), sj.InitialEstimates()
    ours = (float(op.delta_e), float(op.Pm_ref), (float(est.th1), float(est.th2)))
    theirs = (reference.DELTA_E, reference.PM_REF, tuple(reference.TH0))
    if ours != theirs:
        raise SystemExit(f"operating point differs: smibjax {ours}, reference {theirs}")


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--n-scipy", type=int, default=8, help="SciPy scenarios per method/controller"
    )
    ap.add_argument("--methods", nargs="+", default=["LSODA", "Radau"])
    ap.add_argument("--batch", type=int, default=1024, help="smibjax batch size")
    ap.add_argument("--devices", type=int, default=2, help="smibjax host devices")
    ap.add_argument(
        "--controllers", nargs="+", choices=CONTROLLERS, default=CONTROLLERS
    )
    ap.add_argument("--repeat", type=int, default=2, help="smibjax timed calls")
    ap.add_argument(
        "--reference",
        choices=["smibjax", "scipy"],
        default="smibjax",
        help="tight reference: smibjax or SciPy DOP853, rtol 1e-10, atol 1e-12",
    )
    ap.add_argument("--t-end", type=float, default=10.0, help="scenario length (s)")
    ap.add_argument("--seed", type=int, default=0)
    add_tolerance_args(ap)
    ap.add_argument(
        "--smibjax-rtol",
        type=float,
        default=None,
        help="smibjax's rtol alone (default: --rtol, SciPy's)",
    )
    ap.add_argument(
        "--smibjax-atol",
        type=float,
        default=None,
        help="smibjax's atol alone (default: --atol, SciPy's)",
    )
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    args = ap.parse_args(argv)
    for name in ("smibjax_rtol", "smibjax_atol"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and v > 0):
            ap.error(f"--{name.replace('_', '-')} {v:g}: must be a positive number")
    return args


def smibjax_solver(args) -> sj.SolverOptions:
    """smibjax's solver options: --smibjax-rtol/--smibjax-atol, else SciPy's."""
    rtol = args.rtol if args.smibjax_rtol is None else args.smibjax_rtol
    atol = args.atol if args.smibjax_atol is None else args.smibjax_atol
    return sj.SolverOptions(rtol=rtol, atol=atol)


def main(argv=None) -> None:
    args = parse_args(argv)
    cache = enable_cache()
    check_same_model()
    devs = host_devices(args.devices)
    pool = scenarios(args.seed, max(args.batch, args.n_scipy))
    plant = {n: float(getattr(sj.Plant(), n)) for n in sj.PLANT_NAMES}
    rows, agreement = {}, {}
    for ctrl in args.controllers:
        g = gains(ctrl)
        fn = batched_metrics(args.t_end, smibjax_solver(args))
        gd = {n: float(getattr(g, n)) for n in sj.GAIN_NAMES}

        # smibjax: one batch call over the devices (best of --repeat after warm-up)
        faults = take(pool, args.batch)
        first, best, out = timed(
            lambda g=g, faults=faults, fn=fn: jax.block_until_ready(
                fn(g, faults, devs)
            ),
            args.repeat,
        )
        steps = np.asarray(out[2])
        rows[f"{ctrl} smibjax"] = {
            "controller": ctrl,
            "method": f"smibjax Tsit5, batch {args.batch}, {args.devices} devices",
            "scenarios": args.batch,
            "seconds": best,
            "first_call_s": first,
            "scenarios_per_s": args.batch / best,
            "mean_steps": float(steps.mean()),
            "stable_fraction": float(np.mean(np.asarray(out[0]))),
        }
        print(f"  {ctrl} smibjax: {args.batch / best:.1f} scen/s", flush=True)

        # the shared scenarios: smibjax per scenario, and the tight reference
        n = args.n_scipy
        d_jax, lost = deltas(g, pool, n, args.t_end, smibjax_solver(args))
        if args.reference == "smibjax":
            d_ref = deltas(g, pool, n, args.t_end, REFERENCE)[0]
        else:
            d_ref = np.stack(
                [
                    scipy_scenario(
                        gd,
                        plant,
                        fault_dict(row(pool, i)),
                        "DOP853",
                        args.t_end,
                        (REF_RTOL, REF_ATOL),
                    )[0]
                    for i in range(n)
                ]
            )
        ok_jax = ~lost
        agreement[ctrl] = {
            "scenarios": n,
            "smibjax_lost_sync": int(lost.sum()),
            "smibjax_vs_reference_rad": float(
                np.nanmax(np.abs(d_jax - d_ref)[ok_jax], initial=0.0)
            ),
        }

        for method in args.methods:
            ds, oks, t_total = [], [], 0.0
            for i in range(n):
                fl = fault_dict(row(pool, i))
                t0 = time.perf_counter()
                d, ok = scipy_scenario(
                    gd, plant, fl, method, args.t_end, (args.rtol, args.atol)
                )
                t_total += time.perf_counter() - t0
                ds.append(d)
                oks.append(ok)
            ds, oks = np.stack(ds), np.array(oks)
            both = oks & ok_jax
            rate = n / t_total
            rows[f"{ctrl} {method}"] = {
                "controller": ctrl,
                "method": f"scipy solve_ivp {method}, per-scenario loop",
                "scenarios": n,
                "seconds": t_total,
                "scenarios_per_s": rate,
                "stopped_or_failed": int((~oks).sum()),
            }
            agreement[ctrl][method] = {
                "compared_scenarios": int(both.sum()),
                "scipy_vs_smibjax_rad": float(
                    np.nanmax(np.abs(ds - d_jax)[both], initial=0.0)
                ),
                "scipy_vs_reference_rad": float(
                    np.nanmax(np.abs(ds - d_ref)[both], initial=0.0)
                ),
            }
            print(
                f"  {ctrl} {method}: {rate:.2f} scen/s ({int((~oks).sum())} stopped "
                "or failed)",
                flush=True,
            )

        jax_rate = rows[f"{ctrl} smibjax"]["scenarios_per_s"]
        for method in args.methods:
            r = rows[f"{ctrl} {method}"]
            r["smibjax_ratio"] = jax_rate / r["scenarios_per_s"]
        fastest = max(
            args.methods, key=lambda m: rows[f"{ctrl} {m}"]["scenarios_per_s"]
        )
        ratio = rows[f"{ctrl} {fastest}"]["smibjax_ratio"]
        rows[f"{ctrl} smibjax"].update(
            ratio_vs_fastest_scipy=ratio,
            fastest_scipy=fastest,
            target_ratio=TARGET_RATIO[ctrl],
            status=status(ratio, TARGET_RATIO[ctrl]),
        )

    print()
    print(
        f"{'case':16} {'scen/s':>10} {'smibjax x':>10} {'|d - smibjax|':>14} "
        f"{'|d - ref|':>10}"
    )
    for ctrl in args.controllers:
        a = agreement[ctrl]
        r = rows[f"{ctrl} smibjax"]
        print(
            f"{ctrl + ' smibjax':16} {r['scenarios_per_s']:10.1f} {'':>10} {'':>14} "
            f"{a['smibjax_vs_reference_rad']:10.2e}"
        )
        for method in args.methods:
            r, m = rows[f"{ctrl} {method}"], a[method]
            print(
                f"{ctrl + ' ' + method:16} {r['scenarios_per_s']:10.2f} "
                f"{r['smibjax_ratio']:10.0f} {m['scipy_vs_smibjax_rad']:14.2e} "
                f"{m['scipy_vs_reference_rad']:10.2e}"
            )
    for ctrl in args.controllers:
        r = rows[f"{ctrl} smibjax"]
        print(
            f"{ctrl}: smibjax / fastest SciPy ({r['fastest_scipy']}) = "
            f"{r['ratio_vs_fastest_scipy']:.0f}x (target >= {r['target_ratio']:.0f}x: "
            f"{r['status']})"
        )

    config = {
        "scenario_s": args.t_end,
        "faults": f"sample_faults(PRNGKey({args.seed}), n, FaultDistribution()), "
        "the first n_scipy shared",
        "gains": "Gains.paper(controller, beta1=-1, beta2=-1)",
        "tolerance": {"rtol": args.rtol, "atol": args.atol},
        "smibjax_tolerance": {
            "rtol": smibjax_solver(args).rtol,
            "atol": smibjax_solver(args).atol,
        },
        "n_scipy": args.n_scipy,
        "scipy_methods": args.methods,
        "scipy_model": "tests/reference.py rhs and stages, one solve_ivp per stage, "
        "dense output sampled every 10 ms",
        "smibjax": f"device_map(jit(vmap(simulate + metrics))), batch {args.batch}, "
        f"{args.devices} host devices, best of {args.repeat} after a warm-up call",
        "reference": f"{args.reference} at rtol {REF_RTOL:g}, atol {REF_ATOL:g}",
        "agreement": "max |delta| difference (rad) over the samples of the scenarios "
        "that both ran to the end",
        "targets": {"smibjax_over_fastest_scipy": TARGET_RATIO},
        "persistent_cache": cache,
    }
    name = result_name("vs_scipy", args.tag)
    path = write_results(args.out, name, config, {"rows": rows, "agreement": agreement})

    fig, ax = plt.subplots(figsize=(7, 4.5))
    cases = [*args.methods, "smibjax"]
    width = 0.8 / len(cases)
    for k, case in enumerate(cases):
        vals = [rows[f"{c} {case}"]["scenarios_per_s"] for c in args.controllers]
        x = np.arange(len(args.controllers)) + (k - (len(cases) - 1) / 2) * width
        bars = ax.bar(
            x, vals, width, label=case if case == "smibjax" else f"SciPy {case}"
        )
        for b, c in zip(bars, args.controllers, strict=True):
            r = rows[f"{c} {case}"]
            note = f"{r['smibjax_ratio']:.0f}x" if case != "smibjax" else ""
            ax.annotate(
                f"{r['scenarios_per_s']:.3g}\n{note}".strip(),
                (b.get_x() + b.get_width() / 2, b.get_height()),
                ha="center",
                va="bottom",
                fontsize=7,
            )
    ax.set_xticks(np.arange(len(args.controllers)))
    ax.set_xticklabels([f"{c.upper()} (alpha = {ALPHA[c]})" for c in args.controllers])
    ax.set_yscale("log")
    ax.set_ylabel("scenarios / s")
    ax.set_title(
        f"{args.t_end:g} s scenarios, rtol {args.rtol:g}, atol {args.atol:g} "
        f"(label: smibjax speed-up over that method)",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y", which="both")
    fig.tight_layout()
    save_figure(fig, Path(args.out) / f"{name}.png")
    print(f"wrote {path} and {name}.png")


if __name__ == "__main__":
    main()
