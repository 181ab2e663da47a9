"""The fixed-step solve: Tsit5 on a grid known before the run, as a `lax.scan`.

The grid is the union of the steps k dt (the last one cut at t_end), the sample times
of the output grid and the switch times: every sample is a step end (no
interpolation), and no step straddles a switch, so each step runs on one network stage
(the one in force at its midpoint). The step itself is diffrax's `Tsit5.step`; the loop
around it is a scan of scans, the inner one (`block` steps) under `jax.checkpoint`, so
that the reverse pass stores one state per block and recomputes a block's steps once:
about sqrt(steps) states in memory and one extra forward pass of work, where diffrax's
general adaptive loop (`RecursiveCheckpointAdjoint`) recomputes about log2(steps)
times over and traces a far larger program.

A step that ends outside the model's domain (`healthy`) ends the run as diffrax's
event does: that step is the last one counted, and later steps leave the state unchanged (they
are still computed: the scan has a fixed length).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

__all__ = ["FixedSolution", "solve_fixed", "base_grid"]


class FixedSolution(NamedTuple):
    samples: Float[Array, "n 8"]  # state at the sample times (held after a stop)
    y_hold: Float[Array, 8]  # state at t_end, or the last sample before a stop
    lost_sync: Bool[Array, ""]
    t_stop: Float[Array, ""]  # end of the last step taken
    num_steps: Int[Array, ""]  # steps of non-zero length taken


def base_grid(t_end: float, dt: float, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The static part of the grid: k dt (k dt < t_end) and the sample times `ts`
    (points within 1e-9 dt of a sample time are dropped in its favour), sorted, and
    the index of each sample time in it."""
    n = int(np.ceil(t_end / dt - 1e-9))
    steps = np.arange(n) * dt
    near = np.abs(steps[:, None] - ts[None, :]).min(axis=1) <= 1e-9 * dt
    grid = np.sort(np.concatenate([steps[~near], ts]))
    return grid, np.searchsorted(grid, ts)


def solve_fixed(
    field: Callable,
    loop,
    y0: Float[Array, 8],
    switch: Float[Array, 3],
    healthy: Callable,
    *,
    t_end: float,
    dt: float,
    ts: np.ndarray,
    solver: dfx.AbstractRungeKutta | None = None,
    checkpoints: int | None = None,
) -> FixedSolution:
    """Integrate dy/dt = field(t, y, loop) from 0 to t_end on the fixed grid.

    `switch` (s) are the times at which the field changes (each becomes a grid point;
    those outside (0, t_end) are placed at an end and add a zero-length step);
    `healthy(t, y, loop)` is False once the run has left the model's domain;
    `solver`: an explicit Runge-Kutta method of diffrax (default Tsit5);
    `checkpoints`: states kept for the reverse pass, one per block of steps (None:
    about sqrt(steps)).
    """
    grid0, index0 = base_grid(t_end, dt, ts)
    sw = jnp.sort(jnp.clip(switch, 0.0, t_end))
    # A stable sort puts a grid point tied with a switch time before the switch point:
    # the step between them has zero length but ends on the switch, so its length
    # (and d/d(switch time)) belongs to the stage before the switch; a sample at a
    # tied time reads the grid point, which does not move with the switch.
    times = jnp.concatenate([jnp.asarray(grid0), sw])
    perm = jnp.argsort(times, stable=True)
    grid = times[perm]
    is_switch = perm >= grid0.shape[0]
    index = jnp.asarray(index0) + jnp.sum(sw[None, :] < jnp.asarray(ts)[:, None], 1)
    n_steps = grid.shape[0] - 1
    if checkpoints:
        block = max(1, -(-n_steps // checkpoints))
    else:
        block = max(1, int(round(np.sqrt(n_steps))))
    n_blocks = -(-n_steps // block)
    pad = n_blocks * block - n_steps
    ta = jnp.concatenate([grid[:-1], jnp.full(pad, t_end)])
    tb = jnp.concatenate([grid[1:], jnp.full(pad, t_end)])
    jump = jnp.concatenate([is_switch[:-1], jnp.zeros(pad, bool)])
    ends_on_switch = jnp.concatenate([is_switch[1:], jnp.zeros(pad, bool)])
    # The time that selects a step's stage: its midpoint; for a zero-length step
    # ending on a switch, just before it.
    # (It only selects a stage: no derivative flows through it.)
    ta_, tb_ = jax.lax.stop_gradient((ta, tb))
    stage_t = jnp.where(
        tb_ > ta_,
        0.5 * (ta_ + tb_),
        jnp.where(ends_on_switch, jnp.nextafter(ta_, -jnp.inf), ta_),
    )

    solver = dfx.Tsit5() if solver is None else solver
    term = dfx.ODETerm(lambda t, y, args: field(args[1], y, args[0]))
    state0 = solver.init(term, 0.0, dt, y0, (loop, jnp.asarray(0.0)))

    def step(carry, x):
        y, state, alive, t_stop, count = carry
        t0, t1, made_jump, mid = x
        y1, _, _, state1, _ = solver.step(
            term, t0, t1, y, (loop, mid), state, made_jump
        )
        moved = alive & (t1 > t0)
        y1 = jnp.where(alive, y1, y)
        state1 = jax.tree_util.tree_map(
            lambda a, b: jnp.where(alive, a, b), state1, state
        )
        t_stop = jnp.where(moved, t1, t_stop)
        count = count + moved.astype(count.dtype)
        alive = alive & healthy(mid, y1, loop)
        return (y1, state1, alive, t_stop, count), y1

    # A branch that skips the blocks after every run of a batch has stopped (lax.cond
    # on a batch-reduced predicate) was tried: it made every block twice as slow.
    # prevent_cse=False: the checkpoint sits inside the outer scan, where JAX's CSE
    # guard is not needed (jax.checkpoint's docs); measured: value-and-grad 9-12%
    # faster, its compile 10% shorter.
    @functools.partial(jax.checkpoint, prevent_cse=False)
    def run_block(carry, xs):
        return jax.lax.scan(step, carry, xs)

    xs = (ta, tb, jump, stage_t)
    xs = jax.tree_util.tree_map(lambda a: a.reshape(n_blocks, block), xs)
    carry0 = (y0, state0, jnp.asarray(True), jnp.asarray(0.0), jnp.asarray(0))
    (y_end, _, alive, t_stop, count), ys = jax.lax.scan(run_block, carry0, xs)
    ys = jnp.concatenate([y0[None], ys.reshape(-1, y0.shape[0])])
    samples = ys[index]
    lost = ~alive
    # After a stop, every later sample holds the last sample before the step that
    # left the domain (that step's end state lies past the breakdown margin, and a
    # fixed step across a singularity may land far off).
    reached = jnp.asarray(ts) < jnp.where(lost, t_stop, jnp.inf)
    last = jnp.maximum(jnp.sum(reached) - 1, 0)
    y_hold = jnp.where(lost, samples[last], y_end)
    samples = jnp.where(reached[:, None], samples, y_hold[None, :])
    return FixedSolution(samples, y_hold, lost, t_stop, count)
