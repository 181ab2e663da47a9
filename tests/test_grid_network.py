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


@pytest.mark.parametrize("name", ["kundur-gencls", "ieee39-gencls", "smib-gencls"])
def test_low_rank_stages_equal_the_dense_reduction(name):
    """A, c (ports) and the bus response Z, c_all of every stage from one base
    factorization and Woodbury/Schur updates equal a dense solve of each stage's
    whole network to 1e-12 (relative to the largest entry)."""
    case = load_case(name)
    op, _ = operating_point(case)
    for ev in _events(case):
        cfgs = stage_configs(op.grid, ev)
        m = stage_matrices(op.grid, cfgs, ev)
        A, c, Z, c_all = stage_matrices_dense(op.grid, cfgs)
        assert m.A.shape == A.shape and m.Z.shape == Z.shape
        for got, want in ((m.A, A), (m.c, c), (m.Z, Z), (m.c_all, c_all)):
            scale = max(float(jnp.max(jnp.abs(want))), 1.0)
            assert float(jnp.max(jnp.abs(got - want))) < 1e-12 * scale, ev


def test_low_rank_stages_vmap_over_fault_buses():
    """A batch of bus faults at traced positions gives each scenario's dense
    reduction (the base factorization shared)."""
    case = load_case("kundur-gencls")
    op, _ = operating_point(case)
    buses = jnp.array([0, 4, 7, 9])

    def one(b):
        ev = (BusFault(bus=b, t_on=1.0, t_off=1.1),)
        return stage_matrices(op.grid, stage_configs(op.grid, ev), ev).A

    A = jax.jit(jax.vmap(one))(buses)
    for k, b in enumerate(np.asarray(buses)):
        ev = (BusFault(bus=int(b), t_on=1.0, t_off=1.1),)
        want = stage_matrices_dense(op.grid, stage_configs(op.grid, ev))[0]
        assert float(jnp.max(jnp.abs(A[k] - want))) < 1e-14


def test_recorded_bus_voltages_equal_a_per_sample_evaluation():
    """The recording (one product per stage over all samples) gives every sample's
    measurements and |V_bus| of the stage in force, as a per-sample evaluation with
    the dense stage matrices does; unfinished samples stay NaN."""
    case = load_case("kundur-gencls")
    op, _ = operating_point(case)
    ev = (
        BusFault(bus=6, t_on=0.1, t_off=0.2),
        BranchTrip(branch=3, t=0.2),
        GenTrip(gen=2, t=0.25),
    )
    cfgs = stage_configs(op.grid, ev)
    mats = stage_matrices(op.grid, cfgs, ev)
    A, c, Z, c_all = stage_matrices_dense(op.grid, cfgs)
    t_sw = jnp.array([0.1, 0.2, 0.2, 0.25])
    ts = jnp.linspace(0.0, 0.3, 7)
    rng = np.random.default_rng(0)
    ys = op.y0[None, :] * (1 + 0.05 * rng.standard_normal((7, op.y0.shape[0])))
    ys = ys.at[-1].set(jnp.nan)

    class _Sol:  # what _record reads of diffrax's solution
        result = dfx.RESULTS.successful
        stats = {"num_accepted_steps": 0}

    tr = _record(
        case, op, mats, t_sw, ts, ys, jnp.asarray(False), ts[-1], _Sol(), ys[0]
    )
    dense = mats.__class__(
        A=A,
        c=c,
        gen_status=mats.gen_status,
        Zb=mats.Zb,
        mask=mats.mask,
        cb=mats.cb,
        U=mats.U,
        Q=mats.Q,
    )
    for k in range(6):
        s = int(jnp.sum(ts[k] >= t_sw))
        _, meas, i_net = evaluate(case, op, dense, s, ys[k])
        v = jnp.abs(Z[s] @ i_net + c_all[s])
        assert float(jnp.max(jnp.abs(tr.v_bus[k] - v))) < 1e-12, k
        assert float(jnp.max(jnp.abs(tr.delta[k] - meas["delta"]))) < 1e-12
        assert float(jnp.max(jnp.abs(tr.pe[k] - meas["Pe"]))) < 1e-12
    assert bool(jnp.all(jnp.isnan(tr.v_bus[-1])))
