"""Switch-time gradients of the grid model through the engine's one adaptive solve path
(issue 44): a line fault on one circuit of Kundur's tie, cleared by opening that circuit
and reclosed later. d(loss)/d(clearing time) and d(loss)/d(reclosing time) from reverse
mode agree with central differences at the default tolerances (measured: 1.3e-7 and
5.1e-7 relative at rtol 1e-6). Without steps that end on the switch times the
derivatives are lost (the stage changes inside a step). On this loss, dropping
`RigidSteps` still gives 8e-5 relative: its effect shows after a tiny clipped step
(`smibjax._stepping`, tests/test_gradients.py for the SMIB)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import pytest

from smibjax.grid.case import load_case
from smibjax.grid.events import BranchClose, BranchTrip, LineFault
from smibjax.grid.operating import operating_point
from smibjax.grid.simulate import coi_angles, simulate_case

TIE = 2  # branch position: circuit 1 of the 7-8 tie


@pytest.fixture(scope="module")
def value_and_grad():
    case = load_case("kundur-gencls")
    op, _ = operating_point(case)

    def loss(times):
        """Mean square COI-angle excursion from the operating point (rad^2) over 2 s,
        for clearing time times[0] and reclosing time times[1] (s)."""
        tc, tr = times
        events = [
            LineFault(branch=TIE, frac=0.5, t_on=1.0, t_off=tc),
            BranchTrip(branch=TIE, t=tc),
            BranchClose(branch=TIE, t=tr),
        ]
        traj = simulate_case(case, op, events, t_end=2.0, dt_save=0.02)
        rel = coi_angles(case, traj.delta, jnp.ones(case.n_gen))
        return jnp.mean((rel - rel[0]) ** 2)

    # one program for the point and for the differences
    return eqx.filter_jit(jax.value_and_grad(loss))


def test_clearing_and_reclosing_time_gradients_match_central_differences(
    value_and_grad,
):
    x = jnp.array([1.1, 1.5])
    value, grad = value_and_grad(x)
    assert 1e-4 < float(value) < 1.0  # a real swing, not a flat line
    h = 1e-5
    for i in range(2):
        e = jnp.zeros(2).at[i].set(h)
        fd = (value_and_grad(x + e)[0] - value_and_grad(x - e)[0]) / (2 * h)
        assert abs(float(fd)) > 1e-3, i  # both times matter to the loss
        assert abs(float(grad[i]) - float(fd)) <= 1e-3 * abs(float(fd)), (i, grad, fd)
