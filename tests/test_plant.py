"""Plant equations against the phasor solution of the network."""

import numpy as np
import pytest

import smibjax as sj
from smibjax.network import Stage, fault_stage, prefault_stage
from smibjax.plant import equilibrium_state

rng = np.random.default_rng(0)


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
