"""Plant equations against the phasor solution of the network."""

import numpy as np
import pytest

import smibjax as sj
from helpers import case_rng
from smibjax._network import Stage, fault_stage, prefault_stage
from smibjax._plant import equilibrium_state


def phasor(delta, E, B, X2, Bf, X1=0.3, V=1.0):
    """SVC-bus voltage and generator power from nodal analysis of E-jX1-m-jX2-V with a
    shunt admittance j(B + Bf) at m."""
    e = E * np.exp(1j * delta)
    vm = (e / (1j * X1) + V / (1j * X2)) / (
        1 / (1j * X1) + 1 / (1j * X2) + 1j * (B + Bf)
    )
    i = (e - vm) / (1j * X1)
    return abs(vm), (e * np.conj(i)).real


@pytest.mark.parametrize("k", range(12))
def test_power_and_voltage_match_phasor_solution(k):
    rng = case_rng("phasor", k)
    plant = sj.Plant()
    delta, E, B = rng.uniform(0.1, 3.0), rng.uniform(0.5, 1.5), rng.uniform(-1, 1)
    stage = [prefault_stage(plant), fault_stage(plant, 0.3, 0.02), Stage(0.4, 0.0)][
        k % 3
    ]
    vt, p = phasor(delta, E, B, float(stage.X2), float(stage.Bf))
    assert float(sj.terminal_voltage(delta, E, B, stage, plant)) == pytest.approx(vt)
    assert float(sj.electrical_power(delta, E, B, stage, plant)) == pytest.approx(p)


def test_operating_point_is_an_open_loop_equilibrium_with_its_field_voltage():
    plant, op = sj.Plant(), sj.OperatingPoint()
    z = equilibrium_state(op, plant)
    assert float(z[2]) == pytest.approx(0.5 / np.sin(0.4964))
    # u_f that holds dE/dt = 0 (Xds = Xd + XT + XL = 1.4): (Xds E - (Xd - Xd') V cos delta) / Xs
    u_fe = (1.4 * float(z[2]) - 0.9 * np.cos(0.4964)) / 0.5
    dz = sj.plant_vector_field(z, u_fe, 0.0, prefault_stage(plant), plant)
    np.testing.assert_allclose(np.asarray(dz), 0.0, atol=1e-12)


def test_input_limits_hard_and_soft():
    import jax

    from smibjax._plant import apply_limits

    real, paper = sj.Plant.preset("realistic"), sj.Plant()
    uf, ur = apply_limits(7.0, -3.0, real)
    assert (float(uf), float(ur)) == (5.0, -1.0)
    assert float(apply_limits(1e6, -1e6, paper)[0]) == 1e6  # no limits
    # soft: within w exp(-distance / w) of the hard clip, true slope inside the
    # limits, the soft clip's own slope beyond them (w e^(-d/w) d/du: 1/(1 + e^(d/w))
    # at a distance d), exact identity without limits
    w = 0.05
    for u, hard in ((0.3, 0.3), (4.5, 4.5), (9.0, 5.0), (-9.0, -5.0)):
        soft = float(apply_limits(u, 0.0, real, w)[0])
        assert soft == pytest.approx(
            hard, abs=w * np.exp(-min(abs(u - 5), abs(u + 5)) / w) + 1e-12
        )
    slope = jax.grad(lambda v: apply_limits(v, 0.0, real, w)[0])
    assert float(slope(0.0)) == pytest.approx(1.0)
    assert float(slope(9.0)) == pytest.approx(1 / (1 + np.exp(4.0 / w)), rel=1e-6)
    assert float(jax.grad(lambda v: apply_limits(v, 0.0, paper, w)[0])(3.0)) == 1.0
