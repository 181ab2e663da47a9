"""Shared fixtures. JAX compiles are the slow part of this suite: runs are shared per
session and the persistent compilation cache lives in .jax_cache/ (gitignored)."""

import os
import sys
from pathlib import Path

from smibjax.cli.process import configure_process

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("JAX_PLATFORMS", "cpu")
# The suite is an entry point like the CLI: float64, equinox's checks as NaNs (so the
# persistent cache in .jax_cache/ stores the simulator), one device unless the
# environment asks for more.
configure_process(host_devices=False, cache_dir=str(ROOT / ".jax_cache"))
sys.path.insert(0, str(Path(__file__).parent))

import pytest  # noqa: E402

import reference  # noqa: E402
import smibjax as sj  # noqa: E402

STABLE = {"beta1": -1.0, "beta2": -1.0}


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
