"""Stored programs: a jitted function's program kept on disk with `jax.export`
(StableHLO), so that a second process calling it with inputs of the same structure
neither traces it nor imports what tracing needs (diffrax, optimistix, lineax).

`stored_jit(fn)` behaves like `eqx.filter_jit(fn)` for a function returning a flat
dict of arrays. Its inputs are split into the *dynamic* part (floating and complex
arrays: the program's arguments) and the *static* part (everything else: Python
numbers, strings, integer and boolean index arrays, the pytree structure), which is
baked into the program. A program is stored under a key made of the function's name,
the static part (integer arrays by a hash of their bytes), the dynamic arrays' shapes
and dtypes, the versions of JAX, jaxlib, equinox, diffrax, lineax and optimistix,
equinox's error mode, float64 and a hash of smibjax's source files: a run with other
numbers of the same structure reuses it; anything else makes a new one. The compiled
executables come from JAX's persistent compilation cache, whose folder holds the
stored programs too (under `smibjax-exported/`).

Both models use it on the command line: the SMIB's `simulate` (`cli._exported`) and
the grid's power flow and `simulate --case`. Without a compilation cache, with
SMIBJAX_EXPORTED=0, or on any error (an unreadable file, a program JAX cannot export:
a host callback) the function runs traced (`eqx.filter_jit`), silently: the results
are the same bit for bit (tests/test_startup.py)."""

from __future__ import annotations

import hashlib
import json
import os
import struct
from pathlib import Path

__all__ = ["stored_jit", "folder", "read", "write", "versions", "source_hash"]

FORMAT = b"smibjax-exported/1\n"
FOLDER = "smibjax-exported"
LAST_PATH: dict[str, str] = {}
"""How the last call of each stored function (by name) computed: "stored" (a stored
program), "exported" (traced, exported and stored now), "traced" (no store)."""

_SOURCE_HASH: str | None = None
_LOADED: dict[str, tuple] = {}  # key -> (output names, callable) in this process


def folder() -> Path | None:
    """The folder of the stored programs, inside the compilation cache's folder;
    None when the cache is off or SMIBJAX_EXPORTED=0."""
    import jax

    if os.environ.get("SMIBJAX_EXPORTED", "1").strip() == "0":
        return None
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / FOLDER if cache else None


def versions() -> str:
    """The versions of the packages that build the programs."""
    import importlib.metadata as md

    import jax
    import jaxlib

    names = ("equinox", "diffrax", "lineax", "optimistix")
    return " ".join(
        [f"jax={jax.__version__}", f"jaxlib={jaxlib.__version__}"]
        + [f"{n}={md.version(n)}" for n in names]
    )


