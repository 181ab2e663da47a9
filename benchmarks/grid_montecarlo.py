"""IEEE 39 (GENROU + IEEEX1 + TGOV1) Monte Carlo of bus faults, as
`python -m smibjax montecarlo --case ieee39` runs it (issue 28's target: 1,024 fault
scenarios of 10 s in under 5 minutes including compilation; compilation under 60 s
cold and 5 s from the persistent cache).

Three parts, each in fresh Python processes so that compilation is counted:

- `sweep`: batch sizes (--sweep, default 8,32,128,256) through
  `smibjax.grid.metrics.batch_metrics` (the CLI's compiled chunk: simulation and
  metrics in one program) on ONE host device: per batch, the first call (compile +
  run) and the second (run), wall and CPU seconds, adaptive steps per scenario (mean,
  max: the vmapped loop runs until its slowest scenario is done) and the CPU seconds
  per scenario. One device, so CPU seconds per scenario are one core's work.
- `compile`: the CLI's program at --chunk on one host device, first and second call
  in a process with an empty cache folder (cold), then in a second process on the
  same folder (cached); compile = first - second call. The cached figure is tracing +
  cache lookup (XLA's compile is skipped).
- `montecarlo`: `python -m smibjax montecarlo --case ieee39 --n N --chunk C` as a
  child process, with an empty cache folder (cold) and again on the same folder
  (warm): wall time from spawn to exit, the child's CPU seconds (user + system), the
  load average before and after.

The machine is shared: every wall time is recorded with the load average and the CPU
seconds, and an idle-machine estimate is derived from the CPU seconds (the run uses
one core: CPU seconds = wall time while it is the only load). Writes
benchmarks/results/grid_montecarlo_ieee39.json.

    python benchmarks/grid_montecarlo.py                      # all parts, n = 1024
    python benchmarks/grid_montecarlo.py --skip montecarlo    # sweep + compile only
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
TAG = "GRID_MC "
TARGET_S, TARGET_COLD_S, TARGET_CACHED_S = 300.0, 60.0, 5.0

CHILD = """
import time
t0 = time.perf_counter()
import json, os
from smibjax._process import configure
configure(min_devices=1, cache_dir=os.environ["SMIBJAX_CACHE_DIR"] or None,
          host_devices={host_devices})
import jax
import numpy as np
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
from smibjax.grid.case import load_case
from smibjax.grid.metrics import batch_metrics
from smibjax.grid.operating import operating_point
from smibjax.grid.scenarios import FaultDistribution, sample_events
case = load_case("ieee39")
op, _ = operating_point(case)
devices = jax.devices()[: {n_dev}]
run = batch_metrics(case, op, devices=devices, t_end=10.0, dt_save=0.01)
t1 = time.perf_counter()
for b in {batches}:
    ev = sample_events(case.system, FaultDistribution(), b, 0)
    out = {{"batch": b, "devices": len(devices), "setup_s": t1 - t0}}
    for k in ("first", "second"):
        c0, w0 = time.process_time(), time.perf_counter()
        m = jax.block_until_ready(run(ev))
        out[k + "_s"] = time.perf_counter() - w0
        out[k + "_cpu_s"] = time.process_time() - c0
    ns = np.asarray(m.n_steps)
    out.update(steps_mean=float(ns.mean()), steps_max=int(ns.max()),
               stable=float(np.mean(np.asarray(m.stable))),
               load=os.getloadavg()[0])
    print({tag!r} + json.dumps(out), flush=True)
