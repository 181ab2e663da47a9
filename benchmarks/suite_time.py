"""The test suite's runtime from a cold compilation cache, and where it goes (issue 18).

Clones REF of this repository into a temporary folder (so its `.jax_cache` is empty),
runs the README's test command there (`python -m pytest`, with the clone's `src/`
first on the path, so the clone's code is what runs) under the `_suite_profile`
plugin, and reports: wall and CPU seconds of the whole run (every process it waited
for: workers, command-line processes, the benchmark chains), and from each worker its
tests' wall and CPU seconds and the JAX compilation events they caused (tracing,
lowering, XLA compiles, per jitted function).

The machine's speed changes from one session to the next (2.5x between two machines
on 2026-12-01), so unless --no-calibrate the script then times a fixed piece of work
on the same machine: the benchmark scripts' tiny runs, one after another, cold cache
(`tests/bench_chain.py`). Suite CPU-seconds over calibration CPU-seconds compares
runs on different machines.

Prints a summary and writes benchmarks/results/suite_time[_TAG].json and .png.

    python benchmarks/suite_time.py [--ref HEAD] [--no-calibrate] [--tag T] [--out DIR]

About 6 minutes on a fast 2-core machine, 15 on a slow one, plus about a minute
(or 4) of calibration. Not part of the suite (it runs the suite).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DEFAULT_OUT = HERE / "results"
TARGET_WALL_S = 360.0  # issue 18: the suite under 6 minutes, cold cache, 2 cores
CALIBRATION_LINE = re.compile(
    r"^(?P<name>\S+)\s+rc (?P<rc>-?\d+)\s+wall\s+(?P<wall>[\d.]+) s\s+cpu\s+"
    r"(?P<cpu>[\d.]+) s",
    re.M,
)


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", default="HEAD", help="commit to measure (default HEAD)")
    ap.add_argument(
        "--no-calibrate",
        dest="calibrate",
        action="store_false",
        help="skip the calibration run (tests/bench_chain.py, cold cache)",
    )
    ap.add_argument("--tag", default="", help="suffix of the result files")
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    return ap.parse_args(argv)


def resolve(ref: str) -> str:
    """The full commit id of `ref` in this repository; one-line error if none."""
    p = subprocess.run(
        ["git", "rev-parse", "--verify", "--quiet", f"{ref}^{{commit}}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    if p.returncode != 0 or not p.stdout.strip():
        raise ValueError(f"--ref = {ref!r} is not allowed: must name a commit here")
    return p.stdout.strip()


def children_cpu() -> float:
    """CPU seconds (user + system) of this process's waited-for descendants."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed_run(cmd, cwd, env) -> tuple[int, float, float]:
    """(exit status, wall s, CPU s of the process and its waited-for children)."""
    c0, t0 = children_cpu(), time.monotonic()
    rc = subprocess.run(cmd, cwd=cwd, env=env).returncode
    return rc, time.monotonic() - t0, children_cpu() - c0


def parse_calibration(text: str) -> dict:
    """{script: {"rc", "wall_s", "cpu_s"}} from `tests/bench_chain.py`'s lines."""
    return {
        m["name"]: {
            "rc": int(m["rc"]),
            "wall_s": float(m["wall"]),
            "cpu_s": float(m["cpu"]),
        }
        for m in CALIBRATION_LINE.finditer(text)
    }


