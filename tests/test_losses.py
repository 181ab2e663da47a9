"""Loss surrogates against the exact metrics they stand for."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax._losses import (
    LossWeights,
    aggregate,
    cvar,
    divergence,
    effort_rate,
    loss_terms,
    soft_overshoot,
    soft_settling_time,
)
from smibjax._metrics import metrics, settling_time


def test_soft_settling_time_of_exponential_decay():
    t = jnp.linspace(0.0, 8.0, 801)
    for tau, amp in ((0.5, 0.2), (1.2, 0.05), (0.3, 0.5)):
        sig = jnp.where(t >= 0.4, amp * jnp.exp(-(t - 0.4) / tau), 0.0)
        exact = tau * np.log(amp / 0.01)
        soft = soft_settling_time(t, 1.0 + sig, 1.0, 0.01, 0.4)
        assert float(settling_time(t, 1.0 + sig, 1.0, 0.01, 0.4)) == pytest.approx(
            exact, abs=1e-3
        )
        # smoothing bias ~ width / |d deviation / dt| at the exit: largest for slow decay
        assert float(soft) == pytest.approx(exact, abs=0.06)


@pytest.mark.xdist_group("reference_runs")  # conftest.py's session runs
def test_surrogates_track_exact_metrics_on_trajectories(jax_runs, paper_run):
    w = LossWeights()
    for tr in (jax_runs["aftsc"], jax_runs["asc"]):
        m, terms = metrics(tr), loss_terms(tr, w)
        assert float(terms["settling_delta"]) == pytest.approx(
            float(m.settling_delta), abs=0.05
        )
        assert float(terms["settling_Vt"]) == pytest.approx(
            float(m.settling_Vt), abs=0.05
        )
        assert float(terms["overshoot"]) == pytest.approx(float(m.overshoot), abs=0.01)
        rate = (float(m.effort_uf) + float(m.effort_ur)) / 10.0
        assert float(effort_rate(tr)) == pytest.approx(np.log1p(rate))
    # unstable: the settling surrogate saturates at the horizon, divergence is finite
    terms = loss_terms(paper_run, w)
    assert float(terms["settling_delta"]) == pytest.approx(10.0 - 0.5, abs=0.02)
    assert 0 < float(divergence(paper_run)) < 10
    # the held samples after the stop all sit at the maximum: the smooth max is biased
    # up by temperature * log(count) = 0.002 * log(800) = 0.013 rad
    assert float(soft_overshoot(paper_run)) == pytest.approx(
        float(metrics(paper_run).overshoot) + 0.002 * np.log(800), abs=0.002
    )


def test_cvar_and_aggregate_closed_forms():
    x = jnp.arange(10.0)  # 0..9
    assert float(cvar(x, 0.8)) == pytest.approx(8.5)  # mean of the worst 2
    assert float(cvar(x, 0.0)) == pytest.approx(4.5)
    assert float(aggregate(x, 0.5, 0.9)) == pytest.approx(4.5 + 0.5 * 9)
    g = jax.grad(lambda v: aggregate(v, 1.0, 0.8))(x)
    np.testing.assert_allclose(np.asarray(g), [0.1] * 8 + [0.6, 0.6])


def test_each_loss_term_is_named_once():
    """`TERMS` is the one list of term names: the weights are its names (plus the two
    bands), `loss_terms` returns exactly them, and the tuner's [loss] table takes them."""
    import dataclasses

    from smibjax._losses import TERM_NAMES, TERMS, LossWeights
    from tuning.config import load_config

    assert TERM_NAMES == tuple(TERMS)
    fields = {f.name for f in dataclasses.fields(LossWeights)}
    assert fields == set(TERMS) | {"delta_band", "Vt_band"}
    assert set(load_config()["loss"]) >= set(TERMS)
