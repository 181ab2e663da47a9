"""The one adaptive solve path of the engine, shared by the SMIB and the grid model.

`adaptive_solve` is diffrax's loop as both models use it: an explicit Runge-Kutta method
(`SolverOptions.method`) under PID step-size control (`rtol`, `atol`), clipped so that a
step ends exactly at every switch time (`jump_ts`) and wrapped in `RigidSteps` (the step
lengths carry no gradient, so that derivatives with respect to switch times stay right
after a clearing or a reclosure: see `_stepping`), an event that stops the run when a
model's `stop(t, y, args)` becomes true (loss of synchronism), samples at `ts` plus the
final state, a recursive-checkpoint reverse pass, and no exception on failure (the
solution's `result` says how the run ended).
"""

from __future__ import annotations

from collections.abc import Callable

import diffrax as dfx
import equinox as eqx
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Float

from ._options import SolverOptions
from ._stepping import RigidSteps

__all__ = ["adaptive_solve", "METHOD_CLASSES", "NanAsInf"]

METHOD_CLASSES = {"tsit5": dfx.Tsit5, "dopri5": dfx.Dopri5, "dopri8": dfx.Dopri8}


class NanAsInf(eqx.Module):
    """The error norm `norm`, with NaN read as inf: a trial step whose error is NaN
    (an explicit step far too long for a stiff stage, right after a switch, that
    overflows: GENROE's exponential saturation psi^n of a state of 1e37) is then
    rejected and the next one shortened by the controller's smallest factor, as for
    an infinite error. diffrax's PID controller takes a NaN error into the next step
    length (NaN times the step), so that every later step is rejected until the step
    budget runs out. Identical to `norm` wherever the error is a number."""

    norm: Callable

    def __call__(self, y) -> Array:
        n = self.norm(y)
        return jnp.where(jnp.isnan(n), jnp.inf, n)


def adaptive_solve(
    vector_field: Callable,
    y0: Float[Array, " n"],
    ts: Float[Array, " T"],
    jumps: Float[Array, " n_switch"] | None,
    solver: SolverOptions,
    stop: Callable,
    *,
    args=None,
    norm: Callable | None = None,
    dt0: float | None = None,
    t0: float = 0.0,
) -> dfx.Solution:
    """Integrate dy/dt = vector_field(t, y, args) from `t0` (s) to `ts[-1]` (s), saving
    at the times `ts` (s) and at the end (`SaveAt(ts=ts, t1=True)`: after the samples
    reached come the final state, at `ts[-1]` or where `stop` fired, then inf padding).

    `jumps` (s): switch times the steps end on (None or empty: none). `norm`: the
    error norm of the step-size control (default diffrax's RMS norm), NaN read as
    inf (`NanAsInf`). `dt0` (s): the first step (None: diffrax's estimate)."""
    pid = dfx.PIDController(
        rtol=float(solver.rtol),
        atol=float(solver.atol),
        norm=NanAsInf(optx.rms_norm if norm is None else norm),
    )
    has_jumps = jumps is not None and jumps.shape[0] > 0
    controller = dfx.ClipStepSizeController(
        RigidSteps(pid), jump_ts=jumps if has_jumps else None
    )
    checkpoints = solver.checkpoints
    return dfx.diffeqsolve(
        dfx.ODETerm(vector_field),
        METHOD_CLASSES[solver.method](),
        t0=t0,
        t1=ts[-1],
        dt0=dt0,
        y0=y0,
        args=args,
        saveat=dfx.SaveAt(ts=ts, t1=True),
        stepsize_controller=controller,
        event=dfx.Event(cond_fn=stop),
        max_steps=int(solver.max_steps),
        adjoint=dfx.RecursiveCheckpointAdjoint(
            checkpoints=None if checkpoints is None else int(checkpoints)
        ),
        throw=False,
    )
