"""The controller family (smibjax.controllers): the paper's law with weighted
macro-variables, the boundary layer and the projection of the estimates; no control;
the conventional AVR + PSS + SVC regulator; the registry and its errors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smibjax as sj
import smibjax.controllers.synergetic as syn
from smibjax._closed_loop import ClosedLoop, closed_loop_vector_field, initial_state
from smibjax.controllers import (
    AvrPss,
    EstimateBox,
    NoControl,
    Synergetic,
    make_controller,
    project,
)
from smibjax.controllers.synergetic import evolution

REALISTIC = sj.Plant.preset("realistic")
LATE = sj.Fault(t_fault=5.0, t_clear=6.0, t_reclose=7.0)


@pytest.mark.parametrize("c1, c2", [(1.0, 1.0), (2.5, 0.7)])
@pytest.mark.parametrize("layer", [0.0, 0.01])
def test_weighted_macro_variables_follow_their_evolution_law(c1, c2, layer):
    """phi_i = c_i e1 + e2 + beta_i e_(i+2): with th_hat = theta on the nominal network
    and no limits, dphi_i/dt is the evolution law exactly (exact or boundary-layer
    form), for the paper's c = 1 and for other weights."""
    gains = sj.Gains(alpha=5 / 7, beta1=-1.3, beta2=-2.0, T2=0.5, c1=c1, c2=c2)
    ctrl = Synergetic(gains, phi_layer=layer)
    plant, op = sj.Plant(), sj.OperatingPoint()
    loop = ClosedLoop(ctrl, LATE, plant, op)
    y = jnp.array([0.62, 0.4, 1.3, 0.05, -0.2, 1.0, 0.0, 0.0])

    def phi(yy):
        return syn.control_law(yy[:4], yy[4:6], gains, plant, op, layer).phi

    p, dphi = jax.jvp(phi, (y,), (closed_loop_vector_field(0.0, y, loop),))
    e1, e2 = 0.62 - float(op.delta_e), 0.4
    x = syn.paper_coordinates(y[:4], plant)
    np.testing.assert_allclose(
        np.asarray(p),
        [c1 * e1 + e2 - 1.3 * (float(x[2]) - 1.0), c2 * e1 + e2 - 2.0 * float(x[3])],
        rtol=1e-12,
    )
    expect = [
        evolution(p[0], gains.T1, 5 / 7, layer),
        evolution(p[1], 0.5, 5 / 7, layer),
    ]
    np.testing.assert_allclose(np.asarray(dphi), np.asarray(expect), rtol=1e-8)


def test_boundary_layer_is_the_exact_law_far_from_zero_and_linear_near_it():
    a, T, eps = 5 / 7, 0.02, 0.01
    for phi in (0.5, -0.3):
        exact = float(syn.spow(-phi / T, a))
        assert float(evolution(phi, T, a, eps)) == pytest.approx(exact, rel=1e-3)
    slope = jax.grad(lambda p: evolution(p, T, a, eps))(0.0)
    assert float(slope) == pytest.approx(-(eps ** (a - 1)) / T**a, rel=1e-12)
    assert float(evolution(0.3, T, 1.0, eps)) == pytest.approx(-0.3 / T)


def test_projection_keeps_the_estimates_in_the_box():
    box = EstimateBox([-1.0, 0.0], [0.0, 2.0])
    # inside, away from the boundary layer: the law unchanged
    r = jnp.array([3.0, -4.0])
    np.testing.assert_array_equal(project(jnp.array([-0.5, 1.0]), r, box), r)
    # on the boundary: the outward component stops, the inward one passes
    out = project(jnp.array([0.0, 2.0]), jnp.array([3.0, 5.0]), box)
    np.testing.assert_array_equal(out, [0.0, 0.0])
    back = project(jnp.array([0.0, 2.0]), jnp.array([-3.0, -5.0]), box)
    np.testing.assert_array_equal(back, [-3.0, -5.0])
    # windup under the limits (gamma = 5, realizable): without projection th_hat runs
    # to hundreds; with it both estimates stay in the box
    g = sj.Gains(beta1=-1.0, beta2=-1.0, gamma1=5.0, gamma2=5.0)
    free = sj.simulate(Synergetic(g, oracle=False), plant=REALISTIC)
    boxed = sj.simulate(Synergetic(g, oracle=False, projection=box), plant=REALISTIC)
    assert float(jnp.max(jnp.abs(free.theta_hat))) > 50
    th = np.asarray(boxed.theta_hat)
    assert th[:, 0].min() >= -1.0 - 1e-9 and th[:, 0].max() <= 1e-9
    assert th[:, 1].min() >= -1e-9 and th[:, 1].max() <= 2.0 + 1e-9


@pytest.mark.parametrize("name", ["none", "avr-pss"])
def test_baselines_rest_at_the_operating_point(name):
    ctrl = make_controller(name)
    plant, op = REALISTIC, sj.OperatingPoint()
    y0 = initial_state(op, plant, sj.InitialEstimates(), ctrl)
    dy = closed_loop_vector_field(0.0, y0, ClosedLoop(ctrl, LATE, plant, op))
    np.testing.assert_allclose(np.asarray(dy[: 4 + ctrl.n_internal]), 0.0, atol=1e-12)


