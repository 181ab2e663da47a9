"""The admittance matrix and the AC power flow (smibjax.grid.ybus, .powerflow).

References, all written here: Ybus by hand for a 3-bus network and the open-circuit
voltage of a transformer (the tap side and the shift sign); an independent power flow
in rectangular coordinates (SciPy's `root` on the current-injection mismatch, with
the PV buses' Q as unknowns) on a meshed 5-bus system and on the WSCC 9-bus system;
the 9-bus system's published solution (Anderson & Fouad, Power System Control and
Stability, 2nd ed., Fig. 2.19; Sauer & Pai, Example 7.1); central finite differences
for the implicit derivatives.
"""

import cmath

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import root

from smibjax.grid.powerflow import (
    PowerFlowError,
    power_flow,
    scale_operating_point,
    solve_power_flow,
)
from smibjax.grid.system import (
    PQ,
    PV,
    SLACK,
    Branches,
    Buses,
    Generators,
    Loads,
    Shunts,
    System,
)
from smibjax.grid.ybus import load_admittance, ybus

DEG = np.pi / 180


def _system(numbers, kinds, branches, loads, gens, shunts=(), vm=None, va=None):
    """A System from lists. branches: (fr, to, r, x, b, tap, shift, status) with bus
    numbers; loads: (bus, p, q); gens: (bus, p, q, v_set, qmin, qmax, mbase, status);
    shunts: (bus, g, b)."""
    numbers = list(numbers)
    pos = {b: i for i, b in enumerate(numbers)}
    n = len(numbers)
    br = np.array(branches, dtype=float).reshape(-1, 8)
    ld = np.array(loads, dtype=float).reshape(-1, 3)
    g = np.array(gens, dtype=float).reshape(-1, 8)
    sh = np.array(shunts, dtype=float).reshape(-1, 3)
    ix = lambda col: [pos[int(b)] for b in col]  # noqa: E731
    return System(
        buses=Buses(
            number=numbers,
            kind=kinds,
            vm=np.ones(n) if vm is None else vm,
            va=np.zeros(n) if va is None else va,
            base_kv=np.full(n, 230.0),
            area=np.ones(n),
        ),
        branches=Branches(
            fr=ix(br[:, 0]),
            to=ix(br[:, 1]),
            r=br[:, 2],
            x=br[:, 3],
            b=br[:, 4],
            tap=br[:, 5],
            shift=br[:, 6],
            status=br[:, 7],
            is_transformer=(br[:, 5] != 1) | (br[:, 6] != 0),
        ),
        shunts=Shunts(bus=ix(sh[:, 0]), g=sh[:, 1], b=sh[:, 2]),
        loads=Loads(bus=ix(ld[:, 0]), p=ld[:, 1], q=ld[:, 2]),
        generators=Generators(
            bus=ix(g[:, 0]),
            p=g[:, 1],
            q=g[:, 2],
            v_set=g[:, 3],
            qmin=g[:, 4],
            qmax=g[:, 5],
            mbase=g[:, 6],
            status=g[:, 7],
        ),
    )


def wscc9() -> System:
    """WSCC 9-bus, Anderson & Fouad Fig. 2.18 (100 MVA base; charging B = 2 Y/2)."""
    lines = [
        (1, 4, 0.0, 0.0576, 0.0),
        (2, 7, 0.0, 0.0625, 0.0),
        (3, 9, 0.0, 0.0586, 0.0),
        (4, 5, 0.010, 0.085, 0.176),
        (4, 6, 0.017, 0.092, 0.158),
        (5, 7, 0.032, 0.161, 0.306),
        (6, 9, 0.039, 0.170, 0.358),
        (7, 8, 0.0085, 0.072, 0.149),
        (8, 9, 0.0119, 0.1008, 0.209),
    ]
    return _system(
        range(1, 10),
        [SLACK, PV, PV, PQ, PQ, PQ, PQ, PQ, PQ],
        [(*ln, 1.0, 0.0, 1.0) for ln in lines],
        [(5, 1.25, 0.50), (6, 0.90, 0.30), (8, 1.00, 0.35)],
        [
            (1, 0.0, 0.0, 1.040, -9.99, 9.99, 247.5, 1),
            (2, 1.63, 0.0, 1.025, -9.99, 9.99, 192.0, 1),
            (3, 0.85, 0.0, 1.025, -9.99, 9.99, 128.0, 1),
        ],
    )


