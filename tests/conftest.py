"""Shared fixtures (the shared helpers are in helpers.py). JAX compiles are the slow
part of this suite: runs are shared per session and the persistent compilation cache
lives in .jax_cache/ (gitignored)."""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from helpers import CACHE, STABLE  # noqa: E402
from smibjax import configure  # noqa: E402

os.environ.setdefault("JAX_PLATFORMS", "cpu")
# The suite is an entry point like the CLI: float64, equinox's checks as NaNs (so the
# persistent cache in .jax_cache/ stores the simulator), one host device. Both are set
# in the environment, not only in this process's JAX config: a test that calls a
# command's `main()` in process runs `smibjax.configure()` again, which reads them
# (without them it would move this worker's cache to ~/.cache/smibjax/jax and ask
# the environment of later processes for one device per core).
os.environ["SMIBJAX_CACHE_DIR"] = CACHE
# Every compiled program goes to the cache, also the one-operation programs of code
# run op by op (a grid case's power flow set-up: ~100 per case): the other worker,
# the command-line processes and the benchmark chains then read them instead of
# compiling them again (measured: IEEE 39's operating point and network matrices in
# a second process, 7.4 -> 3.3 CPU-s). Kept unless the environment sets it.
os.environ.setdefault("SMIBJAX_CACHE_MIN_COMPILE_S", "0")
if "--xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=1"
    ).strip()
configure(host_devices=False, cache_dir=CACHE)

import pytest  # noqa: E402

import reference  # noqa: E402
import smibjax as sj  # noqa: E402


def _whole_suite(config) -> bool:
    """The session runs every test of tests/test_benchmarks.py (no -k or -m filter,
    and the module or a folder above it among the arguments)."""
    if config.option.keyword or config.option.markexpr:
        return False
    here = Path(__file__).parent.resolve()
    args = [a.split("::")[0] for a in config.args] or ["."]
    for a in args:
        path = (Path(config.invocation_params.dir) / a).resolve()
        if path == here / "test_benchmarks.py" or path in (here, *here.parents):
            return True
    return False


def pytest_configure(config):
    """Under pytest-xdist, the controller (which runs no test) runs the benchmark
    scripts' tiny runs in the background from the start (`bench_chain`); the workers,
    started after this hook, inherit where they write."""
    if hasattr(config, "workerinput") or not config.getoption("numprocesses", None):
        return
    if not _whole_suite(config):
        return
    import tempfile

    import bench_chain

    folder = Path(tempfile.mkdtemp(prefix="smibjax-benchmarks-"))
    os.environ[bench_chain.ENV] = str(folder)
    config._bench_chains = bench_chain.start(folder, bench_chain.TINY)


def pytest_unconfigure(config):
    chains = getattr(config, "_bench_chains", None)
    if chains:
        import shutil

        import bench_chain

        for chain in chains:
            chain.stop()
        shutil.rmtree(chains[0].folder, ignore_errors=True)
        os.environ.pop(bench_chain.ENV, None)


def slow_tests() -> set[str]:
    """The test ids and modules of tests/slow_tests.txt (comments dropped)."""
    text = (Path(__file__).parent / "slow_tests.txt").read_text(encoding="utf-8")
    return {ln.split("#")[0].strip() for ln in text.splitlines()} - {""}


def pytest_collection_modifyitems(config, items):
    """The benchmark tests last: they wait for the background scripts. The tests
    tests/slow_tests.txt names get the `slow` marker (`python -m pytest -m "not
    slow"`: the quick subset; issue 50). To regenerate the list from a whole-suite
    profile (`benchmarks/suite_time.py`), take the tests of its JSON `suite.tests`
    whose `cpu_s + children_cpu_s` exceeds 2 s."""
    items.sort(
        key=lambda item: getattr(item.module, "__name__", "") == "test_benchmarks"
    )
    slow = slow_tests()
    for item in items:
        module = item.nodeid.split("::")[0]
        if item.nodeid in slow or module in slow:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def reference_runs():
    """Independent SciPy runs of MODEL.md, keyed like `jax_runs`."""
    return {
        "aftsc": reference.simulate(gains=STABLE, rtol=1e-9, atol=1e-11),
        "asc": reference.simulate(
            gains={**STABLE, "alpha": 1.0}, rtol=1e-9, atol=1e-11
        ),
    }


@pytest.fixture(scope="session")
def jax_runs():
    """The same cases through smibjax's default adaptive solver."""
    return {
        "aftsc": sj.simulate(sj.Gains.paper("aftsc", **STABLE)),
        "asc": sj.simulate(sj.Gains.paper("asc", **STABLE)),
    }


@pytest.fixture(scope="session")
def paper_run():
    """The paper's own gains and fault (loses synchronism)."""
    return sj.simulate(sj.Gains.paper("aftsc"))