def source_hash() -> str:
    """sha256 of smibjax's source files (their paths inside the package and their
    bytes)."""
    global _SOURCE_HASH
    if _SOURCE_HASH is None:
        root = Path(__file__).resolve().parent  # the smibjax package
        h = hashlib.sha256()
        for f in sorted(root.rglob("*.py")):
            h.update(f.relative_to(root).as_posix().encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
        _SOURCE_HASH = h.hexdigest()
    return _SOURCE_HASH


def environment() -> list[str]:
    """The key lines every stored program shares: format, package versions, error
    mode, float64, smibjax's source."""
    import jax

    return [
        FORMAT.decode().strip(),
        versions(),
        f"EQX_ON_ERROR={os.environ.get('EQX_ON_ERROR', '')}",
        f"x64={jax.config.jax_enable_x64}",
        source_hash(),
    ]


def read(path: Path, key: str, n_blobs: int):
    """(header, *blobs) stored at `path` for `key`; None when there is none (or
    another key's, or a damaged file)."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if not data.startswith(FORMAT):
        return None
    parts, at = [], len(FORMAT)
    for _ in range(1 + n_blobs):
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
    return (header, *parts[1:])


def write(path: Path, stored) -> None:
    """Store (header, *blobs) at `path` atomically (`_files.atomic_write`); a folder
    that cannot be written is skipped (the run goes on without it)."""
    from ._files import atomic_write

    header, *blobs = stored
    parts = [json.dumps(header).encode(), *blobs]
    data = FORMAT + b"".join(struct.pack("<Q", len(p)) + p for p in parts)
    try:
        atomic_write(path, lambda tmp: Path(tmp).write_bytes(data), new=False)
    except OSError:
        pass


def weak(x) -> bool:
    return bool(getattr(x, "weak_type", False))


def spec(x):
    """The abstract value of an input array (shape, dtype, weak type)."""
    import jax

    return jax.ShapeDtypeStruct(x.shape, x.dtype, weak_type=weak(x))


class no_lapack:
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


def _is_dynamic(x) -> bool:
    """An input leaf the program takes as an argument: a floating or complex array
    (JAX or NumPy). Integer and boolean arrays (positions, masks) are structure."""
    import jax
    import numpy as np

    if isinstance(x, jax.Array | np.ndarray):
        return np.issubdtype(x.dtype, np.inexact)
    return False


def _static_text(x) -> str:
    import numpy as np

    if isinstance(x, np.ndarray):
        digest = hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()
        return f"ndarray{x.shape}{x.dtype}:{digest}"
    return repr(x)


def _split(args, kwargs):
    """(dynamic leaves, treedef, static part, key text) of a call's inputs."""
    import equinox as eqx
    import jax
    import numpy as np

    # JAX integer/bool arrays are structure too: as NumPy, so that they hash
    def host(x):
        if isinstance(x, jax.Array) and not _is_dynamic(x):
            return np.asarray(x)
        return x

    tree = jax.tree_util.tree_map(host, (args, kwargs))
    dynamic, static = eqx.partition(tree, _is_dynamic)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    static_leaves, static_def = jax.tree_util.tree_flatten(static)
    text = "\n".join(
        [
            str(treedef),
            str(static_def),
            "\n".join(_static_text(x) for x in static_leaves),
            repr([(tuple(x.shape), str(x.dtype), weak(x)) for x in leaves]),
        ]
    )
    return leaves, treedef, static, text


def stored_jit(fn, name: str | None = None):
    """`fn` (returning a flat dict of arrays) jitted, its program stored on disk and
    reused by later processes for inputs of the same structure (module docstring).
    Keyword arguments are part of the structure (static) unless they are floating
    arrays; the keyword `before_trace` (a function, not passed to `fn`) is called
    when the program must be traced (none of this structure is stored), e.g. to say
    so. Returns a dict of JAX arrays with `fn`'s keys."""
    label = name or f"{fn.__module__}.{fn.__qualname__}"
    programs: dict[str, tuple] = {}  # this process's traced programs, by key text

    def call(*args, before_trace=None, **kwargs):
        if before_trace is not None:
            before_trace = _once(before_trace)
        leaves, treedef, static, text = _split(args, kwargs)
        where = folder()
        if where is not None:
            try:
                out = _call_stored(
                    where, fn, label, leaves, treedef, static, text, before_trace
                )
            except Exception:  # any failure: the traced path answers
                out = None
            if out is not None:
                return out
        LAST_PATH[label] = "traced"
        if text not in programs:
            import jax

            if before_trace is not None:
                before_trace()
            names: list[str] = []
            programs[text] = (jax.jit(_program(fn, treedef, static, names)), names)
        jitted, names = programs[text]
        out = jitted(*leaves)  # (the first call traces it and fills `names`)
        return dict(zip(names, out, strict=True))

    call.__wrapped__ = fn
    call.__doc__ = fn.__doc__
    return call


def _once(fn):
    """fn, called at most once."""
    done = []

    def once():
        if not done:
            done.append(True)
            fn()

    return once


def _program(fn, treedef, static, names: list):
    """fn as a function of the dynamic leaves only, returning its outputs as a tuple
    in sorted key order (the keys are written into `names` when traced)."""
    import equinox as eqx
    import jax

    def program(*dynamic):
        a, kw = eqx.combine(jax.tree_util.tree_unflatten(treedef, dynamic), static)
        out = fn(*a, **kw)
        names[:] = sorted(out)
        return tuple(out[k] for k in names)

    return program


def _call_stored(where: Path, fn, label, leaves, treedef, static, text, before_trace):
    import jax
    from jax import export

    key = hashlib.sha256("\n".join([label, text, *environment()]).encode()).hexdigest()
    if key in _LOADED:
        LAST_PATH[label] = "stored"
        names, run = _LOADED[key]
        return dict(zip(names, run(*leaves), strict=True))
    path = where / f"{key}.bin"
    stored = read(path, key, 1)
    if stored is None:
        if before_trace is not None:
            before_trace()
        names: list[str] = []
        program = _program(fn, treedef, static, names)
        exp = export.export(jax.jit(program), platforms=["cpu"])(*map(spec, leaves))
        blob = bytes(exp.serialize())
        header = {"key": key, "outputs": list(names), "lapack": b"lapack" in blob}
        stored = (header, blob)
        write(path, stored)
        LAST_PATH[label] = "exported"
    else:
        LAST_PATH[label] = "stored"
    header, blob = stored
    with no_lapack(not header["lapack"]):
        exported = export.deserialize(bytearray(blob))
        run = jax.jit(exported.call)
        outs = run(*leaves)
    _LOADED[key] = (header["outputs"], run)
    return dict(zip(header["outputs"], outs, strict=True))
