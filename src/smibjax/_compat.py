"""A guarded work-around for one upstream bug.

equinox's closure conversion (used by diffrax's Runge-Kutta stage loop, an equinox
checkpointed while loop, in its reverse pass) checks that a converted function is
called with arguments of the types it was traced with, comparing shardings too. Inside
`jax.shard_map` an argument made by an operation gains the manual mesh's sharding while
its traced example has none, and the check rejects a call that is otherwise identical
(diffrax issue #765; equinox pull request #1261, open, makes the check ignore sharding
metadata). `shard_map_closure_fix` applies that change while a function is traced, and
does nothing where equinox no longer has the function it replaces.
"""

from __future__ import annotations

import contextlib
import threading

import jax

_lock = threading.Lock()


def _shape_dtype_only(tree):
    return jax.tree_util.tree_map(
        lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), tree
    )


@contextlib.contextmanager
def shard_map_closure_fix():
    """While active, equinox's closure-conversion input check compares shapes and
    dtypes, not shardings (as equinox PR #1261 does)."""
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
