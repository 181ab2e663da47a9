"""Steps and milliseconds per 10 s scenario for one run (no batching), AFTSC and ASC,
paper fault, stabilizing gains beta1 = beta2 = -1, default adaptive solver, plus the
fixed-step solver. Prints a table and writes benchmarks/results/single_scenario.json.

    python benchmarks/single_scenario.py [--repeat N]
"""

from __future__ import annotations

from smibjax import configure

# an entry point: float64, equinox's checks as NaNs, before JAX loads
configure(cache=False)

import argparse
import time
from pathlib import Path

from _results import write_results

import smibjax as sj


def measure(gains, repeat, **kw):
    t0 = time.perf_counter()
    tr = sj.simulate(gains, **kw)
    tr.delta.block_until_ready()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        sj.simulate(gains, **kw).delta.block_until_ready()
        times.append(time.perf_counter() - t0)
    return {
        "steps": int(tr.num_steps),
        "rejected": int(tr.num_rejected),
        "ms_per_scenario": 1e3 * min(times),
        "first_call_s": first,
        "stable": bool(tr.stable),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    rows = {}
    for ctrl in ("aftsc", "asc"):
        g = sj.Gains.paper(ctrl, beta1=-1.0, beta2=-1.0)
        rows[f"{ctrl} adaptive"] = measure(g, args.repeat)
        rows[f"{ctrl} fixed dt=1ms"] = measure(g, args.repeat, solver="fixed")
    print(
        f"{'case':22} {'steps':>7} {'rejected':>8} {'ms/scenario':>12} {'1st call s':>10}"
    )
    for k, r in rows.items():
        print(
            f"{k:22} {r['steps']:7d} {r['rejected']:8d} {r['ms_per_scenario']:12.1f} "
            f"{r['first_call_s']:10.1f}"
        )
    write_results(
        args.out,
        "single_scenario",
        {"scenario": "10 s, paper fault, beta1 = beta2 = -1, batch 1"},
        {"rows": rows},
    )


if __name__ == "__main__":
    main()
