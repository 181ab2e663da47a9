"""How to solve and what to save: option objects passed whole to `simulate` (and
through it to the batch engine, Monte Carlo, CCT and the tuner).

Both are small equinox Modules with static fields only: hashable, so a jitted
function compiles once per set of options, and validated when built (a bad value is
a `ParameterError` with one line naming it).
"""

from __future__ import annotations

import warnings
from typing import Literal

import equinox as eqx

from ._validate import ParameterError, require_count, require_positive, require_solver

__all__ = ["SolverOptions", "SaveOptions", "METHODS"]

METHODS = ("tsit5", "dopri5", "dopri8")
DEFAULT_MAX_STEPS = 50_000


class SolverOptions(eqx.Module):
    """The ODE solver.

    - `kind`: `"adaptive"` (PID step-size control with `rtol`, `atol`) or `"fixed"`
      (steps of `dt` (s) on the grid k dt, with the sample times and the switch
      times added as grid points, so that no step straddles a switch and every
      sample is a step end).
    - `method`: the Runge-Kutta method (tsit5, dopri5, dopri8).
    - `rtol`, `atol`: the adaptive solver's tolerances (relative; absolute, in the
      units of each state).
    - `max_steps`: the adaptive solver's step budget per run; a run that exhausts it
      ends with `budget_exhausted` (not stable, not lost: raise the budget; the
      fixed grid needs none). Default 50,000: a 10 s AFTSC run takes ~4k steps at
      alpha = 5/7, 34k at alpha = 0.6 and more as alpha -> 1/2.
    - `dt`: the fixed step (s).
    - `checkpoints`: solver states kept for the reverse pass. Adaptive: diffrax's
      `RecursiveCheckpointAdjoint`; None: about log2(max_steps), the least memory
      and the most recomputation; more trade memory (about 1 kB per checkpoint per
      scenario) for speed. Fixed: one state per block of steps, each block
      recomputed once in the reverse pass; None: about sqrt(steps) blocks. Values
      are unaffected.
    """

    kind: Literal["adaptive", "fixed"] = eqx.field(static=True, default="adaptive")
    method: Literal["tsit5", "dopri5", "dopri8"] = eqx.field(
        static=True, default="tsit5"
    )
    rtol: float = eqx.field(static=True, default=1e-6)
    atol: float = eqx.field(static=True, default=1e-8)
    max_steps: int = eqx.field(static=True, default=DEFAULT_MAX_STEPS)
    dt: float = eqx.field(static=True, default=1e-3)
    checkpoints: int | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.kind not in ("adaptive", "fixed"):
            raise ParameterError(
                f"solver = {self.kind!r} is not allowed: must be 'adaptive' or 'fixed'"
            )
        if self.method not in METHODS:
            raise ParameterError(
                f"method = {self.method!r} is not allowed: must be one of "
                f"{sorted(METHODS)}"
            )
        for name in ("dt", "rtol", "atol"):
            require_positive(name, getattr(self, name))
        require_count("max_steps", self.max_steps)
        require_solver(self.rtol, self.atol, self.max_steps)


class SaveOptions(eqx.Module):
    """What a run returns: the horizon `t_end` (s) and the sampling interval
    `dt_save` (s) of the returned arrays (samples at 0, dt_save, ..., t_end)."""

    t_end: float = eqx.field(static=True, default=10.0)
    dt_save: float = eqx.field(static=True, default=0.01)

    def __check_init__(self):
        for name in ("t_end", "dt_save"):
            require_positive(name, getattr(self, name))
        if self.dt_save > self.t_end:
            raise ParameterError(
                f"dt_save = {self.dt_save:g} is not allowed: must be <= t_end = "
                f"{self.t_end:g}"
            )


def solver_or_legacy(
    owner: str, solver: SolverOptions | None, legacy: dict, stacklevel: int = 3
) -> SolverOptions:
    """The solver options of `owner` (a name, for the messages): `solver`
    (default: `SolverOptions()`), or, from the keywords of 0.1 (`rtol`, `atol`,
    `max_steps`; those given as None are absent), a `SolverOptions` with those
    values and the defaults for the rest. The keywords are deprecated: a
    `DeprecationWarning` (at `stacklevel`), for one release; both at once is a
    `TypeError`."""
    given = {k: v for k, v in legacy.items() if v is not None}
    if not given:
        if solver is None:
            return SolverOptions()
        if not isinstance(solver, SolverOptions):
            raise ParameterError(
                f"solver = {solver!r} is not allowed: must be a SolverOptions"
            )
        return solver
    if solver is not None and solver != SolverOptions():
        raise TypeError(
            f"{owner}: give solver=SolverOptions(...) or the old keywords "
            f"{', '.join(sorted(given))}, not both"
        )
    warnings.warn(
        f"{owner}({', '.join(f'{k}=' for k in sorted(given))}) is deprecated: pass "
        "solver=SolverOptions(...)",
        DeprecationWarning,
        stacklevel=stacklevel,
    )
    return SolverOptions(**given)


def adopt_legacy_solver(obj, rtol, atol, max_steps) -> None:
    """In the `__post_init__` of a frozen dataclass with a `solver` field and the
    deprecated `rtol`, `atol`, `max_steps` init-only keywords: set `obj.solver` to
    `solver_or_legacy` of them (the warning points at the caller's line)."""
    legacy = {"rtol": rtol, "atol": atol, "max_steps": max_steps}
    solver = solver_or_legacy(type(obj).__name__, obj.solver, legacy, stacklevel=5)
    object.__setattr__(obj, "solver", solver)
