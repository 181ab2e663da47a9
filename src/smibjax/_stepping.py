"""Step-size control with a grid that is rigid under differentiation.

diffrax's `ClipStepSizeController(jump_ts=...)` ends a step exactly at a switch time, and
the gradient of that step's end point with respect to the switch time is 1, as it
should be. But the wrapped controller then proposes the next step as
factor * (length of the clipped step): the step lengths after a switch inherit a
derivative with respect to the switch time that is multiplied by the growth factor at
every step (up to 10x), so after a tiny clipped step the grid positions carry
derivatives of 1e10 and more, and d/dt_switch of the solution comes out wrong (measured:
-0.45 against +0.19 from finite differences right after t_reclose, see
tests/test_gradients.py). `RigidSteps` stops the gradient through the *length* of every
proposed step, not through its start: the grid after a switch moves rigidly with the
switch, and the discrete solution's derivative is that of a consistent discretisation.
"""

from __future__ import annotations

from collections.abc import Callable

import diffrax as dfx
import jax.lax as lax


class RigidSteps(dfx.AbstractAdaptiveStepSizeController):
    """Wrap an adaptive controller; proposed step lengths carry no gradient."""

    controller: dfx.AbstractAdaptiveStepSizeController

    @property
    def rtol(self):
        return self.controller.rtol

    @property
    def atol(self):
        return self.controller.atol

    @property
    def norm(self) -> Callable:
        return self.controller.norm

    def wrap(self, direction):
        return RigidSteps(self.controller.wrap(direction))

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        t1, state = self.controller.init(
            terms, t0, t1, y0, dt0, args, func, error_order
        )
        return t0 + lax.stop_gradient(t1 - t0), state

    def adapt_step_size(
        self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
    ):
        keep, next_t0, next_t1, made_jump, state, result = (
            self.controller.adapt_step_size(
                t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
            )
        )
        next_t1 = next_t0 + lax.stop_gradient(next_t1 - next_t0)
        return keep, next_t0, next_t1, made_jump, state, result
