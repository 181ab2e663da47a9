"""Validation helpers shared by the parameter modules and the solver options.

Parameter sets are checked only on concrete values: inside `jax.jit` or `jax.vmap`
their leaves are tracers and validation is skipped (it already happened when the
concrete values were built); `smibjax._parameters` decides that with `is_concrete`.
"""

from __future__ import annotations

import math
import numbers

import jax
import numpy as np

from ._errors import ParameterError as ParameterError  # the one home: _errors.py


def is_concrete(*xs) -> bool:
    """True when none of `xs` is a JAX tracer."""
    return not any(isinstance(x, jax.core.Tracer) for x in xs)


def concrete_value(x):
    """`x` as a NumPy array where its value is known: a concrete array, or a tracer
    that carries its value (under `jax.grad` or `jax.jvp` outside `jit`, the primal);
    None inside `jit` or `vmap`. Validation runs on these values, so that
    differentiating through a non-finite parameter is refused before any solving."""
    if isinstance(x, jax.core.Tracer):
        try:
            v = x.to_concrete_value()
        except Exception:  # pragma: no cover - tracers without the method
            return None
        return None if v is None else np.asarray(v)
    return np.asarray(x)


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


MAX_COUNT = 10**9
"""The largest count (scenarios, chunk size, batch, steps) any input may give: beyond
it a run cannot finish in memory or time, and NumPy/JAX index types overflow."""

MAX_STEPS = 10**8
"""The largest adaptive step budget per run (`max_steps`): diffrax counts steps in
int32-safe arithmetic and a budget beyond this is never spent by a finishing run."""

MAX_TOLERANCE = 1e-2
"""The loosest solver tolerance (rtol, atol) accepted: looser, the step-size
controller rather than the plant decides the verdict (rtol = 1e3 turns a stable gain
set unstable after three steps)."""

MAX_DEPTH = 32
"""The deepest nesting (tables in lists in tables...) an input file may have."""

MAX_INT = 2**63 - 1
"""The largest |integer| an input file may hold (larger ones overflow float and int64
conversions)."""


def show_value(v) -> str:
    """`v` for an error line: short (a 400-digit integer is summarized)."""
    if isinstance(v, int) and not isinstance(v, bool) and abs(v) > MAX_INT:
        return f"<an integer of {len(str(abs(v)))} digits>"
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def require_integer(name: str, v, lo: int | None = 1, hi: int | None = MAX_COUNT):
    """`v` as an int, or `ParameterError` unless it is an integer (not a bool, not a
    float, even an integral one: a seed of 1.5 is not 1) within [lo, hi]."""
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        raise ParameterError(
            f"{name} = {show_value(v)} is not allowed: must be an integer"
        )
    v = int(v)
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = (
            f"in [{lo}, {hi}]"
            if lo is not None and hi is not None
            else (f">= {lo}" if lo is not None else f"<= {hi}")
        )
        raise ParameterError(f"{name} = {show_value(v)} is not allowed: must be {rng}")
    return v


def require_real(
    name: str,
    v,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """`v` as a float, or `ParameterError` unless it is a finite number (not a bool,
    not a string) within the bounds (`lo_open`/`hi_open`: the bound excluded)."""
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise ParameterError(
            f"{name} = {show_value(v)} is not allowed: must be a number"
        )
    try:
        f = float(v)
    except OverflowError:
        f = math.inf
    below = lo is not None and (f <= lo if lo_open else f < lo)
    above = hi is not None and (f >= hi if hi_open else f > hi)
    if not math.isfinite(f) or below or above:
        parts = []
        if lo is not None:
            parts.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            parts.append(f"{'<' if hi_open else '<='} {hi:g}")
        what = "a finite number" + (" " + " and ".join(parts) if parts else "")
        raise ParameterError(f"{name} = {show_value(v)} is not allowed: must be {what}")
    return f


def require_count(name: str, v) -> None:
    """Raise `ParameterError` unless `v` is an integer in [1, `MAX_COUNT`] (not a
    bool)."""
    require_integer(name, v, 1, MAX_COUNT)


def require_positive(name: str, v) -> None:
    """Raise `ParameterError` unless the number `v` is finite and > 0 (not a bool)."""
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise ParameterError(
            f"{name} = {show_value(v)} is not allowed: must be a number"
        )
    if not (np.isfinite(v) and v > 0):
        raise ParameterError(f"{name} = {v:g} is not allowed: must be > 0")


def require_solver(rtol, atol, max_steps) -> None:
    """Raise `ParameterError` unless the adaptive solver's tolerances are in
    (0, `MAX_TOLERANCE`] and its step budget an integer in [1, `MAX_STEPS`]."""
    for name, v in (("rtol", rtol), ("atol", atol)):
        require_real(name, v, 0.0, MAX_TOLERANCE, lo_open=True)
    require_integer("max_steps", max_steps, 1, MAX_STEPS)


BYTES_PER_SAMPLE = 8 * 40
"""Memory (bytes) one saved sample of one run takes while a batch runs: the states,
the observed outputs and their metric reductions, float64, with slack for XLA's
temporaries (an estimate for planning, not a measurement)."""


def memory_budget() -> int:
    """The memory (bytes) a batch may plan to use: `SMIBJAX_MEMORY_LIMIT` (bytes) if
    set, else half of the machine's physical memory."""
    import os

    env = os.environ.get("SMIBJAX_MEMORY_LIMIT", "").strip()
    if env.isdigit():
        return int(env)
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        total = 16 * 2**30
    return max(total // 2, 2**28)


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def require_memory(what: str, runs: float, samples: float, hint: str) -> None:
    """Raise `ParameterError` unless a batch of `runs` runs of `samples` saved samples
    each fits `memory_budget()` (estimated with `BYTES_PER_SAMPLE`), before any work;
    `hint` says what to change."""
    need = float(runs) * float(samples) * BYTES_PER_SAMPLE
    budget = memory_budget()
    if not need <= budget:
        raise ParameterError(
            f"{what} is not allowed: one batch of {float(runs):.4g} runs x "
            f"{float(samples):.4g} samples needs about {_gib(need)}, more than the "
            f"{_gib(budget)} available (half the memory; SMIBJAX_MEMORY_LIMIT "
            f"overrides): {hint}"
        )


def show_key(k) -> str:
    """A key of an input file for an error line: as written where it is plain
    printable text, else quoted with its escapes (a key holding a newline or nothing
    at all must not break or blur the one line)."""
    plain = isinstance(k, str) and k and k.isprintable() and "." not in k
    return k if plain else show_value(k)


def check_tree(data, source: str):
    """`data` (parsed JSON/TOML), or `ParameterError` where it nests deeper than
    `MAX_DEPTH` or holds an integer beyond +-`MAX_INT` (named by its key path)."""
    stack = [(data, (), 0)]
    while stack:
        node, path, depth = stack.pop()
        where = ".".join(map(show_key, path)) or "the top level"
        if depth > MAX_DEPTH:
            raise ParameterError(
                f"{source} is not allowed: nested deeper than {MAX_DEPTH} levels "
                f"(at {where})"
            )
        if isinstance(node, dict):
            stack.extend((v, (*path, k), depth + 1) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, (*path, i), depth + 1) for i, v in enumerate(node))
        elif isinstance(node, int) and not isinstance(node, bool):
            if abs(node) > MAX_INT:
                raise ParameterError(
                    f"{where} = {show_value(node)} in {source} is not allowed: must be "
                    f"an integer within +-{MAX_INT} (2**63 - 1)"
                )
    return data


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
