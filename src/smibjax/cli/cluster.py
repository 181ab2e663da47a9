"""Monte Carlo chunks on Dask distributed (`--workers N`, `--scheduler ADDRESS`).

`dask_runner` is a context manager yielding a runner for `run_montecarlo`: one Dask task
per chunk, keyed by the run's spec and the chunk index, results streamed back as they
complete (the client writes them to `chunks/`, so `--resume` and the progress bar work
as in the single-process run). Only the `MonteCarloSpec` (plain numbers) and the chunk
index travel; the task, `_run_chunk`, calls `compute_chunk(spec, k)` in the worker, whose
jitted engine is cached per process: each worker compiles once and reuses the compiled
simulator for every later chunk of the same solver configuration. A chunk is a pure
function of (spec, k), so a retry or a duplicate gives the same rows: a worker that dies
mid-chunk costs a rerun of that chunk on another worker (the scheduler reschedules the
tasks of a lost worker up to `distributed.scheduler.allowed-failures` times; a task that
raises is retried `retries` times), and the rows equal those of the in-process run.

`--workers N` starts a `LocalCluster` of N worker processes with one thread each, JAX on
the CPU, one XLA host device per worker and single-threaded Eigen (`worker_env`), so N
workers on N cores do not oversubscribe. With `--scheduler`, start the workers with the
same environment, one process and one thread per core, for example:

    XLA_FLAGS="--xla_force_host_platform_device_count=1 --xla_cpu_multi_thread_eigen=false" \\
    OMP_NUM_THREADS=1 JAX_PLATFORMS=cpu \\
    dask worker tcp://SCHEDULER:8786 --nworkers $(nproc) --nthreads 1

(`dask scheduler` starts the scheduler; every worker needs the same smibjax and JAX
versions as the client: the task is sent by reference to `smibjax.cli.cluster._run_chunk`.)
Dask is an optional extra: `pip install 'smibjax[cluster]'`.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
from collections.abc import Iterable, Iterator

from .._montecarlo import MonteCarloSpec, compute_chunk
from .._parameters import ParameterError

__all__ = ["DaskRunner", "dask_runner", "chunk_key", "worker_env", "run_grid_chunk"]

_MISSING = (
    "--workers/--scheduler need the cluster extra: pip install 'smibjax[cluster]'"
)

# XLA flags of a worker process: one host device, Eigen on the calling thread only.
_WORKER_XLA_FLAGS = (
    "--xla_force_host_platform_device_count=1",
    "--xla_cpu_multi_thread_eigen=false",
)


def _distributed():
    """The `distributed` module, or ParameterError naming the extra to install."""
    try:
        import distributed
    except ImportError:
        raise ParameterError(_MISSING) from None
    return distributed


def worker_env() -> dict[str, str]:
    """Environment of a local worker process: JAX on the CPU in 64-bit mode, one XLA host
    device, single-threaded Eigen/OpenMP/BLAS, the client's other XLA flags and its
    persistent compilation cache folder (if any)."""
    kept = [
        f
        for f in os.environ.get("XLA_FLAGS", "").split()
        if not f.startswith(tuple(x.split("=")[0] for x in _WORKER_XLA_FLAGS))
    ]
    env = {
        "XLA_FLAGS": " ".join([*kept, *_WORKER_XLA_FLAGS]),
        "JAX_PLATFORMS": "cpu",
        "JAX_ENABLE_X64": "1",
        "EQX_ON_ERROR": os.environ.get("EQX_ON_ERROR", "nan"),
        "OMP_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
    }
    try:
        import jax

        cache = jax.config.jax_compilation_cache_dir
    except Exception:  # pragma: no cover - unusual JAX builds
        cache = None
    cache = cache or os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if cache:
        env["JAX_COMPILATION_CACHE_DIR"] = str(cache)
    return env


@functools.lru_cache(maxsize=1)
def _setup_worker() -> None:
    """Once per worker process, before its first chunk: apply the environment's JAX
    settings, which JAX reads when it is imported (a spawned worker may import it, via
    its parent's main module, before the nanny sets the worker's environment)."""
    import jax

    from .._process import configure

    cache = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    configure(
        host_devices=False,
        cache=bool(cache) and not jax.config.jax_compilation_cache_dir,
        cache_dir=cache,
    )
    platforms = os.environ.get("JAX_PLATFORMS")
    if platforms and jax.config.jax_platforms != platforms:
        jax.config.update("jax_platforms", platforms)


def _run_chunk(spec: MonteCarloSpec, k: int) -> dict:
    """The Dask task: the rows of chunk k, computed in the worker process."""
    _setup_worker()
    return compute_chunk(spec, k)


def run_grid_chunk(job, k: int) -> dict:
    """The grid's Dask task: the rows of chunk k of a `grid.montecarlo.GridChunkJob`,
    computed in the worker process (its case rebuilt there once)."""
    from ..grid.montecarlo import grid_chunk

    _setup_worker()
    return grid_chunk(job, k)


def chunk_key(spec: MonteCarloSpec, k: int) -> str:
    """The Dask key of chunk k of `spec`: the same in every process and session, so a
    resubmitted chunk is the same task."""
    text = json.dumps(spec.to_dict(), sort_keys=True, separators=(",", ":"))
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    return f"smibjax-mc-{digest}-s{spec.seed}-{k}"


class DaskRunner:
    """A Monte Carlo runner on a Dask `client`: `runner(spec, chunks)` submits one
    task per chunk and yields `(k, rows)` as tasks complete (any order). `task(spec,
    k)` computes a chunk in a worker: the SMIB's `compute_chunk` by default, or
    `run_grid_chunk` for a grid job (`grid.montecarlo.GridChunkJob`) as `spec`."""

    def __init__(self, client, retries: int = 3, task=None):
        self.client = client
        self.retries = retries
        self.task = _run_chunk if task is None else task

    def __call__(
        self, spec: MonteCarloSpec, chunks: Iterable[int]
    ) -> Iterator[tuple[int, dict]]:
        as_completed = _distributed().as_completed
        chunks = list(chunks)
        futures = {}
        for k in chunks:
            fut = self.client.submit(
                self.task,
                spec,
                k,
                key=chunk_key(spec, k),
                retries=self.retries,
                priority=-k,  # earlier chunks first
            )
            futures[fut.key] = (k, fut)
        if not futures:
            return
        try:
            for fut in as_completed([f for _, f in futures.values()]):
                k, _ = futures.pop(fut.key)
                rows = fut.result()
                fut.release()
                yield k, rows
        finally:
            left = [f for _, f in futures.values()]
            if left:
                self.client.cancel(left)


@contextlib.contextmanager
def dask_runner(
    scheduler: str | None = None,
    workers: int | None = None,
    *,
    retries: int = 3,
    task=None,
) -> Iterator[DaskRunner]:
    """A runner on Dask: `workers=N` starts a local cluster of N single-threaded worker
    processes (closed on exit; 1 <= N <= the CPU count); `scheduler=ADDRESS`
    connects to a running scheduler. The runner's `client` is the
    `distributed.Client`; `task` as `DaskRunner`'s."""
    if (scheduler is None) == (workers is None):
        raise ParameterError("give a Dask scheduler address or a number of workers")
    cpus = os.cpu_count() or 1
    if workers is not None and (
        not isinstance(workers, int) or isinstance(workers, bool) or workers < 1
    ):
        raise ParameterError(f"workers = {workers!r} is not allowed: must be >= 1")
    if workers is not None and workers > cpus:
        raise ParameterError(
            f"workers = {workers} is not allowed: must be at most {cpus} (the CPU "
            "count: more single-threaded processes than cores only oversubscribe them)"
        )
    distributed = _distributed()
    with contextlib.ExitStack() as stack:
        if workers is not None:
            cluster = stack.enter_context(
                distributed.LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    env=worker_env(),
                    dashboard_address=None,
                )
            )
            client = stack.enter_context(distributed.Client(cluster))
        else:
            try:
                client = stack.enter_context(distributed.Client(scheduler, timeout=20))
            except (OSError, ValueError, TypeError) as e:  # unreachable or malformed
                raise ParameterError(
                    f"--scheduler {scheduler!r}: cannot connect to a Dask scheduler "
                    f"there ({type(e).__name__}: {e})"
                ) from None
        yield DaskRunner(client, retries=retries, task=task)