def meshed5() -> System:
    """A meshed 5-bus system with non-consecutive bus numbers: a tap-changing
    transformer 20-40 (tap on 20), a phase shifter 50-40 (from 50) in a loop with the
    line 30-50, charging, a shunt, two generators sharing PV bus 20, a generator at PQ
    bus 50, an out-of-service generator and an out-of-service line."""
    return _system(
        [10, 20, 30, 40, 50],
        [SLACK, PV, PQ, PQ, PQ],
        [
            (10, 20, 0.02, 0.06, 0.06, 1.0, 0.0, 1),
            (10, 30, 0.08, 0.24, 0.05, 1.0, 0.0, 1),
            (20, 30, 0.06, 0.18, 0.04, 1.0, 0.0, 1),
            (20, 40, 0.005, 0.12, 0.0, 0.97, 0.0, 1),
            (30, 40, 0.01, 0.03, 0.02, 1.0, 0.0, 1),
            (50, 40, 0.0, 0.10, 0.0, 1.02, 6 * DEG, 1),
            (30, 50, 0.08, 0.24, 0.05, 1.0, 0.0, 1),
            (10, 50, 0.05, 0.20, 0.04, 1.0, 0.0, 0),  # out of service
        ],
        [(30, 0.45, 0.15), (40, 0.25, 0.05), (40, 0.15, 0.05), (50, 0.60, 0.10)],
        [
            (10, 0.0, 0.0, 1.06, -2.0, 2.0, 200, 1),
            (20, 0.25, 0.0, 1.045, -0.5, 1.0, 100, 1),
            (20, 0.15, 0.0, 1.045, -0.2, 0.4, 50, 1),
            (50, 0.10, 0.03, 1.00, -1.0, 1.0, 50, 1),
            (30, 5.00, 0.0, 1.10, -1.0, 1.0, 500, 0),  # out of service
        ],
        shunts=[(50, 0.01, 0.15)],
        va=np.array([5 * DEG, 0, 0, 0, 0]),  # the slack angle is not zero
    )


# ---- independent references (numpy loops, SciPy, rectangular coordinates) ----


def _ybus_np(system, status=None):
    """Y from the circuit: an ideal transformer a:1 (a = tap e^{j shift}) at the from
    end, V_i = V_fr / a and I_fr = I_i / conj(a) (lossless), then the pi section."""
    br = system.branches
    n = system.n_bus
    Y = np.zeros((n, n), complex)
    status = br.status if status is None else status
    for k in range(len(br.fr)):
        i, j = int(br.fr[k]), int(br.to[k])
        ys = status[k] / complex(br.r[k], br.x[k])
        yc = 0.5j * status[k] * br.b[k]
        a = br.tap[k] * cmath.exp(1j * br.shift[k])
        # I_i = (ys + yc) V_i - ys V_j ; I_j = -ys V_i + (ys + yc) V_j
        Y[i, i] += (ys + yc) / (a * a.conjugate())
        Y[i, j] += -ys / a.conjugate()
        Y[j, i] += -ys / a
        Y[j, j] += ys + yc
    for bus, g, b in zip(
        system.shunts.bus, system.shunts.g, system.shunts.b, strict=True
    ):
        Y[bus, bus] += complex(g, b)
    return Y


def _bus_data(system):
    """Bus roles and schedules, from the System, written out with loops."""
    n = system.n_bus
    g, ld = system.generators, system.loads
    kind = np.asarray(system.buses.kind)
    gens_at = [
        [k for k in range(len(g.bus)) if g.bus[k] == i and g.status[k]]
        for i in range(n)
    ]
    slack = kind == SLACK
    pv = np.array([kind[i] == PV and len(gens_at[i]) > 0 for i in range(n)])
    v_set = np.array(
        [
            np.mean([g.v_set[k] for k in gens_at[i]])
            if gens_at[i]
            else system.buses.vm[i]
            for i in range(n)
        ]
    )
    s_load = np.zeros(n, complex)
    for bus, p, q in zip(ld.bus, ld.p, ld.q, strict=True):
        s_load[bus] += complex(p, q)
    s_gen = np.zeros(n, complex)
    for k in range(len(g.bus)):
        if g.status[k]:
            s_gen[g.bus[k]] += complex(g.p[k], g.q[k])
    return slack, pv, v_set, s_gen - s_load, s_load, gens_at


