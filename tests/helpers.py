"""Helpers the test modules share (import them with `from helpers import ...`; the
tests folder is on sys.path): the repository's folders, the suite's compilation
cache and the environment of its command-line processes, the stable gains the tests
run, and per-case random generators.

Nothing here imports JAX or smibjax: conftest.py configures the process first.
"""

from __future__ import annotations

import os
import zlib
from pathlib import Path

import numpy as np

__all__ = ["ROOT", "CACHE", "STABLE", "cli_env", "case_rng"]

ROOT = Path(__file__).resolve().parents[1]
CACHE = str(ROOT / ".jax_cache")

# beta1 = beta2 = -1: gains under which the paper's fault is survived and settles
STABLE = {"beta1": -1.0, "beta2": -1.0}


def cli_env() -> dict:
    """The environment of the suite's command-line processes: the suite's compilation
    cache, and one host device like this process, so that a process runs the programs
    this one compiled (found in the cache) and gives this process's numbers."""
    return {
        **os.environ,
        "SMIBJAX_CACHE_DIR": CACHE,
        "SMIBJAX_CACHE_MIN_COMPILE_S": os.environ.get(
            "SMIBJAX_CACHE_MIN_COMPILE_S", "0"
        ),
        "XLA_FLAGS": "--xla_force_host_platform_device_count=1",
    }


def case_rng(*case) -> np.random.Generator:
    """A NumPy generator seeded by the case itself (e.g. the test's name and its
    parameters): a failing case draws the same numbers whichever worker runs it and
    whatever ran before it, and reruns alone (`pytest -k`) with them."""
    return np.random.default_rng(zlib.crc32(repr(case).encode()))