"""


def _env(cache_dir: str) -> dict:
    env = {**os.environ, "SMIBJAX_CACHE_DIR": cache_dir}
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT / "src"), env.get("PYTHONPATH", "")]
    ).strip(os.pathsep)
    return env


def _child(batches, n_dev: int, cache_dir: str) -> list[dict]:
    code = CHILD.format(
        batches=list(batches), n_dev=n_dev, host_devices=n_dev > 1, tag=TAG
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env=_env(cache_dir),
    )
    if r.returncode:
        sys.exit(f"child failed:\n{r.stderr[-3000:]}")
    rows = [
        json.loads(s[len(TAG) :]) for s in r.stdout.splitlines() if s.startswith(TAG)
    ]
    for row in rows:
        row["compile_s"] = row["first_s"] - row["second_s"]
        row["compile_cpu_s"] = row["first_cpu_s"] - row["second_cpu_s"]
        row["cpu_per_scenario_s"] = row["second_cpu_s"] / row["batch"]
    return rows


def sweep(args) -> dict:
    rows = []
    for b in args.sweep:  # one process per batch: each compiles its own program
        (row,) = _child([b], 1, "")
        print(
            f"  batch {b:4d}: first {row['first_s']:.1f} s, second "
            f"{row['second_s']:.2f} s wall / {row['second_cpu_s']:.2f} CPU-s "
            f"({1e3 * row['cpu_per_scenario_s']:.1f} CPU-ms per scenario), steps "
            f"mean {row['steps_mean']:.0f} max {row['steps_max']}, load "
            f"{row['load']:.1f}",
            flush=True,
        )
        rows.append(row)
    return {"devices": 1, "rows": rows}


def compile_times(args) -> dict:
    n_dev = 1  # as the CLI runs it (two host devices deadlock: docs/performance.md)
    out = {"batch": args.chunk, "devices": n_dev}
    with tempfile.TemporaryDirectory(prefix="grid_mc_cache_") as d:
        for name in ("cold", "cached"):
            (row,) = _child([args.chunk], n_dev, d)
            out[name] = row
            print(
                f"  compile {name}: {row['compile_s']:.1f} s wall, "
                f"{row['compile_cpu_s']:.1f} CPU-s (first call "
                f"{row['first_s']:.1f} s, second {row['second_s']:.1f} s; setup "
                f"{row['setup_s']:.1f} s), load {row['load']:.1f}",
                flush=True,
            )
    out["target_cold_s"], out["target_cached_s"] = TARGET_COLD_S, TARGET_CACHED_S
    return out


def montecarlo(args) -> dict:
    out = {"n": args.n, "chunk": args.chunk, "runs": {}}
    with tempfile.TemporaryDirectory(prefix="grid_mc_") as d:
        env = _env(str(Path(d) / "cache"))
        for name in ("cold", "warm"):
            dest = Path(d) / f"out_{name}"
            cmd = [sys.executable, "-m", "smibjax", "montecarlo", "--case", "ieee39"]
            cmd += ["--n", str(args.n), "--chunk", str(args.chunk), "--seed", "0"]
            cmd += ["--out", str(dest)]
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            load0 = os.getloadavg()
            t0 = time.perf_counter()
            r = subprocess.run(cmd, capture_output=True, text=True, env=env)
            wall = time.perf_counter() - t0
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if r.returncode:
                sys.exit(f"montecarlo failed:\n{r.stderr[-3000:]}")
            cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
            summary = json.loads((dest / "summary.json").read_text())
            run = {
                "wall_s": wall,
                "cpu_s": cpu,
                "loop_s": summary["seconds"],
                "load_before": list(load0),
                "load_after": list(os.getloadavg()),
                "stable_fraction": summary["stable_fraction"],
                "exhausted": summary["exhausted"],
                "peak_rss_mb": after.ru_maxrss / 1024,
                "cpu_per_scenario_s": cpu / args.n,
            }
            out["runs"][name] = run
            print(
                f"  montecarlo {name}: {args.n} scenarios in {wall:.1f} s wall "
                f"(loop {summary['seconds']:.1f} s), {cpu:.1f} CPU-s, load "
                f"{load0[0]:.1f} -> {run['load_after'][0]:.1f}, stable "
                f"{summary['stable_fraction']:.3f}",
                flush=True,
            )
    out["target_s"] = TARGET_S
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1024, help="scenarios (default 1024)")
    ap.add_argument("--chunk", type=int, default=128, help="CLI chunk (default 128)")
    ap.add_argument(
        "--sweep",
        type=lambda s: [int(x) for x in s.split(",")],
        default=[8, 32, 128, 256],
        help="batch sizes of the sweep (default 8,32,128,256)",
    )
    ap.add_argument(
        "--skip",
        nargs="*",
        default=[],
        choices=("sweep", "compile", "montecarlo"),
        help="parts to leave out",
    )
    ap.add_argument("--out", default=str(HERE / "results"), help="results folder")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from _results import write_results

    res = {"load_average_start": list(os.getloadavg())}
    config = {k: v for k, v in vars(args).items() if k != "out"}
    for name, fn in (
        ("compile", compile_times),
        ("montecarlo", montecarlo),
        ("sweep", sweep),
    ):
        if name not in args.skip:
            print(f"{name}:", flush=True)
            res[name] = fn(args)
            write_results(args.out, "grid_montecarlo_ieee39", config, res)
    res["load_average_end"] = list(os.getloadavg())
    rows = res.get("sweep", {}).get("rows", [])
    pick = [r for r in rows if r["batch"] == args.chunk] or rows[-1:]
    if pick:
        per = pick[0]["cpu_per_scenario_s"]
        cores = 1  # the CLI runs on one host device
        comp = res.get("compile", {}).get("cold", {}).get("compile_cpu_s", 0.0)
        est = {
            "cpu_per_scenario_s": per,
            "batch": pick[0]["batch"],
            "n": args.n,
            "cores": cores,
            "solve_s": args.n * per / cores,
            "compile_cold_s": comp,
            "total_s": args.n * per / cores + comp,
            "note": "n x CPU-s per scenario (one device, warm) / cores + the CPU-s of "
            "the cold compile measured here: the wall time on an otherwise idle "
            "machine",
        }
        res["estimate_idle"] = est
        print(
            f"estimate, idle {cores}-core machine: {args.n} scenarios "
            f"{est['solve_s']:.0f} s + compile {comp:.0f} s = {est['total_s']:.0f} s "
            f"(target {TARGET_S:.0f} s)"
        )
    path = write_results(args.out, "grid_montecarlo_ieee39", config, res)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