def _solve_rect(system):
    """V (complex) by SciPy root on the current mismatch conj(S / V) - Y V at the
    non-slack buses, unknowns e + j f there and Q at the PV buses, with
    |V|^2 = v_set^2 at the PV buses."""
    Y = _ybus_np(system)
    slack, pv, v_set, s_sched, _, _ = _bus_data(system)
    ns = np.flatnonzero(~slack)
    pvs = np.flatnonzero(pv)
    m = len(ns)
    v_slack = v_set * np.exp(1j * np.asarray(system.buses.va))

    def unpack(x):
        v = np.where(slack, v_slack, 0j)
        v[ns] = x[:m] + 1j * x[m : 2 * m]
        s = s_sched.copy()
        s[pvs] = s.real[pvs] + 1j * x[2 * m :]
        return v, s

    def F(x):
        v, s = unpack(x)
        di = (np.conj(s / v) - Y @ v)[ns]
        return np.concatenate([di.real, di.imag, np.abs(v[pvs]) ** 2 - v_set[pvs] ** 2])

    x0 = np.concatenate([np.ones(m), np.zeros(m), np.zeros(len(pvs))])
    sol = root(F, x0, method="hybr", tol=1e-12)
    assert np.max(np.abs(F(sol.x))) < 1e-12
    return unpack(sol.x)[0]


def _mismatch_np(system, vm, va):
    """(dP, dQ) computed minus scheduled (pu) where they are specified, else 0."""
    slack, pv, _, s_sched, _, _ = _bus_data(system)
    v = np.asarray(vm) * np.exp(1j * np.asarray(va))
    s = v * np.conj(_ybus_np(system) @ v)
    dp = np.where(slack, 0.0, s.real - s_sched.real)
    dq = np.where(slack | pv, 0.0, s.imag - s_sched.imag)
    return dp, dq


# ---- (a) Ybus ----


def _three_bus():
    # 1-2 line with charging; 2-3 transformer, tap 1.05 on bus 2; 3-1 phase shifter
    # from bus 3 (tap 0.98, shift 10 deg); shunt at 3; load at 2 (not in Y)
    return _system(
        [1, 2, 3],
        [SLACK, PQ, PQ],
        [
            (1, 2, 0.01, 0.10, 0.20, 1.0, 0.0, 1),
            (2, 3, 0.00, 0.08, 0.00, 1.05, 0.0, 1),
            (3, 1, 0.02, 0.15, 0.00, 0.98, 10 * DEG, 1),
        ],
        [(2, 0.5, 0.2), (2, 0.1, -0.05)],
        [(1, 0.0, 0.0, 1.0, -1, 1, 100, 1)],
        shunts=[(3, 0.02, -0.10)],
    )


def test_ybus_equals_the_closed_form_with_a_tap_a_phase_shift_and_charging():
    y12, y23, y31 = 1 / (0.01 + 0.10j), 1 / 0.08j, 1 / (0.02 + 0.15j)
    t, a = 1.05, 0.98 * cmath.exp(10j * DEG)
    # fmt: off
    expected = np.array([
        [y12 + 0.1j + y31,      -y12,                   -y31 / a],
        [-y12,                  y12 + 0.1j + y23 / t**2, -y23 / t],
        [-y31 / a.conjugate(),  -y23 / t,               y23 + y31 / abs(a) ** 2 + 0.02 - 0.10j],
    ])
    # fmt: on
    np.testing.assert_allclose(
        np.asarray(jax.jit(ybus)(_three_bus())), expected, rtol=1e-14
    )


