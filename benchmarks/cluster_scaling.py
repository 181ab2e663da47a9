"""Monte Carlo throughput on Dask: scenarios/s with 1 and 2 local worker processes
(`smibjax.cli.cluster.dask_runner(workers=N)`), against the in-process run on one device and
on all host devices, for one fixed Monte Carlo (AFTSC, beta1 = beta2 = -1, default
scenario distribution, seed 0). Each configuration runs twice: cold (the workers compile
on their first chunk) and warm (the compiled engine is reused). Also measured: cluster
start-up, the round trip of a trivial task (the scheduler's per-task overhead), the
worker time per chunk not spent computing, and each worker's first-chunk compile time
(its first chunk's compute time less the median of its later chunks). Checks that every
configuration gives the same rows.

Prints a table, writes benchmarks/results/cluster_scaling.json and cluster_scaling.png.

    python benchmarks/cluster_scaling.py [--n 2048] [--chunk 256] [--t-end 10]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from smibjax import configure

configure(cache=False)  # one host device per core, before JAX starts its CPU backend

import jax
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _common import enable_cache
from _results import write_results

import smibjax as sj
from smibjax._montecarlo import COLUMNS, MonteCarloSpec, compute_chunk
from smibjax.cli.plotting import save_figure


def _noop(x):
    return x


def make_spec(n: int, chunk: int, t_end: float) -> MonteCarloSpec:
    g = sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0)
    return MonteCarloSpec(
        n=n,
        chunk=min(chunk, n),
        gains={name: float(getattr(g, name)) for name in sj.GAIN_NAMES},
        t_end=t_end,
    )


def collect(pairs) -> dict[str, np.ndarray]:
    """(k, rows) pairs in any order -> rows in index order."""
    parts = dict(pairs)
    return {c: np.concatenate([parts[k][c] for k in sorted(parts)]) for c in COLUMNS}


def timed_run(runner, spec):
    t0 = time.perf_counter()
    rows = collect(runner(spec, range(spec.n_chunks)))
    return time.perf_counter() - t0, rows


def in_process(spec, devices):
    def runner(spec, chunks):
        for k in chunks:
            yield k, compute_chunk(spec, k, devices=devices)

    cold, rows = timed_run(runner, spec)
    warm, _ = timed_run(runner, spec)
    return {
        "devices": len(devices),
        "cold_s": cold,
        "warm_s": warm,
        "cold_scenarios_per_s": spec.n / cold,
        "warm_scenarios_per_s": spec.n / warm,
        "compile_s": cold - warm,
    }, rows


def _compute_times(stream) -> dict[str, list[tuple[float, float]]]:
    """worker -> [(start, stop)] of its chunk computations, in order."""
    out: dict[str, list[tuple[float, float]]] = {}
    for t in stream:
        if not str(t["key"]).startswith("smibjax-mc-"):
            continue
        for s in t["startstops"]:
            if s["action"] == "compute":
                out.setdefault(t["worker"], []).append((s["start"], s["stop"]))
    return {w: sorted(v) for w, v in out.items()}


def on_dask(spec, workers: int, roundtrips: int):
    from distributed import get_task_stream

    from smibjax.cli.cluster import dask_runner

    t0 = time.perf_counter()
    with dask_runner(workers=workers) as runner:
        client = runner.client
        client.wait_for_workers(workers)
        startup = time.perf_counter() - t0
        with get_task_stream(client) as cold_ts:
            cold, rows = timed_run(runner, spec)
        with get_task_stream(client) as warm_ts:
            warm, _ = timed_run(runner, spec)
        client.submit(_noop, -1, pure=False).result()
        trips = []
        for i in range(roundtrips):
            t = time.perf_counter()
            client.submit(_noop, i, pure=False).result()
            trips.append(time.perf_counter() - t)
    cold_c = _compute_times(cold_ts.data)
    warm_c = _compute_times(warm_ts.data)
    warm_durations = [b - a for v in warm_c.values() for a, b in v]
    chunk_s = statistics.median(warm_durations)
    compile_per_worker = {
        w: (v[0][1] - v[0][0]) - chunk_s for w, v in sorted(cold_c.items())
    }
    # worker time per chunk not spent computing: scheduling, transfers, idle tail
    idle = (warm * workers - sum(warm_durations)) / spec.n_chunks
    return {
        "workers": workers,
        "startup_s": startup,
        "cold_s": cold,
        "warm_s": warm,
        "cold_scenarios_per_s": spec.n / cold,
        "warm_scenarios_per_s": spec.n / warm,
        "chunk_compute_s_median": chunk_s,
        "first_chunk_compile_s": list(compile_per_worker.values()),
        "idle_per_chunk_s": idle,
        "trivial_task_roundtrip_ms": 1e3 * statistics.median(trips),
    }, rows


def same_rows(a, b) -> bool:
    return all(np.array_equal(a[c], b[c], equal_nan=True) for c in COLUMNS)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2048, help="scenarios")
    ap.add_argument("--chunk", type=int, default=256, help="scenarios per chunk")
    ap.add_argument("--t-end", type=float, default=10.0, help="horizon (s)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--roundtrips", type=int, default=50)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    # the persistent cache only where SMIBJAX_CACHE_DIR is set (the test suite's:
    # montecarlo.py's tiny run compiled the in-process programs, and the Dask
    # workers, which get the folder, share theirs with tests/test_cluster.py's); the
    # JSON says whether it was on
    enable_cache()
    spec = make_spec(args.n, args.chunk, args.t_end)
    all_devices = jax.devices()
    rows, ref = {}, None
    configs = [("in-process, 1 device", all_devices[:1])]
    if len(all_devices) > 1:
        configs.append((f"in-process, {len(all_devices)} devices", all_devices))
    for label, devs in configs:
        rows[label], r = in_process(spec, devs)
        ref = r if ref is None else ref
        rows[label]["same_rows"] = same_rows(ref, r)
    for w in args.workers:
        label = f"dask, {w} worker{'s' if w > 1 else ''}"
        rows[label], r = on_dask(spec, w, args.roundtrips)
        rows[label]["same_rows"] = same_rows(ref, r)

    base = rows["in-process, 1 device"]["warm_scenarios_per_s"]
    print(
        f"{spec.n} scenarios, chunks of {spec.chunk} ({spec.n_chunks}), t_end "
        f"{spec.t_end:g} s, {os.cpu_count()} CPUs"
    )
    print(
        f"{'configuration':24} {'warm scen/s':>11} {'speed-up':>8} {'cold scen/s':>11} "
        f"{'compile s':>14} {'idle/chunk s':>12} {'trip ms':>8} {'start s':>7} "
        f"{'same rows':>9}"
    )
    for label, r in rows.items():
        comp = r.get("first_chunk_compile_s", [r.get("compile_s", float("nan"))])
        comp_s = "/".join(f"{c:.1f}" for c in comp)
        print(
            f"{label:24} {r['warm_scenarios_per_s']:11.1f} "
            f"{r['warm_scenarios_per_s'] / base:8.2f} {r['cold_scenarios_per_s']:11.1f} "
            f"{comp_s:>14} {r.get('idle_per_chunk_s', float('nan')):12.3f} "
            f"{r.get('trivial_task_roundtrip_ms', float('nan')):8.1f} "
            f"{r.get('startup_s', float('nan')):7.1f} {str(r['same_rows']):>9}"
        )

    out = Path(args.out)
    write_results(
        out,
        "cluster_scaling",
        {
            "n": spec.n,
            "chunk": spec.chunk,
            "t_end": spec.t_end,
            "seed": spec.seed,
            "gains": "AFTSC, beta1 = beta2 = -1",
            "workers": args.workers,
            "threads_per_worker": 1,
            "persistent_compilation_cache": bool(
                jax.config.jax_compilation_cache_dir
                or os.environ.get("JAX_COMPILATION_CACHE_DIR")
            ),
        },
        {"rows": rows},
    )
    fig, ax = plt.subplots(figsize=(8, 4))
    labels = list(rows)
    x = np.arange(len(labels))
    ax.bar(
        x - 0.2, [rows[k]["warm_scenarios_per_s"] for k in labels], 0.4, label="warm"
    )
    ax.bar(
        x + 0.2, [rows[k]["cold_scenarios_per_s"] for k in labels], 0.4, label="cold"
    )
    ax.set_xticks(x, labels, rotation=15, ha="right")
    ax.set_ylabel("scenarios / s")
    ax.set_title(
        f"Monte Carlo throughput: {spec.n} scenarios, chunks of {spec.chunk}, "
        f"t_end {spec.t_end:g} s"
    )
    ax.legend()
    fig.tight_layout()
    save_figure(fig, out / "cluster_scaling.png")
    print(f"wrote {out / 'cluster_scaling.json'} and {out / 'cluster_scaling.png'}")


if __name__ == "__main__":
    main()