def summarize(profiles: list[dict], start: float, top: int = 12) -> dict:
    """Totals and the largest items of the `_suite_profile` files of one run.

    `start`: the run's start (epoch s). Returns per-process rows (tests, CPU s, busy
    s, last test's end after `start`), event totals {event: [count, s]} over the
    workers' tests and what ran between them, per-module wall seconds, and the `top`
    largest programs (by XLA compile seconds) and tests (by wall seconds)."""
    processes, events = [], defaultdict(lambda: [0, 0.0])
    modules, programs = defaultdict(float), defaultdict(lambda: [0, 0.0])
    tests = []
    misses = Counter()  # persistent-cache key -> misses over every process
    for prof in profiles:
        rows = prof["tests"]
        misses.update(prof.get("misses_outside_tests", []))
        misses.update(k for r in rows if len(r) > 7 for k in r[7])
        processes.append(
            {
                "process": prof["process"],
                "tests": len(rows),
                "cpu_s": prof["cpu_s"],
                "busy_s": sum(r[2] for r in rows),
                "last_end_s": max((r[1] + r[2] for r in rows), default=start) - start,
            }
        )
        for ev in [r[4] for r in rows] + [prof["outside_tests"]]:
            for k, (n, s) in ev.items():
                events[k][0] += n
                events[k][1] += s
        for nodeid, _, wall, cpu, ev, *more in rows:
            kids = more[:1]
            progs = more[1] if len(more) > 1 else {}
            modules[nodeid.split("::")[0]] += wall
            comp = ev.get("compile", [0, 0.0])
            tests.append(
                {
                    "test": nodeid,
                    "wall_s": wall,
                    "cpu_s": cpu,
                    "children_cpu_s": kids[0] if kids else None,
                    "compiles": comp[0],
                    "compile_s": comp[1],
                    "trace_s": ev.get("trace", [0, 0.0])[1],
                    # its XLA compiles of at least 0.2 s: {function: [count, s]}
                    "programs": {k: v for k, v in progs.items() if v[1] >= 0.2},
                }
            )
        for name, (n, s) in prof["programs"].items():
            programs[name][0] += n
            programs[name][1] += s
    by_program = sorted(programs.items(), key=lambda kv: -kv[1][1])
    return {
        "processes": sorted(processes, key=lambda p: p["process"]),
        "events": {k: {"count": n, "s": s} for k, (n, s) in sorted(events.items())},
        "modules_wall_s": dict(sorted(modules.items(), key=lambda kv: -kv[1])),
        "programs": [
            {"function": name, "compiles": n, "compile_s": s}
            for name, (n, s) in by_program[:top]
        ],
        "repeated_misses": repeated_misses(misses),
        # every test (the printed summary shows the longest): where a change would
        # save the most CPU is read from the whole list
        "tests": sorted(tests, key=lambda t: -t["wall_s"]),
    }


def repeated_misses(misses: Counter) -> dict:
    """The persistent cache's misses in the test processes (`misses`: key -> count)
    and those of a key missed more than once: the same program compiled by two
    processes (both at once, before either wrote it) or again after a write that
    failed. `extra_compiles` by function (the key's name before its hash)."""
    extra = Counter()
    for key, n in misses.items():
        if n > 1:
            extra[key.rsplit("-", 1)[0]] += n - 1
    return {
        "misses": sum(misses.values()),
        "keys": len(misses),
        "repeated_keys": sum(1 for n in misses.values() if n > 1),
        "extra_compiles": sum(extra.values()),
        "extra_by_function": dict(extra.most_common()),
    }


def run_suite(commit: str, workdir: Path) -> dict:
    """Clone `commit` into `workdir`/repo, run `python -m pytest` there under the
    profiler; the run's figures and `summarize` of its profile files."""
    repo = workdir / "repo"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(repo)], check=True)
    subprocess.run(["git", "checkout", "-q", commit], cwd=repo, check=True)
    prof_dir = workdir / "profile"
    prof_dir.mkdir()
    path = os.pathsep.join(
        [str(repo / "src"), str(HERE), os.environ.get("PYTHONPATH", "")]
    )
    env = {**os.environ, "PYTHONPATH": path, "SMIBJAX_SUITE_PROFILE": str(prof_dir)}
    env.setdefault("MPLBACKEND", "Agg")
    start = time.time()
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-p",
        "_suite_profile",
        "-p",
        "no:cacheprovider",
    ]
    rc, wall, cpu = timed_run(cmd, repo, env)
    profiles = [json.loads(p.read_text()) for p in sorted(prof_dir.glob("*.json"))]
    return {"rc": rc, "wall_s": wall, "cpu_s": cpu, **summarize(profiles, start)}


def calibrate(commit: str, workdir: Path) -> dict:
    """`tests/bench_chain.py` of `commit` with an empty cache: per script and in all."""
    repo = workdir / "repo"
    env = {**os.environ, "PYTHONPATH": str(repo / "src")}
    p = subprocess.run(
        [
            sys.executable,
            str(repo / "tests" / "bench_chain.py"),
            str(workdir / "cache"),
        ],
        cwd=repo,
        env=env,
        capture_output=True,
        text=True,
    )
    scripts = parse_calibration(p.stdout)
    return {
        "rc": p.returncode,
        "scripts": scripts,
        "cpu_s": sum(s["cpu_s"] for s in scripts.values()),
        "wall_s": sum(s["wall_s"] for s in scripts.values()),
    }


