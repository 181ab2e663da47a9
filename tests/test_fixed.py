"""The fixed-grid scan (smibjax._fixed) against closed forms: a piecewise-linear decay
whose rate switches at traced times, its derivative with respect to a switch time,
and the stop on leaving the domain."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax._fixed import base_grid, solve_fixed

RATES = (1.0, 3.0, 0.5, 2.0)  # 1/s before, between and after the switch times


def field(t, y, loop):
    """dy/dt = -k(t) y, k switching at loop["switch"] (t is a step's midpoint)."""
    k = jnp.asarray(RATES)[jnp.sum(t >= loop["switch"])]
    return -k * y


def exact(t, y0, switch):
    """y0 exp(-integral of k) at times t."""
    edges = np.concatenate([[0.0], switch, [np.inf]])
    integral = sum(
        r * np.clip(t - a, 0.0, b - a)
        for r, a, b in zip(RATES, edges[:-1], edges[1:], strict=True)
    )
    return y0 * np.exp(-integral)


TS = np.linspace(0.0, 2.0, 41)


@jax.jit  # one program per use (value, jacrev, grad), not the scan's ops one by one
def _solve(switch, floor):
    return solve_fixed(
        field,
        {"switch": switch, "floor": floor},
        jnp.array([1.0, 2.0]),
        switch,
        lambda t, y, lp: y[0] > lp["floor"],
        t_end=2.0,
        dt=0.01,
        ts=TS,
        checkpoints=13,  # blocks of 16 steps
    )


def run(switch, floor=-1.0):
    """The decay from y0 = (1, 2) over 2 s at dt = 0.01 s, sampled every 0.05 s, its
    domain y[0] > floor."""
    return _solve(switch, jnp.float64(floor)), TS


def test_base_grid_holds_steps_and_samples_once():
    ts = np.linspace(0.0, 1.0, 11)
    grid, index = base_grid(1.0, 0.03, ts)
    assert np.all(np.diff(grid) > 0) and grid[0] == 0.0 and grid[-1] == 1.0
    np.testing.assert_array_equal(grid[index], ts)
    assert np.max(np.diff(grid)) <= 0.03 + 1e-15
    grid, _ = base_grid(1.0, 0.01, ts)  # samples on the step grid: not doubled
    assert grid.shape == (101,)


@pytest.mark.parametrize("on_grid", [False, True])
def test_piecewise_decay_matches_the_closed_form(on_grid):
    # on_grid: switch times that are also step and sample times
    switch = jnp.array([0.25, 0.5, 1.25] if on_grid else [0.333, 0.5005, 1.2345])
    sol, ts = run(switch)
    want = exact(ts, 1.0, np.asarray(switch))
    np.testing.assert_allclose(sol.samples[:, 0], want, rtol=1e-10)
    np.testing.assert_allclose(sol.samples[:, 1], 2 * want, rtol=1e-10)
    assert not bool(sol.lost_sync) and float(sol.t_stop) == 2.0
    # 200 steps of 0.01 s, plus one for each switch time off the grid
    assert int(sol.num_steps) == (200 if on_grid else 203)


@pytest.mark.parametrize("s2", [0.5, 0.5005, 0.51])  # on a sample, off, on a step
def test_derivative_with_respect_to_a_switch_time(s2):
    """y(t) = exp(-sum k_i (interval i)): dy(t)/ds_2 = (k_3 - k_2) y(t) for t > s_2."""
    switch = jnp.array([0.333, s2, 1.2345])

    def samples(s):
        return run(switch.at[1].set(s))[0].samples[:, 0]

    got = np.asarray(jax.jacrev(samples)(s2))
    _, ts = run(switch)
    y = exact(ts, 1.0, np.asarray(switch))
    want = np.where(ts > s2, (RATES[2] - RATES[1]) * y, 0.0)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    rev = jax.grad(lambda s: samples(s)[-1])(s2)
    assert float(rev) == pytest.approx(want[-1], rel=1e-9)


def test_a_stop_holds_the_last_sample_before_the_step_that_left_the_domain():
    switch = jnp.array([0.3, 0.6, 1.5])
    sol, ts = run(switch, floor=0.2)
    y = exact(ts, 1.0, np.asarray(switch))
    t_cross = ts[np.argmax(y <= 0.2)]  # first sample at or below the floor
    assert bool(sol.lost_sync)
    t_stop = float(sol.t_stop)
    assert t_cross - 0.05 < t_stop <= t_cross  # the step that crossed 0.2
    before = ts < t_stop
    np.testing.assert_allclose(sol.samples[before, 0], y[before], rtol=1e-10)
    last = np.flatnonzero(before)[-1]
    np.testing.assert_array_equal(sol.samples[~before, 0], sol.samples[last, 0])
    np.testing.assert_array_equal(sol.y_hold[0], sol.samples[last, 0])
    assert int(sol.num_steps) == int(round(t_stop / 0.01)) + 2  # two switches passed
