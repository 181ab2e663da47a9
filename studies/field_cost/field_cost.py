"""What a closed-loop field evaluation costs, and where a Monte Carlo step goes.

1. The field (`smibjax._closed_loop.closed_loop_vector_field`) vmapped over --lanes
   lanes and evaluated --evals times in a `lax.fori_loop`, one core: nanoseconds per
   lane and evaluation, and the sines and cosines in the compiled program; once as
   the closed loop runs it (sin and cos of delta computed once, `smibjax._plant.sincos`)
   and once with each consumer computing its own (the controller's coordinate map and
   drift, the plant), as they did before 2026-12-01.
2. The batch engine on Monte Carlo scenarios 0..--n-1 (seed 0, default distribution,
   beta1 = beta2 = -1, oracle, one core): microseconds per lane and accepted step at
   the default sampling dt_save = 0.01 s and at 1 s (the difference is what saving
   the samples costs), and scenarios/s.

AFTSC (alpha = 5/7) and ASC (alpha = 1). Prints a table and writes
studies/field_cost/field_cost.json.

    python studies/field_cost/field_cost.py [--lanes 128] [--evals 2000] [--n 256] [--repeat 3]
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results

# one core: the per-lane figures do not depend on how a batch is split
os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=1"

from smibjax import configure

configure(cache=False)

import argparse
import re
import time

import jax
import jax.numpy as jnp
import numpy as np
from _results import write_results

import smibjax as sj
from smibjax._batch import Engine, Scenarios
from smibjax._closed_loop import ClosedLoop, closed_loop_vector_field, healthy
from smibjax._plant import apply_limits, plant_vector_field
from smibjax._scenarios import ScenarioDistribution, sample_scenarios


def field_per_consumer(t, y, loop):
    """The closed-loop field with sin and cos of delta computed by each consumer
    (the controller's coordinate map and drift, the plant): the same values."""
    ok = healthy(t, y, loop)
    safe = jnp.where(ok, y, loop.safe_state)
    z, s = safe[:4], safe[4 : loop.n_dynamic]
    stage = loop.stage(t)
    out = loop.controller(t, z, s, stage, loop.plant, loop.op)
    u_f, u_r = apply_limits(out.u_f, out.u_r, loop.plant, loop.input_smoothing)
    dz = plant_vector_field(z, u_f, u_r, stage, loop.plant)
    dy = jnp.concatenate([dz, out.d_internal, jnp.stack([u_f**2, u_r**2])])
    return jnp.where(ok, dy, 0.0)


def time_field(field, controller, lanes, evals, repeat):
    """(ns per lane and evaluation, sines, cosines in the compiled program)."""
    plant, op = sj.Plant(), sj.OperatingPoint()
    fault, _, _ = sample_scenarios(0, 0, lanes, ScenarioDistribution(), plant)
    y0 = sj.initial_state(op, plant, sj.InitialEstimates())

    def run(fault, y, t):
        def one(fl, y, t):
            loop = ClosedLoop(controller, fl, plant, op)

            def body(i, y):
                return y + 1e-6 * field(t + 1e-4 * i, y, loop)

            return jax.lax.fori_loop(0, evals, body, y)

        return jax.vmap(one)(fault, y, t)

    ys = jnp.tile(y0, (lanes, 1)) + 0.01
    ts = jnp.full((lanes,), 3.0)  # the restored network, every lane
    compiled = jax.jit(run).lower(fault, ys, ts).compile()
    hlo = compiled.as_text()
    compiled(fault, ys, ts).block_until_ready()
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        compiled(fault, ys, ts).block_until_ready()
        best = min(best, time.perf_counter() - t0)
    sines = len(re.findall(r" sine\(", hlo))
    cosines = len(re.findall(r" cosine\(", hlo))
    return 1e9 * best / (evals * lanes), sines, cosines


def time_engine(gains, n, dt_save, repeat):
    """(us per lane and accepted step, scenarios/s, mean steps)."""
    fault, _, _ = sample_scenarios(0, 0, n, ScenarioDistribution(), sj.Plant())
    engine = Engine(dt_save=dt_save)
    out = engine.run(gains, Scenarios(fault))
    jax.block_until_ready(out)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = engine.run(gains, Scenarios(fault))
        jax.block_until_ready(out)
        best = min(best, time.perf_counter() - t0)
    steps = np.asarray(out.num_steps)
    return 1e6 * best / steps.sum(), n / best, float(steps.mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, default=128)
    ap.add_argument("--evals", type=int, default=2000)
    ap.add_argument("--n", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args()
    rows = {}
    for name in ("aftsc", "asc"):
        g = sj.Gains.paper(name, beta1=-1.0, beta2=-1.0)
        ctrl = sj.controllers.Synergetic(g).with_static_alpha()
        row = {}
        for label, field in (
            ("shared", closed_loop_vector_field),
            ("per_consumer", field_per_consumer),
        ):
            ns, sines, cosines = time_field(
                field, ctrl, args.lanes, args.evals, args.repeat
            )
            row[f"field_ns_{label}"] = ns
            row[f"sines_{label}"] = sines
            row[f"cosines_{label}"] = cosines
        for dt_save in (0.01, 1.0):
            us, rate, steps = time_engine(g, args.n, dt_save, args.repeat)
            row[f"engine_us_per_lane_step_dt{dt_save:g}"] = us
            row[f"engine_scenarios_per_s_dt{dt_save:g}"] = rate
            row["engine_mean_steps"] = steps
        rows[name] = row
        print(
            f"{name}: field {row['field_ns_shared']:.0f} ns/lane-eval "
            f"({row['sines_shared']} sin, {row['cosines_shared']} cos) against "
            f"{row['field_ns_per_consumer']:.0f} ns ({row['sines_per_consumer']} sin, "
            f"{row['cosines_per_consumer']} cos) per consumer; engine "
            f"{row['engine_us_per_lane_step_dt0.01']:.2f} us/lane-step at dt_save "
            f"0.01 ({row['engine_scenarios_per_s_dt0.01']:.0f} /s), "
            f"{row['engine_us_per_lane_step_dt1']:.2f} at 1 s",
            flush=True,
        )
    write_results(
        args.out,
        "field_cost",
        {
            "lanes": args.lanes,
            "evals": args.evals,
            "n": args.n,
            "repeat": args.repeat,
            "devices": 1,
            "gains": "paper, beta1 = beta2 = -1, oracle",
            "timing": "best of --repeat",
        },
        rows,
    )


if __name__ == "__main__":
    main()
