"""Where a `python -m smibjax montecarlo` run's time goes, against the engine's rate
(issue 33, item 2), in one process: for ASC and AFTSC (beta1 = beta2 = -1, the
defaults otherwise: seed 0, chunk 1024, rtol 1e-6, atol 1e-8, paper plant), the
chunks 1 .. N/chunk - 1 of a run of N scenarios (chunk 0 warms the compiled
programs), each timed by stage as `run_montecarlo` does them:

- sample: `sample_scenarios` of the chunk's rows (host);
- compute: `Engine.run` on the chunk, blocked (the scenarios' transfer to the
  devices, the split over the host devices, the solve, the metrics, the gather);
- host: the outcome's columns to NumPy (`outcome_columns`, `np.asarray`);
- chunk file: `write_npz` of the chunk (atomic);
- and once per run, on the N rows: scenarios.csv, the summary (json, md), the plot
  (the last two do not grow with N: left out of the rate, shown apart).

Beside them, the engine alone as `benchmarks/throughput.py` measures it
(`_common.batched_metrics`, best of --repeat calls) on the same chunks' scenarios:
"engine" is the sum over the chunks of its best call, so the ratio engine / CLI
stages is the command's share of the engine's rate on the same scenarios. With
--cli, also the command itself as `benchmarks/cli_rate.py` runs it (a process at
n = --chunk and one at n = --n, the marginal rate between them: the same scenarios
as the timed chunks), in the same run. Prints a table and writes
benchmarks/results/cli_stages.json.

    python benchmarks/cli_stages.py [--n 4096] [--chunk 1024] [--repeat 2]
        [--controllers asc aftsc] [--cli] [--tag NAME]
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from smibjax import configure

configure(cache=True)

import argparse
import os
import tempfile
import time

import jax
import numpy as np

import smibjax as sj
from smibjax._batch import Engine, Scenarios
from smibjax._files import write_json, write_npz, write_text
from smibjax._montecarlo import (
    COLUMNS,
    INT_COLUMNS,
    MonteCarloSpec,
    outcome_columns,
    summarize,
)
from smibjax._scenarios import sample_scenarios


def stages(spec: MonteCarloSpec, k: int, engine: Engine, ctrl, tmp: Path) -> dict:
    """Seconds of each stage of chunk k, as `compute_chunk` and `run_montecarlo` run
    them (the columns assembled the same way)."""
    t = {}
    start, stop = spec.chunk_range(k)
    t0 = time.perf_counter()
    faults, D, Pm = sample_scenarios(
        spec.seed, start, stop, spec.distribution(), spec.parameters()[1]
    )
    jax.block_until_ready(faults)
    t1 = time.perf_counter()
    out = jax.block_until_ready(engine.run(ctrl, Scenarios(faults)))
    t2 = time.perf_counter()
    cols = {c: np.asarray(v) for c, v in outcome_columns(out).items()}
    cols["index"] = np.arange(start, stop)
    for name, attr in (
        ("t_fault", "t_fault"),
        ("t_clear", "t_clear"),
        ("t_reclose", "t_reclose"),
        ("fault_location", "lam"),
        ("fault_reactance", "Xf"),
    ):
        cols[name] = np.asarray(getattr(faults, attr))
    cols["clear_duration"] = cols["t_clear"] - cols["t_fault"]
    cols["D"], cols["Pm"] = np.asarray(D), np.asarray(Pm)
    rows = {c: cols[c].astype(int) if c in INT_COLUMNS else cols[c] for c in COLUMNS}
    t3 = time.perf_counter()
    write_npz(tmp / f"{k:06d}.npz", rows)
    t4 = time.perf_counter()
    t.update(sample=t1 - t0, compute=t2 - t1, host=t3 - t2, chunk_file=t4 - t3)
    return t, rows, faults


def run_files(rows: dict, tmp: Path) -> dict:
    """Seconds of the once-per-run files on all rows."""
    from smibjax.cli.plotting import plot_montecarlo
    from smibjax.cli.runs import summary_markdown, write_csv

    t0 = time.perf_counter()
    write_csv(tmp / "scenarios.csv", rows)
    t1 = time.perf_counter()
    s = summarize(rows)
    write_json(tmp / "summary.json", s)
    write_text(tmp / "summary.md", summary_markdown(s, "Monte Carlo"))
    t2 = time.perf_counter()
    plot_montecarlo(rows, tmp / "montecarlo.png", "Monte Carlo")
    t3 = time.perf_counter()
    return {"csv": t1 - t0, "summary": t2 - t1, "plot": t3 - t2}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--chunk", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--controllers", nargs="+", default=["asc", "aftsc"])
    ap.add_argument("--cli", action="store_true", help="also the command's own rate")
    ap.add_argument("--out", default=str(HERE / "results"))
    ap.add_argument("--tag", default="")
    args = ap.parse_args()
    from _common import batched_metrics, result_name
    from _results import write_results

    fn = batched_metrics(10.0)
    results = {}
    for c in args.controllers:
        gains = {"beta1": -1.0, "beta2": -1.0}
        spec = MonteCarloSpec(n=args.n, chunk=args.chunk, controller=c, gains=gains)
        params, plant, op, init = spec.parameters()
        engine = Engine(plant, op, init, t_end=spec.t_end, dt_save=spec.dt_save)
        ctrl = spec.controller_of(params)
        g = sj.Gains.paper(c, **gains)
        per = {"sample": 0.0, "compute": 0.0, "host": 0.0, "chunk_file": 0.0}
        bare, parts = 0.0, []
        with tempfile.TemporaryDirectory() as d:
            tmp = Path(d)
            for k in range(spec.n_chunks):
                t, rows, faults = stages(spec, k, engine, ctrl, tmp)
                parts.append(rows)
                if k == 0:  # warms the programs; also the engine's call below
                    jax.block_until_ready(fn(g, faults))
                    continue
                for s, v in t.items():
                    per[s] += v
                best = float("inf")
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    jax.block_until_ready(fn(g, faults))
                    best = min(best, time.perf_counter() - t0)
                bare += best
                print(
                    f"  {c} chunk {k}: "
                    + " ".join(f"{s} {v:.3f}" for s, v in t.items())
                    + f" | engine {best:.3f} s",
                    flush=True,
                )
            all_rows = {x: np.concatenate([p[x] for p in parts]) for x in COLUMNS}
            files = run_files(all_rows, tmp)
        m = (spec.n_chunks - 1) * args.chunk
        chunk_total = sum(per.values())
        # the once-per-run files' share of the timed chunks' rows (the plot's and the
        # summary's cost does not grow with n: a constant, outside the marginal rate)
        files_share = {s: v * m / args.n for s, v in files.items()}
        cli_total = chunk_total + files_share["csv"]
        results[c] = {
            "scenarios_timed": m,
            "stage_seconds": per,
            "files_seconds_all_rows": files,
            "files_seconds_share": files_share,
            "engine_seconds": bare,
            "engine_scenarios_per_s": m / bare,
            "cli_scenarios_per_s": m / cli_total,
            "cli_over_engine": bare / cli_total,
            "compute_over_engine": bare / per["compute"],
        }
        if args.cli:  # the command, as benchmarks/cli_rate.py runs it, alternated
            # with the engine on the same chunks so that the load falls on both alike
            from cli_rate import cli

            chunks = [
                sample_scenarios(0, *spec.chunk_range(k), spec.distribution(), plant)[0]
                for k in range(1, spec.n_chunks)
            ]

            def engine_seconds(chunks=chunks, g=g):
                t0 = time.perf_counter()
                for f in chunks:
                    jax.block_until_ready(fn(g, f))
                return time.perf_counter() - t0

            rounds = []
            with tempfile.TemporaryDirectory() as d:
                extra = ["--chunk", str(args.chunk)]
                cli(args.chunk, c, extra, Path(d) / "warm")
                for _ in range(args.repeat):
                    e1 = engine_seconds()
                    ts = cli(args.chunk, c, extra, Path(d) / "small")
                    tl = cli(args.n, c, extra, Path(d) / "large")
                    e2 = engine_seconds()
                    rounds.append({"small": ts, "large": tl, "engine": [e1, e2]})
            ratios = [
                (sum(r["engine"]) / 2) / (r["large"] - r["small"]) for r in rounds
            ]
            results[c].update(
                command_rounds=rounds,
                command_marginal_scenarios_per_s=[
                    m / (r["large"] - r["small"]) for r in rounds
                ],
                command_over_engine=ratios,
            )
    print(
        f"\n{'':6} {'engine/s':>9} {'cli/s':>8} {'ratio':>6} | seconds: "
        "sample compute host chunk_file csv summary plot (engine)"
    )
    for c, r in results.items():
        s, f = r["stage_seconds"], r["files_seconds_share"]
        print(
            f"{c:6} {r['engine_scenarios_per_s']:9.0f} {r['cli_scenarios_per_s']:8.0f} "
            f"{r['cli_over_engine']:6.2f} | {s['sample']:.2f} {s['compute']:.2f} "
            f"{s['host']:.2f} {s['chunk_file']:.2f} {f['csv']:.2f} "
            f"{f['summary']:.2f} {f['plot']:.2f} ({r['engine_seconds']:.2f})"
        )
        if "command_over_engine" in r:
            rates = ", ".join(f"{x:.0f}" for x in r["command_marginal_scenarios_per_s"])
            ratios = ", ".join(f"{x:.2f}" for x in r["command_over_engine"])
            print(
                f"{'':6} the command: marginal {rates} /s by round, {ratios} x the "
                "engine timed around it"
            )
    write_results(
        args.out,
        result_name("cli_stages", args.tag),
        {
            "n": args.n,
            "chunk": args.chunk,
            "repeat": args.repeat,
            "timed": "chunks 1..n/chunk-1 (chunk 0 warms the programs)",
            "engine": "_common.batched_metrics(10.0) on the same chunks, best of "
            "--repeat calls (as benchmarks/throughput.py)",
            "files": "scenarios.csv, summary, plot on all n rows; the csv counted at "
            "the timed rows' share, the summary and plot (constant in n) apart",
            "cores": os.cpu_count(),
        },
        {"controllers": results},
    )


if __name__ == "__main__":
    main()
