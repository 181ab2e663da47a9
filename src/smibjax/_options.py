"""How to solve and what to save: option objects passed whole to `simulate` (and
through it to the batch engine, Monte Carlo, CCT and the tuner).

Both are small equinox Modules with static fields only: hashable, so a jitted
function compiles once per set of options, and validated when built (a bad value is
a `ParameterError` with one line naming it).
"""

from __future__ import annotations

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
