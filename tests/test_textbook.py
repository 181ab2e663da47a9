"""The textbook check (issue 14): with no control, D = 0 and E' frozen (T0 very large),
the SMIB is the classical model, and the critical clearing time of a bolted fault on
circuit 1 follows from the equal-area criterion (critical angle in closed form) and the
fault-on swing equation (integrated here by SciPy, independently of smibjax)."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import smibjax as sj
from smibjax.controllers import NoControl

H, F, X1, XL, V, PM, DELTA0 = 5.0, 60.0, 0.3, 0.2, 1.0, 1.0, 0.4964
T_FAULT = 0.1


def equal_area_cct(lam: float) -> tuple[float, float]:
    """(CCT in s, critical clearing angle in rad) of the classical model.

    Pre-fault X = X1 + XL; fault-on X = X1 + 2 XL + X1/lam (star-delta of the bolted
    fault at fraction lam of circuit 1, MODEL.md section 1); post-fault X = X1 + 2 XL.
    Equal areas: cos d_cr = (Pm (d_max - d0) + P_post cos d_max - P_f cos d0) /
    (P_post - P_f), d_max = pi - asin(Pm / P_post); then the fault-on swing
    M d'' = Pm - P_f sin d from rest at d0 reaches d_cr at the CCT."""
    m = 2 * H / (2 * math.pi * F)
    e = PM * (X1 + XL) / (V * math.sin(DELTA0))
    p_f = e * V / (X1 + 2 * XL + X1 / lam)
    p_post = e * V / (X1 + 2 * XL)
    d_max = math.pi - math.asin(PM / p_post)
    c = PM * (d_max - DELTA0) + p_post * math.cos(d_max) - p_f * math.cos(DELTA0)
    d_cr = math.acos(c / (p_post - p_f))

    def reach(t, y):
        return y[0] - d_cr

    reach.terminal = True
    sol = solve_ivp(
        lambda t, y: [y[1], (PM - p_f * math.sin(y[0])) / m],
        (0.0, 5.0),
        [DELTA0, 0.0],
        events=reach,
        rtol=1e-12,
        atol=1e-12,
    )
    return float(sol.t_events[0][0]), d_cr


CLASSICAL = sj.Plant(D=0.0, T0=1e6)  # the largest value allowed: E' frozen


@pytest.fixture(scope="module")
def lost_sync_at():
    """Jitted (lam, fault duration) lanes -> lost synchronism within 3 s."""

    @jax.jit
    def run(lam, dur):
        def one(lm, d):
            f = sj.Fault(t_fault=T_FAULT, t_clear=T_FAULT + d, t_reclose=20.0, lam=lm)
            return sj.simulate(NoControl(), f, CLASSICAL, t_end=3.0).lost_sync

        return jax.vmap(one)(lam, dur)

    return run


def test_equal_area_cct_brackets_the_simulated_boundary(lost_sync_at):
    lams = [0.2, 0.5, 0.8]
    ccts = [equal_area_cct(lam)[0] for lam in lams]
    # closed-form values (a regression guard of the formula itself)
    np.testing.assert_allclose(ccts, [0.2253, 0.3147, 0.4162], atol=5e-4)
    lam = np.repeat(lams, 2)
    dur = np.array([[c - 0.002, c + 0.002] for c in ccts]).ravel()
    lost = np.asarray(lost_sync_at(lam, dur)).reshape(3, 2)
    # stable 2 ms before the equal-area CCT, loss of synchronism 2 ms after it
    assert not lost[:, 0].any() and lost[:, 1].all()


def test_no_control_holds_the_operating_point():
    f = sj.Fault(t_fault=1.5, t_clear=1.6, t_reclose=1.7)
    tr = sj.simulate(NoControl(), f, CLASSICAL, t_end=2.0)
    before = np.asarray(tr.t) <= 1.5
    np.testing.assert_allclose(np.asarray(tr.delta)[before], DELTA0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(tr.u_r), 0.0)
    # E' frozen: T0 = 1e6 s moves it by about 1e-7 in the fault's 0.5 s
    np.testing.assert_allclose(np.asarray(tr.E), float(tr.E[0]), rtol=1e-6)


def test_cct_synchronism_criterion_matches_the_equal_area_criterion():
    """`critical_clearing_times(criterion="synchronism")` with no control on the
    classical model: within 2 ms of the equal-area CCT at three locations."""
    from smibjax._cct import critical_clearing_times

    lams = (0.2, 0.5, 0.8)
    res = critical_clearing_times(
        {"none": NoControl()},
        CLASSICAL,
        fault_locations=lams,
        fault_time=T_FAULT,
        reclose_time=2.9,
        t_end=3.0,
        tol=5e-4,
        criterion="synchronism",
    )
    got = res.sets["none"].cct
    want = [equal_area_cct(lam)[0] for lam in lams]
    assert res.sets["none"].status == ["ok"] * 3
    np.testing.assert_allclose(got, want, atol=2e-3)
