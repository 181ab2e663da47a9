"""Process set-up: what a program using smibjax sets once, before it computes.

Importing smibjax sets nothing; `smibjax.configure` sets what the command line
(`python -m smibjax`), the tuner (`python -m tuning.optimize`), the Dask workers, the
benchmarks and the test suite set before they compute anything: host devices,
float64, equinox's error mode and the compilation cache. A library user may call it
too, or set at least JAX's 64-bit mode.

This module imports neither JAX nor equinox at module level, so that `configure` can
run before they load.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = [
    "configure",
    "enable_compilation_cache",
    "use_host_devices",
    "cache_state",
]


def use_host_devices(minimum: int = 1) -> None:
    """Ask XLA for one CPU host device per core (at least `minimum`), each without
    intra-op threads on top (measured: AFTSC at batch 4096 on 2 devices, 314 -> 354
    scenarios/s). Takes effect only before JAX starts its CPU backend (its first
    computation); a device count already in XLA_FLAGS is respected."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "--xla_force_host_platform_device_count" in flags:
        return
    n = max(os.cpu_count() or 1, minimum)
    os.environ["XLA_FLAGS"] = (
        f"{flags} --xla_force_host_platform_device_count={n}"
        " --xla_cpu_multi_thread_eigen=false"
    ).strip()


CACHE_PROBLEM: str | None = None
"""Why the compilation cache asked for is off (a path that is not a writable
folder), or None: `cache_state` says it on the phase line before a compile."""


def enable_compilation_cache(path: str | None = None) -> str | None:
    """Turn on JAX's persistent compilation cache in `path` (default:
    $SMIBJAX_CACHE_DIR, else ~/.cache/smibjax/jax; an empty SMIBJAX_CACHE_DIR turns
    it off). Programs that took at least $SMIBJAX_CACHE_MIN_COMPILE_S seconds to
    compile (default 0.1: the simulator, and the command line's metrics program,
    0.3 s) are kept, so a new process skips XLA compilation (tracing
    still runs). 0 keeps every program, also the one-operation programs of code run
    op by op outside `jit` (a power flow's set-up: about a hundred of them per case),
    at the cost of many small files: the test suite's setting, where every worker
    and command-line process would otherwise compile them again. Returns the
    folder."""
    import jax

    if path is None:
        path = os.environ.get(
            "SMIBJAX_CACHE_DIR", str(Path.home() / ".cache" / "smibjax" / "jax")
        )
    global CACHE_PROBLEM
    CACHE_PROBLEM = None
    if path and not _usable_folder(Path(path)):
        # said on the phase line before the first compile (`cache_state`), not now:
        # a command that refuses its input then still prints one line
        CACHE_PROBLEM = (
            f"{str(path)!r} is not a writable folder, running without it; set "
            "SMIBJAX_CACHE_DIR to a folder, or to '' to turn the cache off"
        )
        return None
    if path:
        jax.config.update("jax_compilation_cache_dir", str(path))
        jax.config.update(
            "jax_persistent_cache_min_compile_time_secs", _min_compile_s()
        )
    return path or None


def _min_compile_s() -> float:
    """$SMIBJAX_CACHE_MIN_COMPILE_S as a number of seconds >= 0 (default 0.1)."""
    text = os.environ.get("SMIBJAX_CACHE_MIN_COMPILE_S", "").strip()
    if not text:
        return 0.1
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value >= 0 or value == float("inf"):
        from ._validate import ParameterError

        raise ParameterError(
            f"SMIBJAX_CACHE_MIN_COMPILE_S = {text!r} is not allowed: must be a "
            "number of seconds >= 0"
        )
    return value


def _usable_folder(p: Path) -> bool:
    """`p` is a writable folder, or can be made as one (the nearest existing path
    above it is a writable folder)."""
    here = p
    while not here.exists() and here != here.parent:
        here = here.parent
    return here.is_dir() and os.access(here, os.W_OK | os.X_OK)


def configure(
    *,
    host_devices: bool = True,
    min_devices: int = 1,
    cache: bool = True,
    cache_dir: str | None = None,
) -> None:
    """Set up this process for smibjax (what its entry points call first):

    - `EQX_ON_ERROR=nan` unless already set, if equinox is not loaded yet. Equinox
      turns runtime checks into host callbacks, and XLA's persistent compilation
      cache refuses programs with host callbacks. The only such checks in smibjax's
      compiled graphs are diffrax's argument checks (save times ordered and inside
      [t0, t1], jump times ordered), which smibjax's validated inputs always satisfy;
      as NaN-on-failure checks they compile without callbacks, so the cache can store
      the simulator (first call in a new process: seconds instead of tens of
      seconds).
    - one XLA host device per core, at least `min_devices` (`host_devices`;
      `use_host_devices`), before JAX starts its CPU backend;
    - JAX's 64-bit mode (the closed loop is stiff and the finite-time law works near
      phi = 0, where float32 is not enough);
    - the persistent compilation cache (`cache`; `enable_compilation_cache`).
    """
    if "equinox" not in sys.modules:
        os.environ.setdefault("EQX_ON_ERROR", "nan")
    if host_devices:
        use_host_devices(min_devices)
    import jax

    jax.config.update("jax_enable_x64", True)
    if cache:
        enable_compilation_cache(cache_dir)


def cache_state(*programs: str) -> str:
    """The persistent compilation cache as seen before a compile: "off" (no cache
    folder configured; with the reason where the folder asked for was not usable),
    "warm" (the folder holds an entry of one of `programs`, the names JAX gives the
    jitted functions, e.g. "jit__simulate"; a call with other shapes or options still
    compiles), else "cold"."""
    import jax

    folder = jax.config.jax_compilation_cache_dir
    if not folder:
        return "off" if CACHE_PROBLEM is None else f"off: {CACHE_PROBLEM}"
    try:
        names = os.listdir(folder)
    except OSError:
        return "cold"
    prefixes = tuple(f"{p}-" for p in programs)
    return "warm" if any(n.startswith(prefixes) for n in names) else "cold"