def test_a_transformer_divides_the_from_voltage_by_tap_e_j_shift():
    # at no load the to-end voltage is V_fr / (tap e^{j shift}): it lags by the shift
    system = _system([1, 2], [SLACK, PQ], [(1, 2, 0.0, 0.1, 0.0, 1.1, 0.2, 1)], [], [])
    Y = np.asarray(jax.jit(ybus)(system))
    v_to = -Y[1, 0] / Y[1, 1]  # I_to = 0
    assert v_to == pytest.approx(1 / (1.1 * cmath.exp(0.2j)), rel=1e-14)


def test_ybus_vmaps_over_branch_status_and_extra_shunts():
    system = meshed5()
    status = np.array([np.ones(8), [1, 0, 1, 1, 0, 1, 1, 1], np.full(8, 0.5)])
    shunt = np.array([np.zeros(5), [0, 0, 0.3j, 0, 0], [1 - 2j, 0, 0, 0, 0]])
    Ys = jax.jit(jax.vmap(lambda s, y: ybus(system, s, y)))(status, shunt)
    for Y, st, y in zip(Ys, status, shunt, strict=True):
        np.testing.assert_allclose(
            np.asarray(Y), _ybus_np(system, st) + np.diag(y), rtol=1e-13, atol=1e-14
        )


def test_load_admittance_draws_the_load_power_at_the_voltage():
    system = _three_bus()
    vm = np.array([1.0, 0.95, 1.02])
    y = np.asarray(jax.jit(load_admittance)(system, vm))
    s = vm**2 * np.conj(y)  # the power drawn by y at vm
    np.testing.assert_allclose(s, [0, 0.6 + 0.15j, 0], atol=1e-15)


# ---- (b), (c) the power flow against the independent solver ----


# one worker runs the module: its tests share the module fixture `solved` and the
# power flow's programs (under -n 2 the other worker built them again)
pytestmark = pytest.mark.xdist_group("powerflow")


@pytest.fixture(scope="module")
def solved():
    return {name: solve_power_flow(f()) for name, f in (("5", meshed5), ("9", wscc9))}


@pytest.mark.parametrize("name, make", [("5", meshed5), ("9", wscc9)])
def test_power_flow_equals_an_independent_rectangular_solver(solved, name, make):
    system, res = make(), solved[name]
    v = _solve_rect(system)
    assert bool(res.converged) and 2 <= int(res.iterations) <= 8
    np.testing.assert_allclose(np.asarray(res.vm), np.abs(v), atol=1e-9)
    np.testing.assert_allclose(np.asarray(res.va), np.angle(v), atol=1e-9)
    # the generation each bus needs: P at the slack, Q at PV and slack buses
    slack, pv, _, _, s_load, gens_at = _bus_data(system)
    s_bus = v * np.conj(_ybus_np(system) @ v) + s_load
    assert float(res.p_slack) == pytest.approx(s_bus[slack].real.sum(), abs=1e-9)
    for i in np.flatnonzero(slack | pv):
        ks = gens_at[i]
        assert float(np.sum(res.q_gen[np.array(ks)])) == pytest.approx(
            s_bus[i].imag, abs=1e-9
        )


@pytest.mark.parametrize("name, make", [("5", meshed5), ("9", wscc9)])
def test_the_solution_satisfies_the_power_flow_equations(solved, name, make):
    system, res = make(), solved[name]
    dp, dq = _mismatch_np(system, res.vm, res.va)
    assert max(np.max(np.abs(dp)), np.max(np.abs(dq))) < 1e-10
    assert abs(float(res.mismatch)) < 1e-10
    np.testing.assert_allclose(np.asarray(res.dp), dp, atol=1e-13)
    np.testing.assert_allclose(np.asarray(res.dq), dq, atol=1e-13)


