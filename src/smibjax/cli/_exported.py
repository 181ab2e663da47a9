"""The command line's warm start: `simulate`'s program and its summary's program
stored with `jax.export` (StableHLO), so that a second identical `python -m smibjax
simulate` neither traces them nor loads the solver (diffrax, optimistix, lineax).

`run` checks its inputs as `simulate` does (`simulate_inputs`), then looks for a
stored pair of programs under a key made of everything that determines them: the
controller's and parameter sets' structure (the static fields included) and their
arrays' shapes and dtypes, the horizon, sampling interval and solver options, the
versions of JAX, jaxlib, equinox, diffrax, lineax and optimistix, equinox's error
mode and a hash of smibjax's source files. On a hit it calls the stored programs
(the compiled executables come from JAX's persistent compilation cache, whose
folder holds the stored programs too, under `smibjax-exported/`). On a miss it
traces and exports them, stores them atomically for next time and calls them; on
any error (an unreadable file, a program JAX cannot export) it runs the library's
traced path, silently. The two paths compute the same programs: their results are
equal bit for bit (tests/test_startup.py).

Set SMIBJAX_EXPORTED=0 to always take the traced path.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import struct
from pathlib import Path
from types import SimpleNamespace

__all__ = ["run", "observe", "LAST_PATH"]

FORMAT = b"smibjax-exported/1\n"
FOLDER = "smibjax-exported"
LAST_PATH: str | None = None
"""How the last `run` in this process computed: "stored" (a stored program),
"exported" (traced, exported and stored now), "traced" (the library's path)."""

_SOURCE_HASH: str | None = None


def observe(traj):
    """(metrics, arrays) of a trajectory: `metrics` and the npz/plot arrays
    (`trajectory_arrays`), as JAX values: the summary's program, traced in one
    jitted function (run eagerly, its ~100 small operations compiled one kernel
    each: 1.1 s of CPU per `simulate`)."""
    from .._metrics import metrics
    from .plotting import trajectory_arrays

    return metrics(traj), trajectory_arrays(traj, numpy=False)


def run(gains, fault, plant, op, init, solver, save):
    """One `simulate` run with the library's defaults for the rest (adaptation as
    the controller has it, delta band, hard input limits) and its summary's
    program: (trajectory, metrics, arrays). `trajectory` has the attributes of a
    `Trajectory` (a `Trajectory` on the traced path), `metrics` those of a
    `Metrics` with NumPy values, `arrays` the npz layout as NumPy arrays. Bad
    input raises `ParameterError` before anything is computed, as `simulate` does."""
    global LAST_PATH
    from .._inputs import simulate_inputs

    inputs = simulate_inputs(gains, fault, plant, op, init, None, solver, save)
    folder = _folder()
    if folder is not None:
        try:
            out = _run_stored(folder, inputs)
        except Exception:  # any failure: the traced path answers
            out = None
        if out is not None:
            return out
    LAST_PATH = "traced"
    return _traced(inputs)


def _folder() -> Path | None:
    """The folder of the stored programs, inside the compilation cache's folder;
    None when the cache is off or SMIBJAX_EXPORTED=0."""
    import jax

    if os.environ.get("SMIBJAX_EXPORTED", "1").strip() == "0":
        return None
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / FOLDER if cache else None


def _traced(inputs):
    """The library's path: `simulate` (traced, compiled or loaded from the
    persistent cache) and the summary's program, jitted."""
    import jax
    import numpy as np

    from .._simulate import _simulate

    controller, fault, plant, op, init, solver, save = inputs
    traj = _simulate(controller, fault, plant, op, init, **_statics(solver, save))
    m, arrays = jax.jit(observe)(traj)
    m = jax.tree_util.tree_map(jax.device_get, m)
    return traj, m, {k: np.asarray(v) for k, v in arrays.items()}


def _statics(solver, save) -> dict:
    """`_simulate`'s static keywords, as `simulate` passes them for the command
    line (the default delta band, hard input limits)."""
    from .._inputs import DEFAULT_DELTA_BAND

    return {
        "t_end": float(save.t_end),
        "dt_save": float(save.dt_save),
        "solver": solver,
        "delta_band": float(DEFAULT_DELTA_BAND),
        "input_smoothing": 0.0,
    }


def _split(inputs):
    """(dynamic leaves, their treedef, the static part, key text) of a run's
    inputs: the arrays `eqx.filter_jit` would pass to the program, and the text
    of everything else that determines it."""
    import equinox as eqx
    import jax

    controller, fault, plant, op, init, solver, save = inputs
    args = (controller, fault, plant, op, init)
    dynamic, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    static_leaves, static_def = jax.tree_util.tree_flatten(static)
    statics = _statics(solver, save)
    text = "\n".join(
        [
            FORMAT.decode().strip(),
            str(treedef),
            str(static_def),
            repr(static_leaves),
            repr([(tuple(x.shape), str(x.dtype), bool(_weak(x))) for x in leaves]),
            repr(sorted((k, repr(v)) for k, v in statics.items())),
            _versions(),
            f"EQX_ON_ERROR={os.environ.get('EQX_ON_ERROR', '')}",
            f"x64={jax.config.jax_enable_x64}",
            _source_hash(),
        ]
    )
    return leaves, treedef, static, text


def _weak(x) -> bool:
    return getattr(x, "weak_type", False)


def _versions() -> str:
    """The versions of the packages that build the programs."""
    import importlib.metadata as md

    import jax
    import jaxlib

    names = ("equinox", "diffrax", "lineax", "optimistix")
    return " ".join(
        [f"jax={jax.__version__}", f"jaxlib={jaxlib.__version__}"]
        + [f"{n}={md.version(n)}" for n in names]
    )


def _source_hash() -> str:
    """sha256 of smibjax's source files (their paths inside the package and
    their bytes)."""
    global _SOURCE_HASH
    if _SOURCE_HASH is None:
        root = Path(__file__).resolve().parents[1]  # the smibjax package
        h = hashlib.sha256()
        for f in sorted(root.rglob("*.py")):
            h.update(f.relative_to(root).as_posix().encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
        _SOURCE_HASH = h.hexdigest()
    return _SOURCE_HASH


def _run_stored(folder: Path, inputs):
    """The run from the stored programs of these inputs (exported and stored
    first when there are none); None where JAX cannot export them."""
    global LAST_PATH
    import jax
    import numpy as np

    leaves, treedef, static, text = _split(inputs)
    key = hashlib.sha256(text.encode()).hexdigest()
    path = folder / f"{key}.bin"
    stored = _read(path, key)
    if stored is None:
        stored = _export(inputs, leaves, treedef, static, key)
        _write(path, stored)
        LAST_PATH = "exported"
    else:
        LAST_PATH = "stored"
    header, sim_blob, obs_blob = stored
    from jax import export

    with _no_lapack(not header["lapack"]):
        sim = export.deserialize(bytearray(sim_blob))
        outs = sim.call(*leaves)
        obs = export.deserialize(bytearray(obs_blob))
        m_out, a_out = obs.call(*outs)
    traj = SimpleNamespace(**dict(zip(header["trajectory"], outs, strict=True)))
    m = _metrics_like(header["metrics"], [jax.device_get(x) for x in m_out])
    arrays = {k: np.asarray(v) for k, v in zip(header["arrays"], a_out, strict=True)}
    return traj, m, arrays


def _metrics_like(names, values):
    """A `Metrics`-like named tuple of `values` (the class itself lives beside
    the solver)."""
    from collections import namedtuple

    return namedtuple("Metrics", names)(*values)


def _export(inputs, leaves, treedef, static, key):
    """(header, simulate's program, the summary's program) of these inputs,
    exported (traced now)."""
    import equinox as eqx
    import jax
    from jax import export

    from .._metrics import Metrics
    from .._simulate import Trajectory, _simulate

    controller, fault, plant, op, init, solver, save = inputs
    statics = _statics(solver, save)
    simulate_fn = _simulate.__wrapped__
    names = [f.name for f in dataclasses.fields(Trajectory)]

    def sim(*dynamic):
        args = eqx.combine(jax.tree_util.tree_unflatten(treedef, dynamic), static)
        traj = simulate_fn(*args, **statics)
        return tuple(getattr(traj, k) for k in names)

    def spec(x):
        return jax.ShapeDtypeStruct(x.shape, x.dtype, weak_type=_weak(x))

    sim_exp = export.export(jax.jit(sim), platforms=["cpu"])(*map(spec, leaves))
    array_names: list[str] = []

    def obs(*outs):
        traj = SimpleNamespace(**dict(zip(names, outs, strict=True)))
        m, arrays = observe(traj)
        array_names[:] = sorted(arrays)  # (a jitted function's dict: sorted keys)
        return tuple(m), tuple(arrays[k] for k in array_names)

    obs_exp = export.export(jax.jit(obs), platforms=["cpu"])(*sim_exp.out_avals)
    sim_blob, obs_blob = bytes(sim_exp.serialize()), bytes(obs_exp.serialize())
    header = {
        "key": key,
        "trajectory": names,
        "metrics": list(Metrics._fields),
        "arrays": array_names,
        # the programs call no LAPACK routine: calling them needs no LAPACK set-up
        # (jaxlib's loads SciPy: 0.2-0.4 s)
        "lapack": b"lapack" in sim_blob or b"lapack" in obs_blob,
    }
    return header, sim_blob, obs_blob


def _read(path: Path, key: str):
    """(header, blob, blob) stored at `path` for `key`; None when there is none
    (or another key's, or a damaged file)."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if not data.startswith(FORMAT):
        return None
    parts, at = [], len(FORMAT)
    for _ in range(3):
        if at + 8 > len(data):
            return None
        (n,) = struct.unpack_from("<Q", data, at)
        parts.append(data[at + 8 : at + 8 + n])
        at += 8 + n
    if at != len(data) or any(not p for p in parts):
        return None
    header = json.loads(parts[0])
    if header.get("key") != key:
        return None
    return header, parts[1], parts[2]


def _write(path: Path, stored) -> None:
    """Store (header, blob, blob) at `path` atomically (`_files.atomic_write`); a
    folder that cannot be written is skipped (the run goes on without it)."""
    from .._files import atomic_write

    header, *blobs = stored
    parts = [json.dumps(header).encode(), *blobs]
    data = FORMAT + b"".join(struct.pack("<Q", len(p)) + p for p in parts)
    try:
        atomic_write(path, lambda tmp: Path(tmp).write_bytes(data), new=False)
    except OSError:
        pass


class _no_lapack:
    """Within the block (when `skip`), calling an exported program does not set up
    jaxlib's LAPACK routines (which imports SciPy): for programs that call none."""

    def __init__(self, skip: bool):
        self.skip = skip
        self.saved = None

    def __enter__(self):
        if self.skip:
            from jax._src.export import _export

            self.saved = _export._ensure_backends_initialized
            _export._ensure_backends_initialized = lambda platforms: None
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            from jax._src.export import _export

            _export._ensure_backends_initialized = self.saved
        return False
