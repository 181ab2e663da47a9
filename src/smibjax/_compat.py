"""A guarded work-around for one upstream bug.

equinox's closure conversion (used by diffrax's Runge-Kutta stage loop, an equinox
checkpointed while loop, in its reverse pass) checks that a converted function is
called with arguments of the types it was traced with, comparing shardings too. Inside
`jax.shard_map` an argument made by an operation gains the manual mesh's sharding while
its traced example has none, and the check rejects a call that is otherwise identical
(diffrax issue #765; equinox pull request #1261, open, makes the check ignore sharding
metadata). `shard_map_closure_fix` applies that change while the one call that needs it runs
(`smibjax._parallel.shard_batch`, the tuner's sharded value-and-grad), and only on the
equinox versions it was checked against (`CHECKED`); on any other version it changes
nothing and warns once (if the upstream fix has landed, nothing is needed; if not,
the sharded call fails with equinox's own error, and `CHECKED` is the place to look).
"""

from __future__ import annotations

import contextlib
import threading
import warnings

import jax

_lock = threading.Lock()
# equinox versions (inclusive range) on which the work-around was checked: the
# private function it replaces exists with this meaning, and the tuner's sharded
# gradient needs it (tests/test_parallel.py).
CHECKED = ((0, 13, 0), (0, 13, 8))
_warned = []


def _version(text: str) -> tuple[int, ...]:
    out = []
    for part in text.split(".")[:3]:
        digits = "".join(c for c in part if c.isdigit())
        out.append(int(digits) if digits else 0)
    return tuple(out)


def checked_version(version: str | None = None) -> bool:
    """True for an equinox version inside `CHECKED` (default: the installed one)."""
    if version is None:
        import equinox

        version = equinox.__version__
    lo, hi = CHECKED
    return lo <= _version(version) <= hi


def _shape_dtype_only(tree):
    return jax.tree_util.tree_map(
        lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), tree
    )


@contextlib.contextmanager
def shard_map_closure_fix():
    """While active, equinox's closure-conversion input check compares shapes and
    dtypes, not shardings (as equinox PR #1261 does)."""
    if not checked_version():
        if not _warned:
            import equinox

            _warned.append(True)
            warnings.warn(
                f"smibjax: the shard_map work-around is not applied on equinox "
                f"{equinox.__version__} (checked on {CHECKED[0]}..{CHECKED[1]})",
                stacklevel=3,
            )
        yield
        return
    try:
        from equinox import _ad
    except ImportError:  # pragma: no cover - equinox reorganised
        yield
        return
    original = getattr(_ad, "_strip_weak_dtype", None)
    if original is None:  # pragma: no cover - equinox changed: nothing to patch
        yield
        return
    with _lock:
        _ad._strip_weak_dtype = _shape_dtype_only
        try:
            yield
        finally:
            _ad._strip_weak_dtype = original