def test_wscc9_matches_the_published_solution(solved):
    res = solved["9"]
    # Anderson & Fouad Fig. 2.19: |V| (pu), angle (deg), generation (MW, Mvar)
    vm = [1.040, 1.025, 1.025, 1.026, 0.996, 1.013, 1.026, 1.016, 1.032]
    va = [0.0, 9.3, 4.7, -2.2, -4.0, -3.7, 3.7, 0.7, 2.0]
    np.testing.assert_allclose(np.asarray(res.vm), vm, atol=1e-3)
    np.testing.assert_allclose(np.asarray(res.va), np.array(va) * DEG, atol=1e-3)
    np.testing.assert_allclose(np.asarray(res.p_gen), [0.716, 1.63, 0.85], atol=1e-3)
    np.testing.assert_allclose(np.asarray(res.q_gen), [0.270, 0.067, -0.109], atol=1e-3)
    # Sauer & Pai's four-digit angles (deg)
    np.testing.assert_allclose(
        np.asarray(res.va[1:]) / DEG,
        [9.280, 4.665, -2.217, -3.989, -3.687, 3.720, 0.7275, 1.967],
        atol=1e-3,
    )


def test_generators_share_their_bus(solved):
    """Bus 20's two generators (case q = 0) share its Q in proportion to their Q
    ranges (1.5 and 0.6 pu); the slack generator takes the slack; the PQ bus's
    generator its schedule; the one out of service nothing."""
    res = solved["5"]
    q = np.asarray(res.q_gen)
    assert q[1] / 1.5 == pytest.approx(q[2] / 0.6, abs=1e-12) and q[1] != 0
    np.testing.assert_allclose(
        np.asarray(res.p_gen), [float(res.p_slack), 0.25, 0.15, 0.10, 0.0]
    )
    assert q[3] == 0.03 and q[4] == 0.0


def test_generators_on_one_bus_keep_the_case_q(solved):
    """With the case's own q at bus 20 (a solved case's machine outputs), each machine
    keeps it plus a range-proportional share of the difference to the bus's Q: on
    case q that already sum to the bus's Q, exactly the case's values. The network
    solution does not depend on the split."""
    res = solved["5"]
    q_bus = float(res.q_gen[1] + res.q_gen[2])
    system = meshed5()
    split = np.array([0.8, 0.2]) * q_bus  # not the range proportion (5:2)
    for q_case, want in (
        (split, split),  # a solved case: kept
        (split - 0.07, split - 0.07 + 0.14 * np.array([1.5, 0.6]) / 2.1),
    ):
        q = np.array(system.generators.q, dtype=float)
        q[1:3] = q_case
        s2 = solve_power_flow(eqx.tree_at(lambda s: s.generators.q, system, q))
        np.testing.assert_allclose(np.asarray(s2.q_gen)[1:3], want, rtol=0, atol=1e-12)
        np.testing.assert_allclose(s2.vm, res.vm, atol=1e-12)


def test_a_flat_start_ignores_the_raw_file_voltages(solved):
    """From raw-file voltages of 0.2 pu Newton fails; from a flat start it finds the
    solution."""
    system = meshed5()
    system = eqx.tree_at(lambda s: s.buses.vm, system, np.full(5, 0.2))
    assert not bool(power_flow(system, start="case").converged)
    res = solve_power_flow(system, start="flat")
    np.testing.assert_allclose(res.vm, solved["5"].vm, atol=1e-12)
    np.testing.assert_allclose(res.va, solved["5"].va, atol=1e-12)
    # the host solve from the case's voltages falls back to the flat start
    res = solve_power_flow(system)
    np.testing.assert_allclose(res.vm, solved["5"].vm, atol=1e-12)


def test_a_low_voltage_solution_from_the_case_is_replaced_by_the_flat_one():
    """A load of 0.6 + j0.2 pu behind j0.5 from a 1 pu slack has two power-flow
    solutions, |V2| = 0.8031 and 0.3938 pu (roots of |V|^4 - (1 - 2 Q X)|V|^2 +
    (P^2 + Q^2) X^2 = 0). Newton from the raw file's 0.2 pu lands on the low one;
    the host solve keeps the flat start's high one."""
    system = _system(
        [1, 2],
        [SLACK, PQ],
        [(1, 2, 0.0, 0.5, 0.0, 1.0, 0.0, 1)],
        [(2, 0.6, 0.2)],
        [(1, 0.0, 0.0, 1.0, -9, 9, 100, 1)],
        vm=np.array([1.0, 0.2]),
        va=np.array([0.0, -0.5]),
    )
    a, b = 1 - 2 * 0.2 * 0.5, (0.6**2 + 0.2**2) * 0.5**2
    hi, lo = (
        np.sqrt((a + np.sqrt(a * a - 4 * b)) / 2),
        np.sqrt((a - np.sqrt(a * a - 4 * b)) / 2),
    )
    low = power_flow(system, start="case")
    assert bool(low.converged) and float(low.vm[1]) == pytest.approx(lo, abs=1e-10)
    assert float(solve_power_flow(system).vm[1]) == pytest.approx(hi, abs=1e-10)


