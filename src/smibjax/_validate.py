"""Validation helpers shared by the parameter modules and the solver options.

Parameter sets are checked only on concrete values: inside `jax.jit` or `jax.vmap`
their leaves are tracers and validation is skipped (it already happened when the
concrete values were built); `smibjax._parameters` decides that with `is_concrete`.
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


def require(ok, owner: str, name: str, value, allowed: str, *others) -> None:
    """Raise `ParameterError` unless `ok` (concrete, e.g. NumPy) holds everywhere.
    `allowed` may hold `{}` fields for `others` (values it names, such as the bound
    of a range), which are formatted like `value`, and only on failure: a batch of
    parameter sets costs no array printing when it is valid."""
    if not bool(np.all(np.asarray(ok))):
        if others:
            allowed = allowed.format(*(_fmt(x) for x in others))
        raise ParameterError(
            f"{owner}.{name} = {_fmt(value)} is not allowed: {allowed}"
        )


MAX_MAGNITUDE = 1e6
"""The largest |value| accepted for a plant parameter, operating-point value or initial
estimate: far beyond any physical per-unit value, and small enough that the model's
products and powers of it stay finite in float64 (1e308 overflows to inf/NaN)."""


def require_finite(
    p, owner: str, names, bound: float | None = MAX_MAGNITUDE, allow_inf=()
) -> None:
    """Raise `ParameterError` unless every field `names` of the NumPy namespace `p` is
    finite (NaN never passes) and, with `bound`, within [-bound, bound]. Names in
    `allow_inf` may also be +-inf (e.g. an absent input limit)."""
    for name in names:
        v = getattr(p, name, None)
        if v is None or np.asarray(v).dtype.kind not in "fiu":
            continue
        v = np.asarray(v, dtype=float)
        ok = np.isfinite(v) | (np.isinf(v) & (name in allow_inf))
        what = "finite" if name not in allow_inf else "a number or +-inf"
        if bound is not None:
            ok = ok & ((np.abs(v) <= bound) | np.isinf(v))
            what += f" with |value| <= {bound:g}"
        require(ok, owner, name, v, f"must be {what}")


def require_in_horizon(t_fault, t_clear, t_end: float) -> None:
    """Raise `ParameterError` unless the fault and its clearing lie inside the horizon
    (t_fault < t_clear < t_end, everywhere in a batch): a run that ends before the
    fault (or before its clearing) would report the pre-fault state as a verdict on
    the fault."""
    tf, tc = np.asarray(t_fault, dtype=float), np.asarray(t_clear, dtype=float)
    require(
        tf < t_end,
        "Fault",
        "t_fault",
        tf,
        f"must be < t_end = {t_end:g} (the fault must happen within the run)",
    )
    require(
        tc < t_end,
        "Fault",
        "t_clear",
        tc,
        f"must be < t_end = {t_end:g} (the fault must be cleared within the run)",
    )


MAX_SAMPLES = 1_000_000  # samples of one run: ~200 MB of outputs


def require_samples(t_end: float, dt_save: float) -> None:
    """Raise `ParameterError` unless t_end / dt_save (the samples of a run) is at most
    `MAX_SAMPLES`."""
    if not t_end / dt_save <= MAX_SAMPLES:
        raise ParameterError(
            f"t_end / dt_save = {t_end:g} / {dt_save:g} is not allowed: must be <= "
            f"{MAX_SAMPLES:g} samples a run (dt_save >= {t_end / MAX_SAMPLES:g} s)"
        )


def require_count(name: str, v) -> None:
    """Raise `ParameterError` unless `v` is an integer >= 1 (not a bool)."""
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1:
        raise ParameterError(f"{name} = {v!r} is not allowed: must be >= 1")


def require_positive(name: str, v) -> None:
    """Raise `ParameterError` unless the number `v` is finite and > 0."""
    if not (np.isfinite(v) and v > 0):
        raise ParameterError(f"{name} = {v:g} is not allowed: must be > 0")


def require_x64() -> None:
    """A clear error where JAX runs in 32-bit mode: the closed loop is stiff and the
    finite-time law works near phi = 0, where float32 is not enough."""
    import jax

    if not jax.config.jax_enable_x64:
        raise RuntimeError(
            "smibjax needs JAX's 64-bit mode: call "
            "jax.config.update('jax_enable_x64', True) (or set JAX_ENABLE_X64=1) "
            "before creating any array"
        )
