"""Would a stiff (implicit) solver cut the AFTSC step count? (issue 6)

The AFTSC tail (t > 4 s, settled) takes about 60% of the steps of an explicit
solver at a step size that looks stability-limited. This script integrates the paper
fault (beta1 = beta2 = -1) with the independent NumPy model of tests/reference.py
through scipy.integrate.solve_ivp with explicit and implicit methods at the default
tolerances (rtol 1e-6, atol 1e-8), one call per network stage, for alpha = 5/7
(AFTSC) and alpha = 1 (ASC), and counts steps (all, and after --tail s), right-hand
side evaluations and Jacobians. Prints a table and writes
studies/stiff_solvers/stiff_solvers.json and stiff_solvers.png.

    python studies/stiff_solvers/stiff_solvers.py [--methods RK45 Radau BDF LSODA] [--t-end 10]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results
sys.path.insert(0, str(ROOT / "tests"))  # reference.py, the SciPy model

import matplotlib
import numpy as np
from scipy.integrate import solve_ivp

import reference

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _results import write_results

from smibjax.cli.plotting import save_figure

RTOL, ATOL = 1e-6, 1e-8
ALPHAS = {"aftsc": 5 / 7, "asc": 1.0}


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", nargs="+", default=["RK45", "Radau", "BDF", "LSODA"])
    ap.add_argument("--t-end", type=float, default=10.0, help="scenario length (s)")
    ap.add_argument("--tail", type=float, default=4.0, help="tail starts here (s)")
    ap.add_argument("--out", default=str(HERE))
    return ap.parse_args(argv)


def run(alpha: float, method: str, t_end: float, tail: float) -> dict:
    """Steps, tail steps, evaluations, Jacobians and delta(t_end) of one solve."""
    g = {**reference.GAINS, "beta1": -1.0, "beta2": -1.0, "alpha": alpha}
    p, fl = dict(reference.PLANT), dict(reference.FAULT)
    xs = p["Xdp"] + p["XT"] + p["XL"]
    d0 = reference.DELTA_E
    y = np.array(
        [d0, 0.0, reference.PM_REF * xs / (p["V"] * math.sin(d0)), p["B0"]]
        + list(reference.TH0)
    )
    bounds = [0.0, fl["t_fault"], fl["t_clear"], fl["t_reclose"], math.inf]
    steps = tail_steps = nfev = njev = 0
    t0 = time.perf_counter()
    for i, stage in enumerate(reference.stages(p, fl)):
        a, b = bounds[i], min(bounds[i + 1], t_end)
        if b <= a:
            continue
        sol = solve_ivp(
            reference.rhs,
            (a, b),
            y,
            method=method,
            rtol=RTOL,
            atol=ATOL,
            args=(p, g, stage, True),
        )
        if not sol.success:
            raise SystemExit(f"{method}, alpha = {alpha:.4g}: {sol.message}")
        steps += len(sol.t) - 1
        tail_steps += int(np.sum(sol.t[1:] > tail))
        nfev += int(sol.nfev)
        njev += int(sol.njev)
        y = sol.y[:, -1]
    return {
        "steps": steps,
        "tail_steps": tail_steps,
        "nfev": nfev,
        "njev": njev,
        "delta_end": float(y[0]),
        "seconds": time.perf_counter() - t0,
    }


def main(argv=None) -> None:
    args = parse_args(argv)
    rows = {
        c: {m: run(a, m, args.t_end, args.tail) for m in args.methods}
        for c, a in ALPHAS.items()
    }
    print(
        f"\npaper fault, beta = -1, rtol {RTOL:g}, atol {ATOL:g}, t_end {args.t_end:g} s"
    )
    print(
        f"{'controller':10s} {'method':7s} {'steps':>7s} {'tail':>7s} "
        f"{'nfev':>8s} {'njev':>6s} {'delta(t_end)':>14s}"
    )
    for c, by_method in rows.items():
        for m, r in by_method.items():
            print(
                f"{c:10s} {m:7s} {r['steps']:7d} {r['tail_steps']:7d} "
                f"{r['nfev']:8d} {r['njev']:6d} {r['delta_end']:14.8f}"
            )
    spread = {
        c: max(r["delta_end"] for r in bm.values())
        - min(r["delta_end"] for r in bm.values())
        for c, bm in rows.items()
    }
    print("spread of delta(t_end) across methods (rad):", spread)

    fig, ax = plt.subplots(figsize=(7, 3.5))
    width = 0.8 / len(rows)
    x = np.arange(len(args.methods))
    for k, (c, bm) in enumerate(rows.items()):
        steps = [bm[m]["steps"] for m in args.methods]
        tails = [bm[m]["tail_steps"] for m in args.methods]
        ax.bar(x + k * width, steps, width, label=f"{c} (alpha = {ALPHAS[c]:.3g})")
        ax.bar(x + k * width, tails, width, color="k", alpha=0.3)
    ax.set_xticks(x + width * (len(rows) - 1) / 2, args.methods)
    ax.set_ylabel(f"steps (shaded: after t = {args.tail:g} s)")
    ax.set_title("solve_ivp steps, paper fault, rtol 1e-6")
    ax.legend()
    fig.tight_layout()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_figure(fig, out / "stiff_solvers.png", dpi=120)
    path = write_results(
        out,
        "stiff_solvers",
        {
            "methods": args.methods,
            "t_end_s": args.t_end,
            "tail_from_s": args.tail,
            "rtol": RTOL,
            "atol": ATOL,
            "model": "tests/reference.py, one solve_ivp per network stage",
        },
        {"rows": rows, "delta_end_spread_rad": spread},
    )
    print(f"wrote {path} and stiff_solvers.png")


if __name__ == "__main__":
    main()
