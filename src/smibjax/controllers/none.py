"""`none`: no control action (docs/model.md section 2, "Baselines").

The field voltage is held at its operating-point value E_fd0 (the u_f that makes
dE'/dt = 0 at the operating point) and the SVC command is 0, so B relaxes to B0. With
D = 0 and a very large T0 this is the classical model, whose critical clearing time
follows from the equal-area criterion (tests/test_textbook.py).
"""

from __future__ import annotations

import jax.numpy as jnp

from .._plant import operating_field_voltage
from .base import AbstractController, ControllerOutput

__all__ = ["NoControl"]


class NoControl(AbstractController):
    """Constant field voltage E_fd0 (pu) and u_r = 0; no parameters, no state."""

    n_internal = 0

    @classmethod
    def parameter_kinds(cls) -> dict[str, str]:
        return {}

    def initial_internal(self, z0, plant, op, init):
        return jnp.zeros((0,), dtype=z0.dtype)

    def label(self) -> str:
        return "no control"

    def __call__(self, t, z, s, stage, plant, op, trig=None):
        u_f = operating_field_voltage(op, plant) + jnp.zeros_like(z[0])
        zero = jnp.zeros_like(z[0])
        return ControllerOutput(
            u_f=u_f, u_r=zero, d_internal=s * 0.0, diagnostics=jnp.stack([zero, zero])
        )
