"""SYNEX, the paper's synergetic excitation law as a decentralized grid exciter
(src/smibjax/grid/devices/synex.py): an exact equilibrium on Kundur's system, the
SMIB controller's law as the oracle on the network SMIB, and fault runs that end
stable or flagged unstable, never NaN."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from smibjax import OperatingPoint, ParameterError, Plant
from smibjax.controllers.synergetic.gains import Gains
from smibjax.controllers.synergetic.law import control_law
from smibjax.grid.case import build_case, case_files, load_case
from smibjax.grid.devices.synex import SYNEX, thevenin_reactance
from smibjax.grid.events import BranchClose, BranchTrip, BusFault
from smibjax.grid.loop import evaluate, state_labels
from smibjax.grid.network import stage_configs, stage_matrices
from smibjax.grid.operating import operating_point
from smibjax.grid.params import set_params
from smibjax.grid.psse import DyrRecord, read_dyr, read_raw, to_system
from smibjax.grid.scenarios import branch_positions, bus_positions
from smibjax.grid.simulate import simulate_jit

WB = 2 * math.pi * 60.0


def _smib_synex(beta=-1.0, alpha=5.0 / 7.0, c=1.0, emin=-100.0, emax=100.0):
    """The network SMIB (smib.raw: GENTRA behind XT and the double line, SVC at
    B = B0 = 0) with SYNEX on the machine, whose equivalent is the paper's plant:
    XE = XT + XL = 0.3, the machine's Xd, X'd, T'do, H, D."""
    raw, dyr = case_files("smib")
    system = to_system(read_raw(raw))
    records = read_dyr(dyr)
    gentra = next(r for r in records if r.model == "GENTRA").params
    params = {
        "XE": 0.3,
        "XD": gentra["Xd"],
        "XDP": gentra["Xd_p"],
        "TDOP": gentra["Tdo_p"],
        "H": gentra["H"],
        "D": gentra["D"],
        "BETA": beta,
        "T1": 0.005,
        "ALPHA": alpha,
        "C": c,
        "EMIN": emin,
        "EMAX": emax,
    }
    rec = DyrRecord(bus=1, model="SYNEX", ident="1", params=params, file="test", line=0)
    return build_case(system, [*records, rec], name="smib-synex")


def _derivative_at_rest(case):
    op, pf = operating_point(case)
    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    dy, meas, _ = evaluate(case, op, mats, 0, op.y0)
    return op, pf, mats, dy, meas


def test_kundur_synex_starts_at_an_exact_equilibrium_with_the_thevenin_reactance():
    """Every state derivative of kundur-synex (GENROU machines, SYNEX on all four)
    at t = 0 is below 1e-8, the field voltage is the power flow's, and the dyr's XE
    is the Thevenin reactance at each terminal (thevenin_reactance, 1e-6)."""
    case = load_case("kundur-synex")
    op, pf, mats, dy, meas = _derivative_at_rest(case)
    worst = int(np.argmax(np.abs(dy)))
    assert float(jnp.max(jnp.abs(dy))) < 1e-8, state_labels(case)[worst]
    syn = next(c for c in case.controllers if type(c).__name__ == "SYNEX")
    xe = thevenin_reactance(case, op)[np.asarray(syn.gen)]
    np.testing.assert_allclose(np.asarray(syn.XE), xe, rtol=0, atol=1e-6)
    # the law's own value at rest differs from Efd0 on GENROU (E' behind X'd is
    # not its flux state): the offset is what holds the equilibrium, and is not 0
    assert float(jnp.min(jnp.abs(op.refs[case.controllers.index(syn)][2]))) > 0.1


@pytest.mark.parametrize("c", [1.0, 2.5])
def test_synex_on_the_network_smib_is_the_smib_controllers_law(c):
    """On the network SMIB the local equivalent is the paper's plant exactly, so the
    device's field voltage equals `control_law`'s u_f at the same state (estimates
    at (-D, Pm), SVC at B = B0 = 0), away from rest; at rest the offset is 0."""
    case = _smib_synex(beta=-1.0, c=c, emin=-1e4, emax=1e4)  # no clip here
    op, pf, mats, dy, _ = _derivative_at_rest(case)
    assert float(jnp.max(jnp.abs(dy))) < 1e-8
    k = next(i for i, g in enumerate(case.controllers) if type(g).__name__ == "SYNEX")
    assert abs(float(op.refs[k][2][0])) < 1e-10  # u_f0 = Efd0: no offset
    plant = Plant()
    delta0 = float(op.refs[k][0][0])
    assert delta0 == pytest.approx(float(op.y0[0]), abs=1e-12)  # inf bus at angle 0
    gains = Gains.paper("aftsc", beta1=-1.0, beta2=-1.0, c1=c)
    opp = OperatingPoint(delta_e=delta0, Pm_ref=float(op.refs[k][1][0]))
    th = jnp.array([-plant.D, float(op.refs[k][1][0])])
    for d_delta, omega, d_e in [(0.1, 1e-3, 0.02), (-0.2, -2e-3, -0.05)]:
        y = op.y0.at[0].add(d_delta).at[1].set(omega).at[2].add(d_e)
        _, meas, _ = evaluate(case, op, mats, 0, y)
        z = jnp.array([y[0], WB * omega, y[2], 0.0])
        want = control_law(z, th, gains, plant, opp).u_f
        # to the power flow's tolerance (the SVC's B0 and the infinite bus's
        # reactive balance come from it): 1e-9 relative
        np.testing.assert_allclose(float(meas["Efd"][0]), float(want), rtol=1e-8)


