"""The benchmark scripts' tiny runs (benchmarks/NAME.py, and one study,
studies/stiff_solvers/), one after another in two background threads (`LANES`).

Under pytest-xdist the chains run in the controller process, which runs no tests:
they start at the beginning of the session (`conftest.pytest_configure`), beside the
workers, and the tests of tests/test_benchmarks.py (collected last) only wait for
their results. Without xdist, the module's own fixture starts them. Every script uses
the suite's persistent compilation cache, so a later script finds what an earlier one
compiled (throughput and vs_scipy run the same engine at t_end 1.3 s and a batch of
4).

A script's folder holds log.txt, its outputs, and `rc` (its exit status, written last).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
STUDIES = ROOT / "studies"
ENV = "SMIBJAX_BENCH_DIR"  # where the controller's chain writes (set for the workers)
# no time limit: a script runs until it ends (on a loaded machine the tuning_grid
# run took longer than the 600 s this once allowed, and was killed: issue 50); a
# script that hangs is for the CI job's own limit to end

# script -> tiny command-line arguments, in the order they run
TINY = {
    # two devices only: the sharded path is the script's own (one device is every
    # other test's engine); "1 2" costs 32 CPU-s cold, "2" 25 (2026-12-03)
    "throughput": [
        "--batches",
        "4",
        "--devices",
        "2",
        "--n-check",
        "1",
        "--t-end",
        "1.3",  # every sampled fault (up to 1.0 s + 0.25 s) clears within the run
        "--repeat",
        "1",
    ],
    "vs_scipy": [
        "--n-scipy",
        "1",
        "--batch",
        "4",
        "--devices",
        "2",
        "--t-end",
        "1.3",  # throughput's horizon and batch: its compiled engine
        "--repeat",
        "1",
    ],
    # montecarlo and cluster_scaling: tests/test_cluster.py's chunk of 4 and horizon
    # (3 s), with the suite's cache (the scripts turn it on where SMIBJAX_CACHE_DIR
    # is set): cluster_scaling's in-process runs read montecarlo's programs, and its
    # Dask worker's program is test_cluster's workers' (one device each)
    "montecarlo": ["--n", "8", "--chunk", "4", "--t-end", "3"],
    "cluster_scaling": ["--n", "8", "--chunk", "4", "--t-end", "3", "--workers", "1"]
    + ["--roundtrips", "3"],
    "stiff_solvers": ["--methods", "RK45", "Radau", "--t-end", "1.0"],
    "compile": ["--cases", "simulate", "--repeat", "1", "--t-end", "0.8"],
    # paper.toml's training (1 ms grid, the 1e-3 training layer since 2026-12-02) on
    # tests/test_tuning.py's tiny run shape (batch 2, 3 s), with the suite's one host
    # device (`ONE_DEVICE`): its value-and-grad program is then the paper-step tests'
    # (`PAPER_STEP`, the same key in the persistent cache; measured 2026-12-02:
    # test_paper_config_first_steps_are_pinned 25.3 CPU-s cold, 16.2 after this run).
    # Relative errors of the central differences at this shape (d/d T2 0.29, d/d
    # gamma2 0.033): eps 5e-6: 6e-5, 9.3e-4; 2e-6: 9.1e-5, 1.5e-3; 1e-6: 2.8e-4,
    # 3.7e-4, at least 27x inside the test's 1e-2
    "gradients": ["--batch", "2", "--t-end", "3", "--repeat", "1"]
    + ["--fd-eps", "1e-6"],
    # the tiny SMIB + SEXS + IEEEST case of the tuner's tests: 4 training simulations
    # per tuner, 3 held-out faults. Kundur's cost 127 CPU-s cold, this 70-85. Run
    # with the suite's one host device (`ONE_DEVICE`): its gradient run's programs are
    # then tests/test_tuning_grid.py's tiny run's (the same keys in the persistent
    # cache), and whichever runs second reads them (jit_loss: 27 s of XLA compile)
    "tuning_grid": ["--config", "tests/data/grid_tuning/tiny.toml"]
    + ["--steps", "2", "--batch", "2", "--n", "3", "--popsize", "2"],
}


# two chains side by side: the engine scripts (which share a compiled engine, in this
# order) and the others. At the end of a session the workers are idle while the
# chain's last scripts run; two chains leave less to run then. tuning_grid first: its
# programs are the grid tuner tests' (`ONE_DEVICE`), which then read them (the tests
# of tests/test_tuning_grid.py run late in a session). montecarlo and cluster_scaling
# first in theirs: cluster_scaling's Dask worker compiles tests/test_cluster.py's
# workers' program (an early module; when it runs first, its two workers compile it
# side by side and the script reads it).
LANES = (
    ("montecarlo", "cluster_scaling", "throughput", "vs_scipy"),
    ("tuning_grid", "gradients", "compile", "stiff_solvers"),
)

# Scripts that run with the suite's one host device (conftest's XLA_FLAGS) instead of
# their own one per core: JAX's persistent-cache key holds the XLA flags (one device
# per core comes with --xla_cpu_multi_thread_eigen=false) and the devices' topology,
# so a program compiled in a process with 2 host devices is never found by one with 1
# (measured 2026-12-02: benchmarks/tuning_grid.py's training step, the same module
# text, missed test_tuning_grid's entry with 2 devices and hit it with 1). The grid
# tuner runs on one device either way; gradients.py's batch of 2 is one slice on one
# device (its JSON's figures are then one core's).
ONE_DEVICE = frozenset({"tuning_grid", "gradients"})


def script(name: str) -> Path:
    """The script of `name` (a key of `TINY`): benchmarks/NAME.py, else the study's
    studies/NAME/NAME.py."""
    path = BENCH / f"{name}.py"
    return path if path.is_file() else STUDIES / name / f"{name}.py"


def start(folder: Path, names) -> list[Chain]:
    """Start `names` (keys of `TINY`) as up to two chains (`LANES`) into `folder`."""
    lanes = [[n for n in lane if n in names] for lane in LANES]
    lanes[0] += [n for n in names if not any(n in lane for lane in LANES)]
    return [Chain(folder, lane).start() for lane in lanes if lane]


class Chain:
    """Runs `names` (keys of `TINY`) one at a time into `folder`/NAME/."""

    def __init__(self, folder: Path, names):
        self.folder, self.names = Path(folder), list(names)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._proc: subprocess.Popen | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> Chain:
        self._thread.start()
        return self

    def _run(self) -> None:
        # the scripts choose their own host devices (one per core, at least two): not
        # the suite's one (conftest puts it in the environment)
        flags = re.sub(
            r"--xla_force_host_platform_device_count=\S+",
            "",
            os.environ.get("XLA_FLAGS", ""),
        ).strip()
        env = {
            **os.environ,
            "SMIBJAX_CACHE_DIR": str(ROOT / ".jax_cache"),
            "MPLBACKEND": "Agg",
            "XLA_FLAGS": flags,
        }
        one_device = {
            **env,
            "XLA_FLAGS": f"{flags} --xla_force_host_platform_device_count=1".strip(),
        }
        for name in self.names:
            out = self.folder / name
            out.mkdir(parents=True, exist_ok=True)
            with open(out / "log.txt", "w") as log:
                with self._lock:
                    if self._stop.is_set():
                        return
                    self._proc = subprocess.Popen(
                        [sys.executable, str(script(name)), *TINY[name]]
                        + ["--out", str(out)],
                        cwd=ROOT,
                        env=one_device if name in ONE_DEVICE else env,
                        stdout=log,
                        stderr=subprocess.STDOUT,
                    )
                rc = self._proc.wait()
            tmp = out / "rc.tmp"
            tmp.write_text(str(rc))
            tmp.replace(out / "rc")

    def stop(self) -> None:
        """Kill the running script and start no other."""
        with self._lock:
            self._stop.set()
            if self._proc is not None and self._proc.poll() is None:
                self._proc.kill()
                self._proc.wait()
        self._thread.join(timeout=30)


def wait(folder: Path, name: str) -> tuple[int, Path]:
    """(exit status, folder) of script `name` once the chain has run it (however
    long that takes: no test depends on wall time)."""
    out = Path(folder) / name
    while not (out / "rc").is_file():
        time.sleep(0.2)
    return int((out / "rc").read_text()), out


def timing_line(name: str, rc: int, wall: float, cpu: float) -> str:
    """One script's line of `_time_each` (benchmarks/suite_time.py parses it)."""
    return f"{name:16} rc {rc}  wall {wall:6.1f} s  cpu {cpu:6.1f} s"


def _time_each(cache: str) -> None:
    """Run the tiny scripts one after another (not side by side) with the compilation
    cache in `cache` and print each one's wall and CPU seconds (docs/performance.md's
    figures: `python tests/bench_chain.py /tmp/empty-cache`)."""
    import resource
    import tempfile

    env = {**os.environ, "SMIBJAX_CACHE_DIR": cache, "MPLBACKEND": "Agg"}
    env.pop("XLA_FLAGS", None)
    with tempfile.TemporaryDirectory(prefix="smibjax-bench-time-") as tmp:
        for name in [n for lane in LANES for n in lane]:
            r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.monotonic()
            cmd = [sys.executable, str(script(name)), *TINY[name]]
            rc = subprocess.run(
                [*cmd, "--out", str(Path(tmp) / name)],
                cwd=ROOT,
                env=env,
                capture_output=True,
            ).returncode
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime
            print(timing_line(name, rc, time.monotonic() - t0, cpu), flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/bench_chain.py CACHE_DIR")
    _time_each(sys.argv[1])
