"""Non-windup lag with limits that move (EXDC2's [VRMIN Vt, VRMAX Vt]) against a
NumPy oracle integrated as PSS/E does: a small fixed step, integrate, then clamp the
state to the current limits (ANDES's `AntiWindup` resets the state to the limit the
same way). The oracle's own convergence in the step is checked first."""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax.grid.devices import _blocks
from smibjax.grid.devices._blocks import lag_nonwindup
from smibjax.grid.devices.ieeex1 import EXDC2

K, T, VRMAX, VRMIN = 1.0, 0.05, 5.0, -5.0
T_PUSH, T_REV1, T_PUSH2, T_REV2, T_END = 0.2, 1.0, 1.3, 2.5, 3.0
JUMPS = (T_PUSH, T_REV1, T_PUSH2, T_REV2)
KINKS = (0.5, 0.7, 1.5, 2.0)  # Vt's ramps: 1 -> 0.4 over 0.5-0.7 s, back 1.5-2.0 s


def demand(t):
    """K u (pu): 20 from T_PUSH to T_REV1 and from T_PUSH2 to T_REV2, else 1."""
    on = ((t >= T_PUSH) & (t < T_REV1)) | ((t >= T_PUSH2) & (t < T_REV2))
    return jnp.where(on, 20.0, 1.0)


def vt(t):
    """The limits' scale (pu): 1, down to 0.4 along 0.5-0.7 s (the ceiling falls
    below the state), up to 1 along 1.5-2.0 s (rises while the demand pushes)."""
    down = jnp.clip((t - 0.5) / 0.2, 0.0, 1.0)
    up = jnp.clip((t - 1.5) / 0.5, 0.0, 1.0)
    return 1.0 - 0.6 * down + 0.6 * up


def oracle(h):
    """PSS/E-style: Heun's step on T dx/dt = K u - x from each sample, then the state
    clamped to [VRMIN vt, VRMAX vt] at the new time. Returns (t, y = x)."""
    n = int(round(T_END / h))
    t = np.linspace(0.0, T_END, n + 1)
    u = np.asarray(demand(t)) / K
    lim = np.asarray(vt(t))
    x = np.empty(n + 1)
    x[0] = 1.0
    for k in range(n):
        # the input is sampled at the step's start (a step change lands on a sample)
        f0 = (K * u[k] - x[k]) / T
        xp = x[k] + h * f0
        f1 = (K * u[k] - xp) / T
        x[k + 1] = min(
            max(x[k] + 0.5 * h * (f0 + f1), VRMIN * lim[k + 1]), VRMAX * lim[k + 1]
        )
    return t, x


def solve(moving, rtol=1e-8, ts=None, t_end=T_END):
    """lag_nonwindup driven by the prescribed signals, adaptive Tsit5 (rtol, atol =
    rtol / 100, 100,000 steps at most): (y at ts, accepted steps, result)."""

    def f(t, x, args):
        return lag_nonwindup(x, demand(t), K, T, VRMIN * vt(t), VRMAX * vt(t), moving)[
            1
        ]

    ts = jnp.asarray(ts)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(f),
        diffrax.Tsit5(),
        0.0,
        t_end,
        1e-3,
        jnp.array(1.0),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(
            rtol=rtol,
            atol=rtol * 1e-2,
            jump_ts=jnp.asarray([t for t in JUMPS + KINKS if t < t_end]),
        ),
        max_steps=100_000,
        throw=False,
    )
    y = jnp.clip(sol.ys, VRMIN * vt(ts), VRMAX * vt(ts))
    return np.asarray(y), int(sol.stats["num_accepted_steps"]), sol.result


_CACHE = {}


def _oracle():
    if "o" not in _CACHE:
        _CACHE["o"] = oracle(2e-5)
    return _CACHE["o"]


def test_oracle_is_converged_in_its_step():
    t, x = _oracle()
    t2, x2 = oracle(4e-5)
    assert np.max(np.abs(x[::2] - x2)) < 2e-3  # first order at the corners
    # the scenario: the state rides the falling ceiling down to 2 before T_REV1 ...
    at = np.searchsorted(t, 0.99)
    np.testing.assert_allclose(x[at], VRMAX * 0.4, atol=1e-12)
    # ... leaves it at once when the demand drops to 1: 1 + e^{-(t - T_REV1)/T} ...
    s = t[(t > T_REV1) & (t < 1.2)] - T_REV1
    np.testing.assert_allclose(
        x[(t > T_REV1) & (t < 1.2)], 1.0 + (2.0 - 1.0) * np.exp(-s / T), atol=1e-4
    )
    # ... and rides the rising ceiling up (its rate 6 pu/s, the lag's ~300 pu/s)
    mid = (t > 1.55) & (t < 1.95)
    np.testing.assert_allclose(x[mid], VRMAX * np.asarray(vt(t[mid])), atol=1e-12)


