"""Exact metrics against closed forms on synthetic signals."""

import jax.numpy as jnp
import numpy as np
import pytest

import reference
from smibjax._metrics import metrics, settling_time

# the tests that read the session fixtures `reference_runs` (SciPy at rtol 1e-9,
# ~4 CPU-s), `jax_runs` and `paper_run` (conftest.py) run on one worker: under
# -n 2 the other worker computed them again
pytestmark = pytest.mark.xdist_group("reference_runs")


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


def last_exit(t, dev, band, t_from):
    """Settling time written out with NumPy: the last crossing of the band from
    outside to inside after t_from, linearly interpolated, minus t_from."""
    out = np.flatnonzero((dev > band) & (t >= t_from))
    i = out[-1]
    frac = (dev[i] - band) / (dev[i] - dev[i + 1])
    return t[i] + frac * (t[i + 1] - t[i]) - t_from


@pytest.mark.parametrize("controller", ["aftsc", "asc"])
def test_settling_times_match_the_independent_reference(
    controller, jax_runs, reference_runs
):
    """Settling of delta and omega against the SciPy integration of MODEL.md
    (tests/reference.py), measured there with NumPy: delta agrees to ~1e-6 rad, so the
    settling times agree to ~1e-4 s (a band of 3 s could not see a wrong metric)."""
    t, y = reference_runs[controller]
    m = metrics(jax_runs[controller])
    want_delta = last_exit(t, np.abs(y[:, 0] - reference.DELTA_E), 0.01, 0.5)
    want_omega = last_exit(t, np.abs(y[:, 1]), 0.01, 0.5)
    assert float(m.settling_delta) == pytest.approx(want_delta, abs=2e-3)
    assert float(m.settling_omega) == pytest.approx(want_omega, abs=2e-3)
    assert 4.4 < want_delta < 4.55  # README: 4.48 s (AFTSC), 4.47 s (ASC)


def test_metrics_of_stable_and_unstable_runs(jax_runs, paper_run):
    m = metrics(jax_runs["aftsc"])
    assert bool(m.stable)
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


def test_a_run_that_spent_its_step_budget_is_not_stable(jax_runs):
    """Even with delta inside its band at the end: the run did not reach t_end."""
    import equinox as eqx

    tr = jax_runs["aftsc"]
    assert bool(metrics(tr).stable)
    cut = eqx.tree_at(lambda x: x.budget_exhausted, tr, jnp.asarray(True))
    assert not bool(metrics(cut).stable)


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