def report(res: dict) -> str:
    """The printed summary."""
    s = res["suite"]
    lines = [
        f"suite at {res['commit'][:10]}: rc {s['rc']}, wall {s['wall_s']:.0f} s "
        f"({s['wall_s'] / 60:.1f} min; target {TARGET_WALL_S / 60:.0f} min), "
        f"CPU {s['cpu_s']:.0f} s ({s['cpu_s'] / s['wall_s']:.2f} cores busy)",
    ]
    for p in s["processes"]:
        lines.append(
            f"  {p['process']:10} {p['tests']:4d} tests  busy {p['busy_s']:6.1f} s  "
            f"CPU {p['cpu_s']:6.1f} s  last test ends at {p['last_end_s']:6.1f} s"
        )
    lines.append(
        "  JAX events in the test processes: "
        + ", ".join(
            f"{k} {v['s']:.0f} s ({v['count']})" for k, v in s["events"].items()
        )
    )
    rep = s.get("repeated_misses")
    if rep:
        lines.append(
            f"  persistent-cache misses {rep['misses']} ({rep['keys']} programs); "
            f"compiled again by another test process: {rep['extra_compiles']}"
        )
    lines.append("  largest programs (XLA compile):")
    for p in s["programs"][:8]:
        lines.append(
            f"    {p['compile_s']:6.1f} s  {p['compiles']:4d}x  {p['function']}"
        )
    lines.append("  longest tests (wall; compile, trace):")
    for t in s["tests"][:8]:
        lines.append(
            f"    {t['wall_s']:6.1f} s  ({t['compile_s']:5.1f}, {t['trace_s']:5.1f})  "
            f"{t['test']}"
        )
    cal = res.get("calibration")
    if cal:
        lines.append(
            f"calibration (tests/bench_chain.py, cold cache): CPU {cal['cpu_s']:.0f} s, "
            f"rc {cal['rc']}; suite CPU / calibration CPU = {res['cpu_ratio']:.2f}"
        )
    return "\n".join(lines)


def plot(res: dict, path: Path) -> None:
    """Per-module wall seconds (summed over workers) and the largest programs."""
    from smibjax.cli.plotting import save_figure, subplots

    s = res["suite"]
    fig, (a, b) = subplots(1, 2, figsize=(12, 5.5))
    mods = list(s["modules_wall_s"].items())[:15][::-1]
    a.barh([m.removeprefix("tests/") for m, _ in mods], [v for _, v in mods])
    a.set_xlabel("wall s, summed over the workers")
    a.set_title(
        f"suite {res['commit'][:8]}: {s['wall_s'] / 60:.1f} min wall, "
        f"{s['cpu_s']:.0f} CPU-s"
    )
    progs = s["programs"][:10][::-1]
    b.barh([p["function"] for p in progs], [p["compile_s"] for p in progs])
    b.set_xlabel("XLA compile s (all compiles of the function)")
    b.set_title("largest programs")
    fig.tight_layout()
    save_figure(fig, path)


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        commit = resolve(args.ref)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    sys.path.insert(0, str(HERE))
    from _common import result_name
    from _results import write_results

    with tempfile.TemporaryDirectory(prefix="smibjax-suite-time-") as tmp:
        suite = run_suite(commit, Path(tmp))
        res = {"commit": commit, "suite": suite}
        if args.calibrate:
            res["calibration"] = calibrate(commit, Path(tmp))
            res["cpu_ratio"] = suite["cpu_s"] / max(res["calibration"]["cpu_s"], 1e-9)
    print(report(res))
    name = result_name("suite_time", args.tag)
    config = {"ref": args.ref, "calibrate": args.calibrate, "cpus": os.cpu_count()}
    write_results(args.out, name, config, res)
    plot(res, Path(args.out) / f"{name}.png")
    print(f"wrote {Path(args.out) / name}.json and .png")
    return 0 if suite["rc"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