# ---- (d) implicit derivatives ----


def test_gradients_with_respect_to_the_loads_equal_finite_differences(solved):
    system = meshed5()

    def solution(p, f=power_flow):
        s = f(eqx.tree_at(lambda s: s.loads.p, system, p))
        return (
            np.concatenate([s.vm, s.va])
            if f is solve_power_flow
            else jnp.concatenate([s.vm, s.va])
        )

    p0 = jnp.asarray(system.loads.p)
    J = np.asarray(jax.jacfwd(solution)(p0))
    h = 1e-5  # the host solve, already compiled (the fixture's program)
    fd = [
        solution(p0.at[k].add(d), solve_power_flow)
        for k in range(len(p0))
        for d in (h, -h)
    ]
    J_fd = np.stack(
        [(fd[2 * k] - fd[2 * k + 1]) / (2 * h) for k in range(len(p0))], axis=1
    )
    assert np.max(np.abs(J)) > 0.05  # a real dependence, not zeros
    np.testing.assert_allclose(J, J_fd, rtol=1e-5, atol=1e-10)


def test_reverse_mode_gradients_in_network_and_generation_parameters(solved):
    """jax.grad of a scalar of the solution with respect to the phase shift, a
    transformer's reactance and a generator's schedule, against central differences."""
    system = meshed5()
    w = np.array([0.3, -1.0, 0.5, 2.0, 1.0])

    def with_params(theta):
        br, g = system.branches, system.generators
        return eqx.tree_at(
            lambda s: (s.branches.shift, s.branches.x, s.generators.p),
            system,
            (
                jnp.asarray(br.shift).at[5].set(theta[0]),
                jnp.asarray(br.x).at[3].set(theta[1]),
                jnp.asarray(g.p).at[1].set(theta[2]),
            ),
        )

    def objective(theta, f=power_flow):
        s = f(with_params(theta))
        return jnp.sum(w * s.va) + s.vm[3] + s.q_gen[1]

    theta0 = jnp.array([6 * DEG, 0.12, 0.25])
    grad = np.asarray(jax.grad(objective)(theta0))
    h = 1e-5
    fd = [
        (
            float(objective(theta0.at[k].add(h), solve_power_flow))
            - float(objective(theta0.at[k].add(-h), solve_power_flow))
        )
        / (2 * h)
        for k in range(3)
    ]
    assert np.min(np.abs(grad)) > 0.01
    np.testing.assert_allclose(grad, fd, rtol=1e-5)


# ---- (e), (g) vmap over operating points, one compile ----


def test_vmap_over_load_factors_equals_the_loop_with_one_compile():
    system = wscc9()
    traces = []

    def solve(f):
        traces.append(1)
        return power_flow(scale_operating_point(system, f, f))

    batched = jax.jit(jax.vmap(solve))
    factors = jnp.array([0.8, 1.0, 1.2, 1.5])
    res = batched(factors)
    again = batched(jnp.array([0.9, 1.1, 1.3, 0.7]))
    assert len(traces) == 1 and batched._cache_size() == 1
    assert bool(jnp.all(res.converged)) and bool(jnp.all(again.converged))
    for k, f in enumerate([0.8, 1.0, 1.2, 1.5]):
        one = solve_power_flow(scale_operating_point(system, f, f))
        np.testing.assert_allclose(
            np.asarray(res.vm[k]), np.asarray(one.vm), atol=1e-12
        )
        np.testing.assert_allclose(
            np.asarray(res.va[k]), np.asarray(one.va), atol=1e-12
        )
        np.testing.assert_allclose(
            np.asarray(res.q_gen[k]), np.asarray(one.q_gen), atol=1e-12
        )
        assert int(res.iterations[k]) == int(one.iterations)
        # the loads and the non-slack generation scale; the slack balances
        np.testing.assert_allclose(
            np.asarray(one.p_gen[1:]), f * np.array([1.63, 0.85])
        )
    assert float(res.vm[3, 4]) < float(res.vm[0, 4])  # heavier load, lower voltage
    scaled = scale_operating_point(system, 1.2, 0.9)
    np.testing.assert_allclose(scaled.loads.p, 1.2 * system.loads.p, rtol=1e-15)
    np.testing.assert_allclose(scaled.loads.q, 1.2 * system.loads.q, rtol=1e-15)
    np.testing.assert_allclose(scaled.generators.p, [0, 0.9 * 1.63, 0.9 * 0.85])


