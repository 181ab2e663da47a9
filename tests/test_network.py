"""The star-delta fault reduction against a direct nodal (Kron) reduction."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import smibjax as sj
from smibjax._network import fault_stage, stage_at


def nodal_reduction(XL, lam, Xf):
    """Nodes (m, F, inf); circuit 1 split at F, circuit 2 direct; F to ground via Xf.
    Kron-reduce F out of the bus admittance matrix; return (X2, Bf) of the reduced
    m--inf branch and m's shunt."""
    za, zb = 2 * lam * XL, 2 * (1 - lam) * XL
    y = np.zeros((3, 3))  # susceptance-like admittances 1/X (signs cancel consistently)

    def branch(i, j, x):
        y[i, i] += 1 / x
        y[j, j] += 1 / x
        y[i, j] -= 1 / x
        y[j, i] -= 1 / x

    branch(0, 2, 2 * XL)
    branch(0, 1, za)
    branch(1, 2, zb)
    y[1, 1] += 1 / Xf
    keep = [0, 2]
    yr = y[np.ix_(keep, keep)] - np.outer(y[keep, 1], y[1, keep]) / y[1, 1]
    x2 = -1 / yr[0, 1]
    shunt = yr[0, 0] + yr[0, 1]  # admittance of m to ground, as 1/X
    return x2, -shunt


@settings(max_examples=40, deadline=None)
@given(
    lam=st.floats(0.02, 0.98),
    Xf=st.floats(1e-4, 1.0),
    XL=st.floats(0.05, 0.5),
)
def test_fault_reduction_matches_nodal_solution(lam, Xf, XL):
    plant = sj.Plant(XL=XL)
    s = fault_stage(plant, lam, Xf)
    x2, bf = nodal_reduction(XL, lam, Xf)
    assert float(s.X2) == pytest.approx(x2, rel=1e-10)
    assert float(s.Bf) == pytest.approx(bf, rel=1e-10)


def test_bolted_fault_closed_form_and_continuity():
    plant = sj.Plant()
    s = fault_stage(plant, 0.3, 0.0)
    assert float(s.X2) == pytest.approx(0.4)  # 2 XL
    assert float(s.Bf) == pytest.approx(-1 / (0.3 * 0.4))
    near = fault_stage(plant, 0.3, 1e-9)
    assert float(near.Bf) == pytest.approx(float(s.Bf), rel=1e-6)


def test_stage_sequence_and_boundaries():
    plant, fault = sj.Plant(), sj.Fault(t_fault=0.5, t_clear=0.7, t_reclose=2.0)
    x2 = [float(stage_at(t, fault, plant).X2) for t in (0.0, 0.5, 0.69, 0.7, 1.99, 2.0)]
    bf = [float(stage_at(t, fault, plant).Bf) for t in (0.49, 0.5, 0.7, 2.0)]
    assert x2 == pytest.approx([0.2, 0.4, 0.4, 0.4, 0.4, 0.2])
    assert bf == pytest.approx([0.0, -1 / 0.2, 0.0, 0.0])