def test_synex_fault_runs_end_stable_or_flagged_unstable_never_nan():
    """The paper's SMIB fault (circuit 1 out at 0.7 s, reclosed at 2 s, after a
    bolted fault at the SVC bus from 0.5 s) on the network SMIB: with BETA < 0 the
    run is stable and settles back to rest, with the paper's BETA = 50 (a saddle
    manifold) it is flagged unstable; every sample up to the verdict is finite, and
    the field voltage stays within [EMIN, EMAX]."""
    case = _smib_synex(beta=-1.0, emin=-3.0, emax=6.0)
    op, _ = operating_point(case)
    m = int(bus_positions(case.system, [2])[0])
    k = int(branch_positions(case.system, [(2, 3, "1")])[0])
    ev = (
        BusFault(bus=m, t_on=0.5, t_off=0.7),
        BranchTrip(branch=k, t=0.7),
        BranchClose(branch=k, t=2.0),
    )
    tr = simulate_jit(case, op, ev, t_end=30.0, dt_save=0.1)
    assert bool(tr.stable) and not bool(tr.exhausted)
    for a in (tr.delta, tr.omega, tr.efd):
        assert np.all(np.isfinite(np.asarray(a)))
    efd = np.asarray(tr.efd[:, 0])
    assert efd.max() <= 6.0 + 1e-12 and efd.min() >= -3.0 - 1e-12
    assert efd.max() == pytest.approx(6.0)  # the fault drives it onto the ceiling
    assert abs(float(tr.omega[-1, 0])) < 1e-4
    assert abs(float(tr.delta[-1, 0] - op.y0[0])) < 1e-2
    paper = set_params(case, {"SYNEX.BETA": 50.0})
    op50, _ = operating_point(paper)
    tr50 = simulate_jit(paper, op50, ev, t_end=30.0, dt_save=0.1)
    assert not bool(tr50.stable) and float(tr50.t_unstable) < 30.0
    before = np.asarray(tr50.ts) < float(tr50.t_unstable)
    assert np.all(np.isfinite(np.asarray(tr50.delta)[before]))


def _group(**over):
    p = {
        "XE": 0.3,
        "XD": 1.1,
        "XDP": 0.2,
        "TDOP": 4.0,
        "H": 5.0,
        "D": 0.0,
        "BETA": -1.0,
        "T1": 0.005,
        "ALPHA": 5.0 / 7.0,
        "C": 1.0,
        "EMIN": -math.inf,
        "EMAX": math.inf,
    }
    return SYNEX.from_params([0], [{**p, **over}])


def test_synex_is_finite_at_the_singular_angle_and_refuses_bad_gains():
    """At x1 = 0 (no power out, g31 = 0) the law divides by the floored g31: a
    finite field voltage even with no limits. BETA = 0, ALPHA outside (1/2, 1] and
    XD < XDP are refused with one line naming the value."""
    dev = _group()
    meas = {
        k: jnp.array([v])
        for k, v in {"omega": 0.0, "Pe": 0.0, "Qe": 0.0, "Vt": 1.0}.items()
    }
    ref = jnp.array([[0.5], [1.0], [0.0]])
    efd = dev.out(jnp.zeros((0, 1)), meas, ref)
    assert np.all(np.isfinite(np.asarray(efd))) and abs(float(efd[0])) > 1e3
    for over, name in [
        ({"BETA": 0.0}, "BETA"),
        ({"ALPHA": 0.5}, "ALPHA"),
        ({"XD": 0.1}, "XD"),
    ]:
        with pytest.raises(ParameterError, match=f"SYNEX.{name} = ") as e:
            _group(**over)
        assert "\n" not in str(e.value)