def test_held_state_departs_from_the_oracle_after_a_falling_ceiling():
    """The rule for constant limits (state held, not swept) keeps x = 5 while the
    ceiling falls to 2; when the demand drops to 1 at T_REV1 the output stays at the
    ceiling until x has decayed to it: x = 1 + 4 e^{-s/T} reaches 2 at s = T ln 4,
    where the oracle is at 1 + e^{-ln 4} = 1.25, a departure of 0.75 pu."""
    t, x = _oracle()
    keep = t <= T_PUSH2
    ts, xo = t[keep][::10], x[keep][::10]
    y, _, res = solve(False, ts=ts, t_end=T_PUSH2)
    assert res == diffrax.RESULTS.successful
    dep = np.abs(y - xo)
    assert dep.max() == pytest.approx(0.75, abs=5e-3)
    assert ts[np.argmax(dep)] == pytest.approx(T_REV1 + T * np.log(4.0), abs=2e-4)
    # the sweeping rule, on the same stretch: within 1e-6 after the reversal (2e-8)
    y2, _, _ = solve(True, ts=ts, t_end=T_PUSH2)
    after = ts > T_REV1
    assert np.abs(y2 - xo)[after].max() < 1e-6


def test_sweeping_rule_follows_the_oracle():
    """The moving-limit rule (tau = T / SWEEP) against the oracle over the whole
    scenario: on the falling ceiling the output is the limit, and after the reversal
    the state leaves it at once; on the rising ceiling (6 pu/s) it lags by tau * 6;
    pushed onto a limit it arrives as a lag of time constant tau (the one place
    where it is late: within 10 tau of the oracle to 1e-3)."""
    t, x = _oracle()
    ts, xo = t[::10], x[::10]
    y, _, res = solve(True, ts=ts)
    assert res == diffrax.RESULTS.successful
    tau = T / _blocks.SWEEP
    dep = np.abs(y - xo)
    far = np.ones(ts.size, bool)
    for c in (T_PUSH, T_PUSH2):
        far &= ~((ts >= c) & (ts < c + 0.03))
    assert dep[far].max() < 1.2 * tau * 6.0, dep[far].max()
    for c in (T_PUSH, T_PUSH2):
        w = (ts >= c) & (ts < c + 0.03)
        lim = VRMAX * np.asarray(vt(ts[w]))
        t_o = ts[w][np.argmax(xo[w] >= lim - 1e-3)]
        t_y = ts[w][np.argmax(y[w] >= lim - 1e-3)]
        assert 0.0 <= t_y - t_o < 10 * tau, (c, t_y - t_o)


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10])
def test_sweeping_rule_needs_few_steps_on_a_rising_limit(rtol):
    """No switching surface to chatter on: the adaptive solver completes in a few
    hundred steps at every rtol, where the held rule chatters on the rising ceiling
    (x overshoots it, stops, falls behind it) and spends all 100,000 steps from
    rtol 1e-8 (at 1e-6 it completes, in many more steps)."""
    ts = np.linspace(0.0, T_END, 31)
    _, n_new, res = solve(True, rtol=rtol, ts=ts)
    _, n_old, res_old = solve(False, rtol=rtol, ts=ts)
    assert res == diffrax.RESULTS.successful
    assert n_new < 2000, n_new
    if rtol <= 1e-8:
        assert res_old == diffrax.RESULTS.max_steps_reached
    else:
        assert n_old > 5 * n_new, (n_old, n_new)


