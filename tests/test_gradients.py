"""Gradients with respect to gains and the clearing time against central finite
differences of the same computation.

Measured (see README "Gradients"): with alpha = 1 both the adaptive and the fixed-step
path match to ~1e-6; with alpha = 5/7 the fixed-step path matches and the adaptive one
does not for gains that barely move the loss (the finite-time law's step-size
selection), so the AFTSC checks use `solver="fixed"`.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smibjax as sj
from conftest import STABLE

FAULT = sj.Fault(t_clear=0.7037)  # clearing off the 10 ms sample grid


@eqx.filter_jit
def loss(gains, fault, solver):
    """Mean squared angle error: smooth in the gains and in the switch times."""
    tr = sj.simulate(gains, fault, t_end=4.0, solver=solver)
    return jnp.mean((tr.delta - tr.delta_e) ** 2)


def central_difference(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


CASES = [
    ("asc", "adaptive", "beta1"),
    ("asc", "adaptive", "T1"),
    ("aftsc", "fixed", "beta1"),
    ("aftsc", "fixed", "T1"),
]


@pytest.mark.parametrize("controller, solver, name", CASES)
def test_gain_gradient_matches_finite_differences(controller, solver, name):
    gains = sj.Gains.paper(controller, **STABLE)

    def f(v):
        return loss(eqx.tree_at(lambda g: getattr(g, name), gains, v), FAULT, solver)

    v0 = getattr(gains, name)
    ad = jax.grad(f)(v0)
    # Difference step: on adaptive steps the step-size selection adds noise of order
    # rtol, so the step must not be too small; on the fixed grid the finite-time law
    # chatters near phi = 0 and larger differences average over it (AFTSC T1: a
    # relative step of 1e-2 is 2% off, 1e-5 is 2e-4 off).
    rel_h = 1e-4 if solver == "adaptive" else 1e-5
    fd = central_difference(f, v0, rel_h * abs(float(v0)))
    assert float(ad) == pytest.approx(float(fd), rel=1e-3)


def test_plant_parameter_gradient_matches_finite_differences():
    """d loss / d XL (line reactance: it moves every network stage and the controller's
    nominal model)."""
    gains = sj.Gains.paper("asc", **STABLE)

    @eqx.filter_jit
    def f(xl):
        run = sj.simulate(gains, FAULT, sj.Plant(XL=xl), t_end=4.0)
        return jnp.mean((run.delta - run.delta_e) ** 2)

    ad = jax.grad(f)(jnp.asarray(0.2))
    fd = central_difference(f, 0.2, 1e-6)
    assert float(ad) == pytest.approx(float(fd), rel=1e-3)
    assert abs(float(ad)) > 1e-4


@pytest.mark.parametrize(
    "controller, solver", [("asc", "adaptive"), ("aftsc", "fixed")]
)
def test_clearing_time_gradient_matches_finite_differences(controller, solver):
    gains = sj.Gains.paper(controller, **STABLE)

    def f(tc):
        return loss(gains, eqx.tree_at(lambda x: x.t_clear, FAULT, tc), solver)

    ad = jax.grad(f)(FAULT.t_clear)
    fd = central_difference(f, FAULT.t_clear, 1e-5)
    assert float(ad) == pytest.approx(float(fd), rel=1e-3)
    assert abs(float(ad)) > 1e-3  # a real sensitivity, not a vanishing one


def test_state_sensitivity_to_clearing_time_across_reclosure():
    """d delta(t)/d t_clear at every sample, through both later switches: the
    derivative of the discrete solution must not blow up after t_reclose (it does
    without smibjax's rigid step grid, see smibjax/_stepping.py)."""
    gains = sj.Gains.paper("asc", **STABLE)

    def delta(tc):
        return sj.simulate(gains, sj.Fault(t_clear=tc), t_end=3.0, solver="fixed").delta

    idx = jnp.array([150, 199, 201, 205, 250, 300])  # t = 1.5 ... 3.0 s
    jac = jax.jacrev(lambda tc: delta(tc)[idx])(jnp.asarray(0.7))
    fd = central_difference(lambda tc: delta(tc)[idx], 0.7, 1e-5)
    np.testing.assert_allclose(np.asarray(jac), np.asarray(fd), rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("solver", ["adaptive", "fixed"])
def test_gradients_are_finite_on_an_unstable_run(solver):
    gains = sj.Gains.paper("aftsc")  # loses synchronism
    g = jax.grad(lambda gg, ff: loss(gg, ff, solver), argnums=(0, 1))(gains, FAULT)
    for leaf in jax.tree_util.tree_leaves(g):
        assert np.all(np.isfinite(np.asarray(leaf)))