def test_vmap_over_branch_outages_equals_the_loop(solved):
    system = meshed5()
    status = np.array(
        [[1, 1, 1, 1, 1, 1, 1, 0], [1, 0, 1, 1, 1, 1, 1, 1], [1, 1, 1, 1, 1, 1, 0, 1]],
        float,
    )
    res = jax.vmap(lambda st: power_flow(system, branch_status=st))(status)
    for k, st in enumerate(status):
        one = solve_power_flow(eqx.tree_at(lambda s: s.branches.status, system, st))
        np.testing.assert_allclose(res.vm[k], one.vm, atol=1e-12)
        np.testing.assert_allclose(res.va[k], one.va, atol=1e-12)
    np.testing.assert_allclose(res.vm[0], solved["5"].vm, atol=1e-12)  # the base case
    assert np.max(np.abs(res.va[2] - res.va[0])) > 0.01  # the outage moves the angles


# ---- (f) non-convergence ----


@pytest.mark.parametrize("method", ["sparse", "dense"])
def test_beyond_the_nose_the_error_names_the_worst_bus(method):
    from smibjax.grid.powerflow_sparse import power_flow_sparse

    system = scale_operating_point(wscc9(), 50.0, 1.0)
    core = (power_flow_sparse if method == "sparse" else power_flow)(system)
    assert not bool(core.converged)
    dp, dq = _mismatch_np(system, core.vm, core.va)
    worst = int(np.argmax(np.abs(np.concatenate([dp, dq]))))
    bus = int(system.buses.number[worst % 9])
    m = np.concatenate([dp, dq])[worst]
    what, unit = ("Q", "Mvar") if worst >= 9 else ("P", "MW")
    with pytest.raises(PowerFlowError) as err:
        solve_power_flow(system, method=method)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg == (
        f"power flow did not converge in {int(core.iterations)} iterations: "
        f"largest mismatch {what} = "
        f"{m:.4g} pu ({100 * m:.4g} {unit}) at bus {bus}"
    )


def test_bad_input_is_one_line():
    system = wscc9()
    no_slack = eqx.tree_at(lambda s: s.buses.kind, system, np.full(9, PQ))
    with pytest.raises(
        ValueError, match=r"^power flow: the system has no slack bus \(type 3\)$"
    ):
        solve_power_flow(no_slack)
    with pytest.raises(
        ValueError, match=r"^power flow: start 'cold' is not 'case' or 'flat'$"
    ):
        solve_power_flow(system, start="cold")
    isolated = eqx.tree_at(
        lambda s: s.buses.kind, system, np.array([3, 2, 2, 1, 4, 1, 1, 1, 1])
    )
    with pytest.raises(
        ValueError,
        match=r"^power flow: bus 5 has type 4; the power flow takes 1 \(PQ\), 2 "
        r"\(PV\) and 3 \(slack\)$",
    ):
        solve_power_flow(isolated)
    x = np.asarray(system.branches.x).copy()
    x[4] = 0.0
    shorted = eqx.tree_at(
        lambda s: (s.branches.r, s.branches.x), system, (np.zeros(9), x)
    )
    with pytest.raises(
        ValueError, match=r"^power flow: branch 4-6 has zero impedance \(r = x = 0\)$"
    ):
        solve_power_flow(shorted)
