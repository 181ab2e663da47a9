"""Controller: jvp-derived f and g against MODEL.md's closed forms, the synergetic
evolution law as an invariant of the closed loop, and the equilibrium."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smibjax as sj
import smibjax.controllers.synergetic as syn
from helpers import case_rng
from smibjax._closed_loop import ClosedLoop, closed_loop_vector_field
from smibjax._plant import sincos


def random_state(rng):
    return jnp.array(
        [
            rng.uniform(0.1, 3.0),
            rng.uniform(-3, 3),
            rng.uniform(0.3, 2),
            rng.uniform(-2, 2),
        ]
    )


@pytest.mark.parametrize("k", range(20))
def test_jvp_drift_and_gain_equal_closed_forms(k):
    """The control law evaluates the closed forms; the jvp of the coordinate map
    along the plant's own field is the reference they must equal, on any plant."""
    rng = case_rng("jvp", k)
    plant = sj.Plant(
        Tr=rng.uniform(0.2, 2),
        T0=rng.uniform(2, 8),
        B0=rng.uniform(-0.1, 0.1),
        V=rng.uniform(0.9, 1.1),
        Xd=rng.uniform(0.8, 2.0),
        Xdp=rng.uniform(0.1, 0.4),
        XT=rng.uniform(0.05, 0.2),
        XL=rng.uniform(0.1, 0.6),
    )
    z = random_state(rng)
    f, g = syn.drift_and_gain(z, plant)
    fc, gc = syn.drift_and_gain_closed_form(z, plant)
    np.testing.assert_allclose(np.asarray(f), np.asarray(fc), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(g), np.asarray(gc), rtol=1e-12, atol=1e-12)
    # The shared (sin, cos) of the closed loop gives the same values as computing
    # them in place.
    trig = sincos(z[0])
    ft, gt = syn.drift_and_gain_closed_form(z, plant, trig)
    np.testing.assert_array_equal(np.asarray(ft), np.asarray(fc))
    np.testing.assert_array_equal(np.asarray(gt), np.asarray(gc))
    np.testing.assert_array_equal(
        np.asarray(syn.paper_coordinates(z, plant, trig)),
        np.asarray(syn.paper_coordinates(z, plant)),
    )


def test_sincos_values_and_derivatives_are_those_of_sin_and_cos():
    d = jnp.array([-2.0, 0.0, 0.4964, 3.0])
    s, c = jax.jit(sincos)(d)
    np.testing.assert_array_equal(np.asarray(s), np.sin(np.asarray(d)))
    np.testing.assert_array_equal(np.asarray(c), np.cos(np.asarray(d)))

    def f(x):
        s, c = sincos(x)
        return s * s * c + 2 * c

    def ref(x):
        return jnp.sin(x) ** 2 * jnp.cos(x) + 2 * jnp.cos(x)

    for fn in (jax.grad, lambda h: jax.grad(jax.grad(h))):
        got = jax.vmap(fn(f))(d)
        want = jax.vmap(fn(ref))(d)
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-13)


@pytest.mark.parametrize("alpha", [1.0, 5 / 7])
def test_the_field_computes_one_sine_and_one_cosine(alpha):
    """The compiled, vmapped closed-loop field evaluates sin and cos of the rotor
    angle once each (`smibjax._plant.sincos`). Computed where each is used, XLA's
    CPU fusion evaluated five sines and three cosines: about half the cost of a
    Monte Carlo run."""
    g = syn.static_alpha(sj.Gains.paper("asc", alpha=alpha, beta1=-1.0))
    plant, op = sj.Plant(), sj.OperatingPoint()
    faults = jax.vmap(lambda t: sj.Fault(t_fault=t))(jnp.linspace(0.3, 0.9, 8))

    def field(fault, y, t):
        return closed_loop_vector_field(t, y, ClosedLoop(g, fault, plant, op))

    y = jnp.tile(sj.initial_state(op, plant, sj.InitialEstimates()), (8, 1))
    hlo = (
        jax.jit(jax.vmap(field))
        .lower(faults, y + 0.01, jnp.full((8,), 0.5))
        .compile()
        .as_text()
    )
    assert hlo.count(" sine(") == 1
    assert hlo.count(" cosine(") == 1


