"""The grid's network solution (smibjax.grid.network): the base network factored once
with each stage an exact low-rank update, against a dense reduction of every stage,
and the recording's per-stage bus voltages against a per-sample evaluation."""

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax.grid.case import load_case
from smibjax.grid.events import BranchClose, BranchTrip, BusFault, GenTrip, LineFault
from smibjax.grid.loop import evaluate
from smibjax.grid.network import stage_configs, stage_matrices, stage_matrices_dense
from smibjax.grid.operating import operating_point
from smibjax.grid.simulate import _record

pytestmark = pytest.mark.xdist_group("grid")


@pytest.fixture(scope="module")
def kundur():
    case = load_case("kundur-gencls")
    return case, operating_point(case)[0]


def _events(case):
    """Event sequences covering every kind of stage change, including a bus fault
    and a branch trip on one node, a line fault on a tripped-and-reclosed branch, a
    fault through an impedance and a generator trip."""
    fr0 = int(case.system.branches.fr[0])
    return [
        (BusFault(bus=3, t_on=1.0, t_off=1.1),),
        (
            BusFault(bus=2, t_on=1.0, t_off=1.1, r=0.001, x=0.01),
            BranchTrip(branch=1, t=1.1),
            BranchClose(branch=1, t=2.0),
        ),
        (
            LineFault(branch=2, frac=0.3, t_on=1.0, t_off=1.1),
            BranchTrip(branch=2, t=1.1),
        ),
        (
            LineFault(branch=0, frac=0.6, t_on=1.0, t_off=1.1, x=0.02),
            BusFault(bus=fr0, t_on=1.05, t_off=1.2),
            BranchTrip(branch=0, t=1.3),
            GenTrip(gen=1, t=1.4),
            BranchClose(branch=0, t=1.5),
        ),
    ]


def _max_error(op, ev):
    """The largest |low-rank - dense| over A, c, Z, c_all of every stage, relative
    to the largest entry (one compiled program per event structure)."""

    @jax.jit
    def both(grid, cfgs):
        m = stage_matrices(grid, cfgs, ev)
        dense = stage_matrices_dense(grid, cfgs)
        errs = [
            jnp.max(jnp.abs(a - b)) / jnp.maximum(jnp.max(jnp.abs(b)), 1.0)
            for a, b in zip((m.A, m.c, m.Z, m.c_all), dense, strict=True)
        ]
        return jnp.max(jnp.stack(errs))

    return float(both(op.grid, stage_configs(op.grid, ev)))


def test_low_rank_stages_equal_the_dense_reduction(kundur):
    """A, c (ports) and the bus response Z, c_all of every stage from one base
    factorization and Woodbury/Schur updates equal a dense solve of each stage's
    whole network to 1e-12, for every kind of event."""
    case, op = kundur
    for ev in _events(case)[1::2]:  # between them, every kind of event
        assert _max_error(op, ev) < 1e-12, ev


def test_low_rank_stages_with_an_infinite_bus():
    """The same on the SMIB, whose infinite bus is a held node (IEEE 39 agreed to
    2e-17 in a one-off check; left out of the suite for time)."""
    case = load_case("smib-gencls")
    op, _ = operating_point(case)
    assert _max_error(op, _events(case)[2]) < 1e-12


def test_low_rank_stages_vmap_over_fault_buses(kundur):
    """A batch of bus faults at traced positions gives each scenario's dense
    reduction (the base factorization shared)."""
    case, op = kundur
    buses = jnp.array([0, 4, 7, 9])

    def ev(b):
        return (BusFault(bus=b, t_on=1.0, t_off=1.1),)

    @jax.jit
    def both(buses):
        low = jax.vmap(
            lambda b: stage_matrices(op.grid, stage_configs(op.grid, ev(b)), ev(b)).A
        )(buses)
        dense = jax.vmap(
            lambda b: stage_matrices_dense(op.grid, stage_configs(op.grid, ev(b)))[0]
        )(buses)
        return low, dense

    low, dense = both(buses)
    assert float(jnp.max(jnp.abs(low - dense))) < 1e-14
    assert float(jnp.max(jnp.abs(low[0, 1] - low[1, 1]))) > 1e-3  # faults differ


def test_recorded_bus_voltages_equal_a_per_sample_evaluation(kundur):
    """The recording (one product per stage over all samples) gives every sample's
    measurements and |V_bus| of the stage in force, as a per-sample evaluation with
    the dense stage matrices does; unfinished samples stay NaN."""
    case, op = kundur
    ev = (
        BusFault(bus=6, t_on=0.1, t_off=0.2),
        BranchTrip(branch=3, t=0.2),
        GenTrip(gen=2, t=0.25),
    )
    t_sw = jnp.array([0.1, 0.2, 0.2, 0.25])
    ts = jnp.array([0.0, 0.05, 0.15, 0.2, 0.22, 0.27, 0.3])  # stages 0 0 1 3 3 4 4
    rng = np.random.default_rng(0)
    ys = op.y0[None, :] * (1 + 0.05 * rng.standard_normal((7, op.y0.shape[0])))
    ys = ys.at[-1].set(jnp.nan)

    class _Sol:  # what _record reads of diffrax's solution
        result = dfx.RESULTS.successful
        stats = {"num_accepted_steps": 0}

    @jax.jit
    def both(ys):
        cfgs = stage_configs(op.grid, ev)
        mats = stage_matrices(op.grid, cfgs, ev)
        A, c, Z, c_all = stage_matrices_dense(op.grid, cfgs)
        dense = eqx_replace(mats, A, c)
        tr = _record(  # the sampled fields of a GridTrajectory
            case, op, mats, t_sw, ts, ys, jnp.asarray(False), ts[-1], _Sol(), ys[0]
        )

        def one(t, y):  # the former recording: per-sample stage matrices
            s = jnp.sum(t >= t_sw)
            _, meas, i_net = evaluate(case, op, dense, s, y)
            return meas, jnp.abs(Z[s] @ i_net + c_all[s])

        meas, v = jax.vmap(one)(ts[:-1], ys[:-1])
        return tr, meas, v

    tr, meas, v = both(ys)
    assert float(jnp.max(jnp.abs(tr["v_bus"][:-1] - v))) < 1e-12
    assert float(jnp.max(jnp.abs(tr["delta"][:-1] - meas["delta"]))) < 1e-12
    assert float(jnp.max(jnp.abs(tr["pe"][:-1] - meas["Pe"]))) < 1e-12
    assert float(tr["v_bus"][2, 6]) < 1e-12 < 0.5 < float(tr["v_bus"][1, 6])  # bolted
    assert bool(jnp.all(jnp.isnan(tr["v_bus"][-1])))


def eqx_replace(mats, A, c):
    """`mats` with the dense reduction's A and c."""
    import equinox as eqx

    return eqx.tree_at(lambda m: (m.A, m.c), mats, (A, c))
