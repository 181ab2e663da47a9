"""Start-up of the command line (issue 32): `--help`, and a first and a second
`simulate` of the paper's fault and a first and a second short tuning run with one
empty compilation cache, each in a fresh process. Prints and saves wall seconds
and the CPU-seconds of each child process (on a loaded machine the CPU-seconds are
the figure to compare).

    python benchmarks/startup.py [--out benchmarks/results] [--no-tuner]

This script imports neither JAX nor smibjax (each run is its own process, which
configures itself); it writes the results with `_results.write_results` at the end.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
TINY = (
    "steps = 1\nbatch = 2\n[validation]\nn = 2\nevery = 1\nt_end = 3.0\n"
    "[train]\nt_end = 3.0\n"
)


def timed(argv: list[str], env: dict, cwd: Path) -> dict:
    """Wall seconds and CPU-seconds (user + sys) of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        sys.exit(f"{' '.join(argv)} failed:\n{r.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(HERE / "results"))
    p.add_argument("--no-tuner", action="store_true", help="skip the tuning runs")
    args = p.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="smibjax-startup-"))
    (tmp / "tiny.toml").write_text(TINY)
    env = {
        **os.environ,
        "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}",
        "SMIBJAX_CACHE_DIR": str(tmp / "cache"),
    }
    py = [sys.executable, "-m"]
    runs = {"help": timed([*py, "smibjax", "simulate", "--help"], env, tmp)}
    sim = [*py, "smibjax", "simulate", "--out", "run.npz", "--force"]
    runs["simulate_first"] = timed(sim, env, tmp)
    runs["simulate_second"] = timed(sim, env, tmp)
    if not args.no_tuner:
        tune = [*py, "tuning.optimize", "--config", "tiny.toml", "--quiet", "--out"]
        runs["tune_first"] = timed([*tune, "t1"], env, tmp)
        runs["tune_second"] = timed([*tune, "t2"], env, tmp)
    load = os.getloadavg()
    for k, v in runs.items():
        print(f"{k:16s} {v['wall_s']:8.2f} s wall {v['cpu_s']:8.2f} CPU-s")
    print(f"load average {load[0]:.1f} (wall times are loaded figures above ~2)")
    sys.path.insert(0, str(HERE))
    from smibjax import configure

    configure(cache=False)
    from _results import write_results

    path = write_results(
        args.out,
        "startup",
        {"tiny_tuning_config": TINY, "load_average": load[0]},
        {"runs": runs},
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
