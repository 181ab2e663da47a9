"""Lanes that wait (issue 15): a vmapped adaptive solve runs every lane until its
slowest is done, so a Monte Carlo chunk costs about (its slowest lane's steps) x (its
width) on each device (`parallel.device_map` gives each device a contiguous slice).
This measures the chunks of the default distribution as the command runs them (index
order) against the same scenarios ordered by a cheap cost predictor (the reclosing
delay t_reclose - t_clear: the longer the line is out, the shorter the settled tail;
Spearman -0.98 with the AFTSC step counts on 8,192 scenarios), chunk by chunk through
the batch engine, the two orders alternated.

    python studies/lanes/lanes.py [--n 4096] [--chunk 256] [--controller aftsc]
        [--phi-layer 0]

Writes studies/lanes/lanes[_TAG].json. Nothing in the Monte Carlo command
changes: this only measures what ordering would give.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results

from smibjax import configure

configure(cache=False)

import argparse
import time

import jax
import numpy as np
from _common import result_name
from _results import write_results

import smibjax as sj
from smibjax._batch import Engine, Scenarios
from smibjax._scenarios import ScenarioDistribution, sample_scenarios
from smibjax.controllers import Synergetic


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--chunk", type=int, default=256)
    ap.add_argument("--controller", choices=["aftsc", "asc"], default="aftsc")
    ap.add_argument("--phi-layer", type=float, default=0.0)
    ap.add_argument("--tag", default="")
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args()
    g = sj.Gains.paper(args.controller, beta1=-1.0, beta2=-1.0)
    ctrl = Synergetic(g, True, None, args.phi_layer)
    faults, _, _ = sample_scenarios(0, 0, args.n, ScenarioDistribution(), sj.Plant())
    orders = {
        "index": np.arange(args.n),
        "reclose_delay": np.argsort(
            np.asarray(faults.t_reclose - faults.t_clear), kind="stable"
        ),
    }
    engine = Engine()

    def chunk(order, k):
        idx = order[k * args.chunk : (k + 1) * args.chunk]
        f = jax.tree_util.tree_map(lambda a: a[idx], faults)
        out = jax.block_until_ready(engine.run(ctrl, Scenarios(f)))
        return idx, np.asarray(out.num_steps), np.asarray(out.metrics.settling_delta)

    chunk(orders["index"], 0)  # compile
    wall = dict.fromkeys(orders, 0.0)
    steps = {o: np.zeros(args.n, int) for o in orders}
    settle = {o: np.zeros(args.n) for o in orders}
    names = list(orders)
    for k in range(-(-args.n // args.chunk)):
        for o in names[k % 2 :] + names[: k % 2]:
            t0 = time.perf_counter()
            idx, s, st = chunk(orders[o], k)
            wall[o] += time.perf_counter() - t0
            steps[o][idx], settle[o][idx] = s, st
    half = -(-args.chunk // len(jax.devices()))

    def efficiency(o):
        x = steps[o][orders[o]].astype(float)
        cost = sum(
            x[i : i + half].size * x[i : i + half].max() for i in range(0, x.size, half)
        )
        return float(x.sum() / cost)

    res = {
        o: {
            "wall_s": wall[o],
            "scenarios_per_s": args.n / wall[o],
            "lockstep_efficiency": efficiency(o),
        }
        for o in orders
    }
    res["speedup"] = wall["index"] / wall["reclose_delay"]
    res["same_steps"] = bool(np.array_equal(steps["index"], steps["reclose_delay"]))
    res["max_settling_diff_s"] = float(
        np.max(np.abs(settle["index"] - settle["reclose_delay"]), initial=0.0)
    )
    res["rows_bitwise_equal"] = bool(
        np.array_equal(settle["index"], settle["reclose_delay"], equal_nan=True)
    )
    for o in orders:
        print(
            f"{o:10} {res[o]['scenarios_per_s']:7.1f} /s  lockstep efficiency "
            f"{res[o]['lockstep_efficiency']:.3f}"
        )
    print(
        f"speed-up {res['speedup']:.3f}; same steps {res['same_steps']}; settling "
        f"bitwise equal {res['rows_bitwise_equal']}"
    )
    write_results(
        args.out,
        result_name("lanes", args.tag),
        {
            "controller": args.controller,
            "phi_layer": args.phi_layer,
            "n": args.n,
            "chunk": args.chunk,
            "devices": len(jax.devices()),
        },
        res,
    )


if __name__ == "__main__":
    main()
