"""Validation helpers shared by the parameter modules and the solver options.

Parameter sets are checked only on concrete values: inside `jax.jit` or `jax.vmap`
their leaves are tracers and validation is skipped (it already happened when the
concrete values were built); `smibjax.parameters` decides that with `is_concrete`.
"""

from __future__ import annotations

import numbers

import jax
import numpy as np


class ParameterError(ValueError):
    """A parameter value outside its allowed range. The message is one line that names
    the value and what is allowed."""


def is_concrete(*xs) -> bool:
    """True when none of `xs` is a JAX tracer."""
    return not any(isinstance(x, jax.core.Tracer) for x in xs)


def _fmt(x) -> str:
    a = np.asarray(x)
    if a.ndim == 0:
        return f"{float(a):g}"
    return np.array2string(a, precision=6, threshold=6)


def require(ok, owner: str, name: str, value, allowed: str) -> None:
    """Raise `ParameterError` unless `ok` (concrete, e.g. NumPy) holds everywhere."""
    if not bool(np.all(np.asarray(ok))):
        raise ParameterError(
            f"{owner}.{name} = {_fmt(value)} is not allowed: {allowed}"
        )


def require_count(name: str, v) -> None:
    """Raise `ParameterError` unless `v` is an integer >= 1 (not a bool)."""
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1:
        raise ParameterError(f"{name} = {v!r} is not allowed: must be >= 1")


def require_positive(name: str, v) -> None:
    """Raise `ParameterError` unless the number `v` is finite and > 0."""
    if not (np.isfinite(v) and v > 0):
        raise ParameterError(f"{name} = {v:g} is not allowed: must be > 0")
