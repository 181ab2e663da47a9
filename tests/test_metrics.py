"""Exact metrics against closed forms on synthetic signals."""

import jax.numpy as jnp
import numpy as np
import pytest

from smibjax.metrics import metrics, settling_time


def test_settling_time_of_exponential_decay():
    # |A exp(-(t - tf)/tau)| = band at t - tf = tau ln(A / band)
    t = jnp.linspace(0.0, 10.0, 10001)
    tf, tau, A, band = 0.5, 0.8, 0.3, 0.01
    sig = jnp.where(t >= tf, A * jnp.exp(-(t - tf) / tau), 0.0)
    ts = settling_time(t, 1.0 + sig, 1.0, band, tf)
    assert float(ts) == pytest.approx(tau * np.log(A / band), abs=1e-6)


def test_settling_time_edge_cases():
    t = jnp.linspace(0.0, 5.0, 501)
    assert float(settling_time(t, jnp.zeros_like(t), 0.0, 0.01, 1.0)) == 0.0
    assert float(settling_time(t, t, 0.0, 0.01, 1.0)) == np.inf  # still outside
    # a bump before t_from does not count
    bump = jnp.where(t < 0.5, 1.0, 0.0)
    assert float(settling_time(t, bump, 0.0, 0.01, 1.0)) == 0.0


def test_metrics_of_stable_and_unstable_runs(jax_runs, paper_run):
    m = metrics(jax_runs["aftsc"])
    assert bool(m.stable)
    assert 3.0 < float(m.settling_delta) < 6.0
    tr = jax_runs["aftsc"]
    dev = np.abs(np.asarray(tr.delta) - 0.4964)
    assert float(m.overshoot) == pytest.approx(dev[np.asarray(tr.t) >= 0.5].max())
    # effort integral against the trapezoid rule on the samples (u_f is smooth after
    # the first 10 ms spike, so compare loosely)
    uf2 = np.asarray(tr.u_f) ** 2
    trap = np.sum(0.5 * (uf2[1:] + uf2[:-1]) * np.diff(np.asarray(tr.t)))
    assert float(m.effort_uf) == pytest.approx(trap, rel=0.1)
    mu = metrics(paper_run)
    assert not bool(mu.stable) and float(mu.settling_delta) == np.inf


def test_a_run_that_spent_its_step_budget_has_no_metrics():
    """Issue 16: `--max-steps 1` stops at t = 0; its metrics are "not reached" (NaN),
    not a settling time of 0 s and an overshoot of 0."""
    import smibjax as sj

    tr = sj.simulate(sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0), max_steps=1)
    assert bool(tr.budget_exhausted) and float(tr.t_stop) == 0.0
    m = metrics(tr)
    assert not bool(m.stable)
    for k, v in m._asdict().items():
        if k != "stable":
            assert np.isnan(float(v)), k
    # a run that gets there keeps numbers
    full = metrics(sj.simulate(sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0)))
    assert bool(full.stable) and 3.0 < float(full.settling_delta) < 6.0
    assert float(full.overshoot) > 0.1
