"""smibjax's multi-machine engine against ANDES 2.0 on Kundur's system with classical
machines (issue 28's accuracy target for GENCLS: 1e-3 rad over 10 s).

ANDES's trajectory is stored in tests/data/andes/kundur_gencls_bus8.npz (made by
tests/data/andes/make_kundur_gencls_bus8.py: trapezoid at a 1 ms fixed step, tol
1e-8), so this runs without ANDES. Both runs: `kundur.raw` + `kundur_gencls.dyr`, a
fault at bus 8 through j1e-4 pu from 1.0 to 1.1 s, constant-impedance loads.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from smibjax.grid.case import load_case
from smibjax.grid.cases import case_file
from smibjax.grid.events import BusFault
from smibjax.grid.loop import gen_names
from smibjax.grid.operating import operating_point
from smibjax.grid.simulate import coi_weights, simulate_jit

DATA = Path(__file__).parent / "data" / "andes" / "kundur_gencls_bus8.npz"


@pytest.fixture(scope="module")
def runs():
    ref = np.load(DATA)
    case = load_case(case_file("kundur.raw"), case_file("kundur_gencls.dyr"))
    op, _ = operating_point(case)
    ev = BusFault(
        bus=case.system.bus_index(int(ref["fault_bus"])),
        t_on=float(ref["t_fault"]),
        t_off=float(ref["t_clear"]),
        r=0.0,
        x=float(ref["xf"]),
    )
    tr = simulate_jit(case, op, (ev,), t_end=10.0, dt_save=0.01, rtol=1e-8, atol=1e-10)
    order = [list(ref["buses"]).index(int(n.split(":")[0])) for n in gen_names(case)]
    w = np.asarray(coi_weights(case, np.ones(case.n_gen)))
    return case, tr, ref["delta"][:, order], ref["t"], w


def _coi(d, w):
    return d - (d @ w / w.sum())[:, None]


def test_same_samples_and_stable(runs):
    _, tr, d_a, t_a, _ = runs
    np.testing.assert_allclose(np.asarray(tr.ts), t_a, atol=1e-12)
    assert bool(tr.stable) and not bool(tr.exhausted)
    assert d_a.shape == (1001, 4)


def test_initial_angles_match_andes(runs):
    """Same power flow and GENCLS initialization: E' angles at t = 0 (measured 6e-7
    rad apart: ANDES's and smibjax's power-flow solutions)."""
    _, tr, d_a, _, _ = runs
    np.testing.assert_allclose(np.asarray(tr.delta)[0], d_a[0], atol=2e-6)


def test_coi_angles_within_target(runs):
    """max |delta_COI smibjax - delta_COI ANDES| over 10 s below the issue's 1e-3 rad
    for every machine (measured 2.7e-5 rad; the rest is ANDES's 1 ms trapezoid)."""
    _, tr, d_a, _, w = runs
    err = np.abs(_coi(np.asarray(tr.delta), w) - _coi(d_a, w)).max(axis=0)
    assert err.max() < 1e-3, err
    assert err.max() < 1e-4, err  # the measured level, with margin
    # the swing is not trivial: > 0.1 rad of COI motion (measured 0.16 rad, G1)
    assert np.ptp(_coi(d_a, w), axis=0).max() > 0.1
