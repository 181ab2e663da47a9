"""Monte Carlo chunks on Dask (issue 7): a real LocalCluster of 2 worker processes gives
the in-process rows, also when a worker process is killed during the run."""

import json
import os
import signal
import sys

import jax
import numpy as np
import pytest

import smibjax as sj
from smibjax._montecarlo import MonteCarloSpec
from smibjax.cli.runs import read_rows, run_montecarlo

pytest.importorskip("distributed")

from smibjax.cli.cluster import chunk_key, dask_runner  # noqa: E402

# one worker holds the module's LocalCluster
pytestmark = pytest.mark.xdist_group("cluster")
GAINS = sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0)
# 6 chunks of 4 (a vmapped batch of one scenario gives slightly different rows from a
# batch of several, so each device slice holds at least 2 here and in the workers).
SPEC = MonteCarloSpec(
    n=24,
    chunk=4,
    gains={name: float(getattr(GAINS, name)) for name in sj.GAIN_NAMES},
    t_end=3.0,
)


def _csv(path) -> list[str]:
    return (path / "scenarios.csv").read_text().splitlines()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The in-process run of SPEC (its scenarios.csv lines)."""
    assert SPEC.chunk // len(jax.devices()) >= 2
    out = tmp_path_factory.mktemp("mc") / "in-process"
    run_montecarlo(SPEC, out, plots=False, progress=False)
    return _csv(out)


@pytest.fixture(scope="module")
def runner():
    """A LocalCluster of 2 single-threaded worker processes, shared by the tests."""
    with dask_runner(workers=2) as r:
        yield r


def _recording(runner, seen, kill_after_first=False):
    """`runner`, recording every chunk index it yields; with `kill_after_first`, SIGKILL
    a worker process that is computing a chunk when the first result arrives."""
    info = {}

    def run(spec, chunks):
        pids = runner.client.run(os.getpid)  # worker address -> process id
        it = runner(spec, chunks)
        for i, (k, rows) in enumerate(it):
            if kill_after_first and i == 0:
                busy = [a for a, keys in runner.client.processing().items() if keys]
                victim = busy[0] if busy else sorted(pids)[0]
                info["victim"], info["busy"] = pids[victim], bool(busy)
                os.kill(pids[victim], signal.SIGKILL)
            seen.append(k)
            yield k, rows

    return run, info


def test_local_cluster_matches_in_process(reference, runner, tmp_path):
    assert len(runner.client.scheduler_info()["workers"]) == 2
    devices = runner.client.run(lambda: (len(jax.devices()), jax.config.jax_enable_x64))
    assert sorted(devices.values()) == [(1, True), (1, True)]
    seen = []
    run, _ = _recording(runner, seen)
    rows, summary = run_montecarlo(
        SPEC, tmp_path / "dask", runner=run, plots=False, progress=False
    )
    assert sorted(seen) == list(range(SPEC.n_chunks))
    assert _csv(tmp_path / "dask") == reference
    assert np.array_equal(rows["index"], np.arange(SPEC.n))
    assert summary["n"] == SPEC.n


def test_killed_worker_loses_nothing(reference, runner, tmp_path):
    seen = []
    run, info = _recording(runner, seen, kill_after_first=True)
    run_montecarlo(SPEC, tmp_path / "dask", runner=run, plots=False, progress=False)
    assert info["busy"], "no worker was computing a chunk when the first one arrived"
    # every chunk exactly once, rows equal to the in-process run
    assert sorted(seen) == list(range(SPEC.n_chunks))
    assert _csv(tmp_path / "dask") == reference
    assert np.array_equal(
        read_rows(tmp_path / "dask" / "scenarios.csv")["index"], np.arange(SPEC.n)
    )
    # the nanny restarted the killed worker process
    runner.client.wait_for_workers(2)
    assert info["victim"] not in runner.client.run(os.getpid).values()


def test_chunk_keys_are_deterministic():
    assert chunk_key(SPEC, 3) == chunk_key(MonteCarloSpec.from_dict(SPEC.to_dict()), 3)
    assert chunk_key(SPEC, 3) != chunk_key(SPEC, 4)
    other = MonteCarloSpec.from_dict({**SPEC.to_dict(), "seed": 1})
    assert chunk_key(SPEC, 3) != chunk_key(other, 3)


def test_missing_extra(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    msg = "--workers/--scheduler need the cluster extra: pip install 'smibjax[cluster]'"
    with pytest.raises(sj.ParameterError) as e:
        with dask_runner(workers=2):
            pass
    assert str(e.value) == msg
    from smibjax.cli import main

    out = tmp_path / "mc"
    assert main(["montecarlo", "--n", "4", "--workers", "2", "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip() == f"smibjax: error: {msg}"
    assert not out.exists()


def test_bad_scheduler_address_is_one_line(tmp_path, capsys):
    from smibjax.cli import main

    out = tmp_path / "o"
    assert (
        main(["montecarlo", "--n", "4", "--scheduler", "nonsense::", "--out", str(out)])
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot connect to a Dask scheduler" in err
    assert main(["montecarlo", "--n", "4", "--workers", "0", "--out", str(out)]) == 2
    assert "--workers 0 is not allowed" in capsys.readouterr().err


def test_workers_end_to_end_finishes_an_interrupted_run(reference, tmp_path, capsys):
    """`montecarlo --workers 2 --resume` (its own LocalCluster, from the command line)
    finishes a run whose last chunks were lost: only those are computed, the chunk
    files already there are kept as they are, and the rows equal the uninterrupted
    in-process run's (SPEC's), line for line."""
    from smibjax.cli import main

    argv = ["montecarlo", "--n", "24", "--chunk", "4", "--t-end", "3"]
    argv += ["--set", "beta1=-1", "--set", "beta2=-1"]
    part = tmp_path / "part"
    assert main([*argv, "--out", str(part)]) == 0
    assert _csv(part) == reference  # the command's run is SPEC's
    kept = {k: (part / "chunks" / f"{k:06d}.npz").stat().st_mtime_ns for k in (0, 1)}
    for k in range(2, 6):  # "killed" after two chunks
        (part / "chunks" / f"{k:06d}.npz").unlink()
    (part / "scenarios.csv").unlink()
    capsys.readouterr()
    assert main([*argv, "--workers", "2", "--resume", "--out", str(part)]) == 0
    assert " of 24 (" in capsys.readouterr().out  # the summary of all 24 rows
    assert _csv(part) == reference
    for k, mtime in kept.items():
        assert (part / "chunks" / f"{k:06d}.npz").stat().st_mtime_ns == mtime
    sessions = __import__("json").loads((part / "run.json").read_text())["sessions"]
    assert sessions[-1]["scenarios_computed"] == 16  # chunks 2-5 only


def test_grid_montecarlo_on_workers_finishes_a_run_with_the_in_process_rows(
    tmp_path, capsys
):
    """`montecarlo --case --workers 2 --resume` (issue 44): each worker rebuilds the
    case from the run's context and computes the chunks it is given; the chunks
    written before are kept, and the rows equal the uninterrupted in-process run's,
    line for line."""
    from smibjax.cli import main

    argv = ["montecarlo", "--case", "kundur-gencls", "--n", "6", "--chunk", "2"]
    argv += ["--t-end", "1.5", "--seed", "3"]
    ref = tmp_path / "ref"
    assert main([*argv, "--out", str(ref)]) == 0
    part = tmp_path / "part"
    assert main([*argv, "--out", str(part)]) == 0
    kept = (part / "chunks" / "000000.npz").stat().st_mtime_ns
    for k in (1, 2):  # "killed" after the first chunk: only it and run.json
        (part / "chunks" / f"{k:06d}.npz").unlink()
    for f in part.iterdir():
        if f.is_file() and f.name != "run.json":
            f.unlink()
    manifest = json.loads((part / "run.json").read_text())
    (part / "run.json").write_text(json.dumps(manifest | {"complete": False}))
    capsys.readouterr()
    assert main([*argv, "--workers", "2", "--resume", "--out", str(part)]) == 0
    err = capsys.readouterr().err
    assert "in each Dask worker" in err
    assert _csv(part) == _csv(ref)
    assert (part / "chunks" / "000000.npz").stat().st_mtime_ns == kept
    rows = _csv(ref)
    assert len(rows) == 7 and "fault_bus" in rows[0]