def test_conventional_baseline_keeps_synchronism_on_the_paper_fault():
    """Textbook AVR + PSS + SVC regulator under the realistic limits (issue 14)."""
    tr = sj.simulate(AvrPss(), sj.Fault(), REALISTIC)
    assert not bool(tr.lost_sync) and bool(tr.stable)
    assert float(jnp.max(jnp.abs(tr.u_f))) <= 5.0 + 1e-9
    assert float(jnp.max(jnp.abs(tr.u_r))) <= 1.0 + 1e-9
    # the PSS acts during the swing, within its output limit (diagnostic 0: v_s)
    v_s = np.asarray(tr.phi)[:, 0]
    assert 0.01 < np.max(np.abs(v_s)) <= 0.2 + 1e-12


class _StateAsCommand(AvrPss):
    """The AVR + PSS as it reported before issue 14's fix: the non-windup lags'
    states as the commanded inputs (never beyond the limits)."""

    def __call__(self, t, z, s, stage, plant, op, trig=None):
        out = super().__call__(t, z, s, stage, plant, op, trig)
        return out._replace(u_f=s[0], u_r=s[4])


def test_avr_pss_commands_its_demand_while_the_limiter_holds_it():
    """At the field ceiling with the voltage low (fault on), the exciter's lag is
    held and the command is the regulator's demand K_A (Vt_ref - Vt + v_s) beyond
    the ceiling, so the limiter shows in the time on a limit; inside the limits the
    command is the lag's state."""
    from smibjax._network import stage_at
    from smibjax._plant import apply_limits

    ctrl, plant, op = AvrPss(), REALISTIC, sj.OperatingPoint()
    fault = sj.Fault()
    z0 = initial_state(op, plant, sj.InitialEstimates(), ctrl)[:4]
    stage = stage_at(jnp.asarray(0.6), fault, plant)  # fault on: Vt well below ref
    s = jnp.zeros(ctrl.n_internal).at[0].set(plant.uf_max).at[4].set(plant.ur_max)
    out = ctrl(0.6, z0, s, stage, plant, op)
    assert float(out.d_internal[0]) == 0.0 and float(out.d_internal[4]) == 0.0
    assert float(out.u_f) > 10 * float(plant.uf_max)  # K_A = 200 on a large error
    assert float(out.u_r) > float(plant.ur_max)
    u_f, u_r = apply_limits(out.u_f, out.u_r, plant)  # the plant applies the limits
    assert float(u_f) == float(plant.uf_max) and float(u_r) == float(plant.ur_max)
    old = _StateAsCommand()(0.6, z0, s, stage, plant, op)
    assert float(old.u_f) == float(plant.uf_max)  # before the fix: never on a limit
    inside = s.at[0].set(2.0).at[4].set(0.1)
    out = ctrl(0.6, z0, inside, stage, plant, op)
    assert float(out.u_f) == 2.0 and float(out.u_r) == 0.1


def test_avr_pss_limit_metrics_see_the_ceiling_on_the_paper_fault():
    """The fix changes what is reported, not what is applied: the same trajectory
    as the lag states as commands, while the peak command is the exciter's demand
    (about 100 pu, not the 5 pu ceiling) and the time on a limit is at least the
    time the applied field voltage sits at its ceiling."""
    from smibjax._metrics import metrics

    new = sj.simulate(AvrPss(), sj.Fault(), REALISTIC)
    old = sj.simulate(_StateAsCommand(), sj.Fault(), REALISTIC)
    np.testing.assert_allclose(np.asarray(new.delta), np.asarray(old.delta), atol=1e-8)
    np.testing.assert_allclose(np.asarray(new.u_f), np.asarray(old.u_f), atol=1e-6)
    m, m_old = metrics(new), metrics(old)
    assert float(m.peak_uf_cmd) > 50.0 and float(m_old.peak_uf_cmd) < 5.01
    assert float(m.peak_ur_cmd) > 2.0 and float(m_old.peak_ur_cmd) < 1.01
    at_ceiling = np.mean(np.abs(np.asarray(new.u_f)) >= float(REALISTIC.uf_max) - 1e-9)
    assert at_ceiling > 0.01
    assert float(m.limit_time_uf) >= at_ceiling


def test_angle_range_is_the_controllers():
    assert Synergetic(sj.Gains()).angle_range == (0.0, np.pi)
    assert NoControl().angle_range == (-np.pi, np.pi)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: make_controller("pid"), "controller = 'pid' is not allowed"),
        (lambda: make_controller("avr-pss", {"beta1": 1.0}), "not a parameter of"),
        (lambda: sj.Gains(c1=0.0), "Gains.c1 = 0 is not allowed"),
        (lambda: sj.Gains(c2=-1.0), "Gains.c2 = -1 is not allowed"),
        (lambda: EstimateBox([0.0, 0.0], [0.0, 2.0]), "empty"),
        (lambda: AvrPss(T_A=-0.1), "AvrPss.T_A = -0.1 is not allowed"),
        (
            lambda: sj.simulate(
                Synergetic(sj.Gains(), projection=EstimateBox([0.0, 0.0], [1.0, 2.0]))
            ),
            "initial estimates .* must lie in the projection box",
        ),
        (lambda: Synergetic(sj.Gains(), phi_layer=-1.0), "phi_layer = -1.0"),
    ],
)
def test_bad_controller_input_is_one_clear_error(call, match):
    with pytest.raises(sj.ParameterError, match=match):
        call()