def test_spow_values_and_finite_derivative_at_zero():
    a = 5 / 7
    assert float(syn.spow(-8.0, a)) == pytest.approx(-(8.0**a))
    assert float(syn.spow(0.0, a)) == 0.0
    dy = jax.grad(syn.spow)(0.0, a)
    assert np.isfinite(float(dy)) and float(dy) > 0
    assert float(jax.grad(syn.spow)(2.0, a)) == pytest.approx(a * 2.0 ** (a - 1))
    da = jax.grad(syn.spow, argnums=1)(2.0, a)
    assert float(da) == pytest.approx(2.0**a * np.log(2.0))
    assert float(jax.grad(syn.spow, argnums=1)(0.0, a)) == 0.0


@pytest.mark.parametrize("alpha", [5 / 7, 1.0])
@pytest.mark.parametrize("k", range(4))
def test_macro_variables_follow_the_evolution_law(alpha, k):
    """With th_hat = theta on the nominal (pre-fault) network and no limits, the control
    law makes dphi_i/dt = spow(-phi_i/T_i, alpha) exactly (eq. 26)."""
    rng = case_rng("evolution", alpha, k)
    gains = sj.Gains(alpha=alpha, beta1=rng.uniform(-5, 5) or 1.0, beta2=-2.0, T2=0.5)
    plant, op = sj.Plant(), sj.OperatingPoint()
    loop = ClosedLoop(
        gains, sj.Fault(t_fault=5.0, t_clear=6.0, t_reclose=7.0), plant, op
    )
    y = jnp.concatenate(
        [
            random_state(rng) * jnp.array([0.3, 0.3, 1, 0.1])
            + jnp.array([0.3, 0, 0.5, 0]),
            jnp.array([-0.2, 1.0, 0.0, 0.0]),
        ]
    )

    def phi(yy):
        return syn.control_law(yy[:4], yy[4:6], gains, plant, op).phi

    dy = closed_loop_vector_field(0.0, y, loop)
    p, dphi = jax.jvp(phi, (y,), (dy,))
    expect = jnp.stack(
        [syn.spow(-p[0] / gains.T1, alpha), syn.spow(-p[1] / gains.T2, alpha)]
    )
    np.testing.assert_allclose(
        np.asarray(dphi), np.asarray(expect), rtol=1e-8, atol=1e-8
    )


@pytest.mark.parametrize("adaptation", [True, False])
def test_operating_point_is_a_closed_loop_equilibrium(adaptation):
    plant, op = sj.Plant(), sj.OperatingPoint()
    init = sj.InitialEstimates(th1=-float(plant.D), th2=float(plant.Pm))
    y = sj.initial_state(op, plant, init)
    loop = ClosedLoop(sj.Gains(), sj.Fault(), plant, op, oracle=adaptation)
    dy = closed_loop_vector_field(0.0, y, loop)
    np.testing.assert_allclose(np.asarray(dy[:6]), 0.0, atol=1e-10)
    out = syn.control_law(y[:4], y[4:6], sj.Gains(), plant, op)
    assert float(out.u_f) == pytest.approx(
        (1.4 * float(y[2]) - 0.9 * np.cos(0.4964)) / 0.5
    )
    assert float(out.u_r) == pytest.approx(0.0, abs=1e-12)


def test_static_alpha_one_drops_the_signed_powers_and_changes_no_value():
    """ASC with alpha = 1 compiled in: the same field to rounding, no log/exp left."""
    g = sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0)
    fixed = syn.static_alpha(g)
    assert fixed.alpha == 1.0 and isinstance(fixed.alpha, float)
    # AFTSC, and alpha = 1 that is traced, are left alone.
    aftsc = sj.Gains.paper("aftsc")
    assert syn.static_alpha(aftsc) is aftsc
    seen = []
    jax.jit(lambda gg: seen.append(syn.static_alpha(gg).alpha) or 0.0)(g)
    assert isinstance(seen[0], jax.core.Tracer)

    fault, plant, op = sj.Fault(), sj.Plant(), sj.OperatingPoint()
    y = jnp.array([0.7, 0.4, 1.3, 0.2, -0.3, 0.8, 0.0, 0.0])

    def field(gains):
        loop = ClosedLoop(gains, fault, plant, op)
        return closed_loop_vector_field(jnp.asarray(0.9), y, loop)

    traced = jax.jit(field)
    static = jax.jit(lambda: field(fixed))
    np.testing.assert_allclose(static(), traced(g), rtol=1e-13, atol=1e-13)
    # spow lowers to log + exp; with alpha = 1 compiled in neither is left.
    assert "log" in traced.lower(g).as_text()
    assert "log" not in static.lower().as_text()
    assert "exponential" not in static.lower().as_text()