def test_constant_limits_unchanged_and_gradients_finite():
    """moving=False is the held rule exactly; the sweeping rule's gradients with
    respect to the input, the state and the limits are finite, also at a limit."""
    x = jnp.array([5.0, 5.2, 4.9, -5.0, 0.0])
    u = jnp.array([20.0, 20.0, -3.0, -20.0, 1.0])
    lo, hi = -5.0 * jnp.ones(5), 5.0 * jnp.ones(5)
    y0, d0 = lag_nonwindup(x, u, K, T, lo, hi)
    y1, d1 = lag_nonwindup(x, u, K, T, lo, hi, False)
    np.testing.assert_array_equal(d0, d1)
    np.testing.assert_array_equal(d0, [0.0, 0.0, (-3.0 - 4.9) / T, 0.0, 20.0])

    def g(x, u, hi):
        return jnp.sum(lag_nonwindup(x, u, K, T, lo, hi, True)[1])

    for grad in jax.grad(g, argnums=(0, 1, 2))(x, u, hi):
        assert np.all(np.isfinite(np.asarray(grad)))
    # at rest inside the limits the rule is the lag itself
    _, d = lag_nonwindup(jnp.array(1.0), jnp.array(1.0), K, T, -5.0, 5.0, True)
    assert float(d) == 0.0


def test_exdc2_uses_the_sweeping_rule():
    """EXDC2's regulator swept down by a falling Vt: VR's derivative pulls a state
    above VRMAX Vt back to the ceiling (IEEEX1: held, derivative 0)."""
    dev = EXDC2(
        [0],
        TR=0.0,
        KA=100.0,
        TA=0.05,
        TB=0.0,
        TC=0.0,
        VRMAX=5.0,
        VRMIN=-5.0,
        KE=1.0,
        TE=0.5,
        KF=0.0,
        TF1=1.0,
        SWITCH=0.0,
        E1=0.0,
        SE1=0.0,
        E2=1.0,
        SE2=0.0,
    )
    meas = {"Vt": jnp.array([1.0]), "Vs": jnp.array([0.0])}
    x0, ref = dev.init(jnp.array([2.0]), meas)
    x = x0.at[2].set(5.0)  # VR on its ceiling at Vt = 1
    low = {"Vt": jnp.array([0.4]), "Vs": jnp.array([0.0])}  # demand 100*0.6 pushes up
    dvr = float(dev.rhs(x, low, ref)[2, 0])
    assert dvr == pytest.approx((2.0 - 5.0) / (0.05 / _blocks.SWEEP), rel=1e-12)


def test_andes_ieeex1_limiter_keeps_constant_limits():
    """The docs' reading of ANDES 2.0.0 (docs/performance.md, "What differs: IEEE
    39"): its IEEEX1 defines VRTMAX = VRMAX v but its lag's limiter keeps VRMAX, so
    its limits do not move with the voltage."""
    andes = pytest.importorskip("andes")
    from smibjax.grid.cases import case_file

    andes.config_logger(stream_level=50)
    ss = andes.load(
        str(case_file("ieee39.raw")),
        addfile=str(case_file("ieee39.dyr")),
        setup=True,
        no_output=True,
        default_config=True,
    )
    la = ss.IEEEX1.LA
    assert (la.upper.name, la.lower.name) == ("VRTMAX", "VRTMIN")
    assert (la.lim.upper.name, la.lim.lower.name) == ("VRMAX", "VRMIN")


def test_sweeping_rule_gradient_through_the_solve_matches_finite_differences():
    """d y(1.03 s)/d T through the adaptive solve (the state swept down the falling
    ceiling, then released at T_REV1): finite, and equal to central differences."""

    def y_at(Tl):
        def f(t, x, args):
            lo, hi = VRMIN * vt(t), VRMAX * vt(t)
            return lag_nonwindup(x, demand(t), K, Tl, lo, hi, True)[1]

        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(f),
            diffrax.Tsit5(),
            0.0,
            1.03,
            1e-3,
            jnp.array(1.0),
            stepsize_controller=diffrax.PIDController(
                rtol=1e-8, atol=1e-10, jump_ts=jnp.asarray([T_PUSH, 0.5, 0.7, T_REV1])
            ),
            max_steps=100_000,
        )
        return sol.ys[-1]

    g = float(jax.grad(y_at)(T))
    h = 1e-5
    fd = float((y_at(T + h) - y_at(T - h)) / (2 * h))
    assert np.isfinite(g)
    # released from 2 at T_REV1 towards 1: y = 1 + e^{-s/T}, dy/dT = s/T^2 e^{-s/T}
    s = 0.03
    assert g == pytest.approx(s / T**2 * np.exp(-s / T), rel=2e-2)
    assert g == pytest.approx(fd, rel=1e-4)
