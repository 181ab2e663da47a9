"""The synchronous machines of smibjax.grid.devices (GENCLS, GENTRA, GENROU): their
equilibria, their equations against the paper's SMIB model (MODEL.md section 1) and
the classical swing equation in closed form, GENROU against ANDES 2.0 (a stored run,
tests/data/machines/andes_genrou_smib.npz, made by make_andes_genrou_smib.py beside
it; and ANDES's own initialisation when andes is installed), the saturation fits
against their data points, and a gradient through a simulation against finite
differences.

Every network here is one node: the machine's terminal bus, tied to an infinite bus
V_inf through a line reactance X (and a fault shunt y_f), solved in closed form,
V = (i_n + V_inf y_line) / (y + y_line + y_f)."""

import dataclasses
import importlib.util
from pathlib import Path

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax._validate import ParameterError
from smibjax.grid.devices.gencls import GENCLS
from smibjax.grid.devices.genroe import GENROE
from smibjax.grid.devices.genrou import GENROU
from smibjax.grid.devices.gensae import GENSAE
from smibjax.grid.devices.gensal import GENSAL
from smibjax.grid.devices.gentra import GENTRA
from smibjax.grid.devices.saturation import quadratic_fit, saturation_factor

DATA = Path(__file__).parent / "data" / "machines"
S_BASE = 100.0
WB = 2 * np.pi * 60.0


def _script():
    spec = importlib.util.spec_from_file_location(
        "make_andes_genrou_smib", DATA / "make_andes_genrou_smib.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


REF = _script()  # the ANDES case's data (and its builder)


def _network_voltage(machine, x, held, v_inf, x_line, y_f=0.0):
    """Terminal voltage (pu) of the one-node network: the machine's Norton source,
    a line j x_line (system base) to v_inf and a shunt y_f at the terminal."""
    i_n, y = machine.norton(x, held, S_BASE)
    y_line = 1.0 / (1j * x_line)
    return (i_n + v_inf * y_line) / (y + y_line + y_f)


# -- random machines and operating points --------------------------------------------


def _saturation(rng, k):
    """(S10, S12): saturated on half of the k machines, none on the other half."""
    s10 = rng.uniform(0.02, 0.15, k)
    s12 = s10 * rng.uniform(2.5, 5.0, k)
    off = np.arange(k) % 2 == 1
    return np.where(off, 0.0, s10), np.where(off, 0.0, s12)


def _random_machine(model, rng, k, saturation="quadratic"):
    mbase = rng.choice([100.0, 200.0, 900.0], k)
    common = dict(
        gen=np.arange(k),
        mbase=mbase,
        H=rng.uniform(2, 8, k),
        D=rng.uniform(0, 2, k),
        ra=rng.uniform(0, 0.005, k),
    )
    if model == "GENCLS":
        return GENCLS(xdp=rng.uniform(0.15, 0.4, k), **common)
    s10, s12 = _saturation(rng, k)
    if model == "GENTRA":
        xdp = rng.uniform(0.15, 0.4, k)
        return GENTRA(
            Tdop=rng.uniform(3, 9, k),
            xd=xdp + rng.uniform(0.6, 1.6, k),
            xq=xdp,
            xdp=xdp,
            S10=s10,
            S12=s12,
            saturation=saturation,
            **common,
        )
    xl = rng.uniform(0.05, 0.15, k)
    xdpp = xl + rng.uniform(0.05, 0.15, k)
    xdp = xdpp + rng.uniform(0.03, 0.2, k)
    xqp = xdpp + rng.uniform(0.05, 0.4, k)
    if model in ("GENSAL", "GENSAE"):
        return {"GENSAL": GENSAL, "GENSAE": GENSAE}[model](
            Tdop=rng.uniform(3, 9, k),
            Tdopp=rng.uniform(0.02, 0.06, k),
            Tqopp=rng.uniform(0.02, 0.1, k),
            xd=xdp + rng.uniform(0.8, 1.5, k),
            xq=xdpp + rng.uniform(0.3, 1.2, k),
            xdp=xdp,
            xdpp=xdpp,
            xl=xl,
            S10=s10,
            S12=s12,
            saturation=saturation,
            **common,
        )
    return {"GENROU": GENROU, "GENROE": GENROE}[model](
        Tdop=rng.uniform(3, 9, k),
        Tdopp=rng.uniform(0.02, 0.06, k),
        Tqop=rng.uniform(0.3, 1.5, k),
        Tqopp=rng.uniform(0.02, 0.1, k),
        xd=xdp + rng.uniform(0.8, 1.5, k),
        xq=xqp + rng.uniform(0.3, 1.2, k),
        xdp=xdp,
        xqp=xqp,
        xdpp=xdpp,
        xl=xl,
        S10=s10,
        S12=s12,
        saturation=saturation,
        **common,
    )


def _random_operating_point(rng, machine):
    """Terminal voltages and injections (system base): |V| in [0.95, 1.05], angle in
    [-0.5, 0.5] rad, P in [0.2, 1], Q in [-0.3, 0.5] pu on the machine base."""
    k = machine.mbase.shape[0]
    v = rng.uniform(0.95, 1.05, k) * np.exp(1j * rng.uniform(-0.5, 0.5, k))
    s = (rng.uniform(0.2, 1.0, k) + 1j * rng.uniform(-0.3, 0.5, k)) * machine.mbase
    return jnp.asarray(v), jnp.asarray(s / S_BASE)


CASES = [
    ("GENCLS", "quadratic", 1),
    ("GENTRA", "quadratic", 2),
    ("GENTRA", "exponential", 3),
    ("GENROU", "quadratic", 4),
    ("GENROU", "exponential", 5),
    ("GENROE", "exponential", 6),
    ("GENSAL", "quadratic", 7),
    ("GENSAE", "exponential", 8),
]


@eqx.filter_jit
def _at_rest(m, v, s):
    """init, and rhs, Norton injection and measurements at the initial state."""
    x0, held = m.init(v, s, S_BASE)
    i_n, y = m.norton(x0, held, S_BASE)
    dx = m.rhs(x0, v, held, held, S_BASE)
    return x0, held, dx, i_n - y * v, m.measure(x0, v, held, S_BASE)


@pytest.mark.parametrize(("model", "saturation", "seed"), CASES)
def test_init_is_an_equilibrium_that_delivers_the_power_flow(model, saturation, seed):
    rng = np.random.default_rng(seed)
    m = _random_machine(model, rng, 16, saturation)
    v, s = _random_operating_point(rng, m)
    x0, held, dx, i_inj, meas = _at_rest(m, v, s)
    assert x0.shape == (len(m.state_names), 16)
    assert float(jnp.max(jnp.abs(dx))) < 1e-10
    # the Norton source injects the power flow's current at the power flow's voltage
    np.testing.assert_allclose(i_inj, jnp.conj(s / v), rtol=0, atol=1e-12)
    s_m = s * S_BASE / m.mbase
    np.testing.assert_allclose(meas["Pe"], s_m.real, atol=1e-12)
    np.testing.assert_allclose(meas["Qe"], s_m.imag, atol=1e-12)
    # Pm covers the electrical power and the armature loss
    loss = m.ra * np.abs(s_m / v) ** 2
    np.testing.assert_allclose(held["Pm"], s_m.real + loss, atol=1e-12)


@eqx.filter_jit
def _rhs_on_infinite_bus(m, x, cmd, v_inf, x_line):
    v = _network_voltage(m, x, cmd, v_inf, x_line)
    return m.rhs(x, v, cmd, cmd, S_BASE)


# -- against the paper and the classical swing equation ----------------------------


def test_gentra_on_an_infinite_bus_is_the_papers_flux_decay_model():
    """MODEL.md section 1 with T0 = T'do, Xs = X'd + X, Xds = Xd + X (the terminal tied
    to the infinite bus V through X), D_paper = D / omega_b, u_f = Efd:
    dE/dt = -Xds/(Xs T0) E + (Xd - X'd)/(Xs T0) V cos(delta) + u_f/T0,
    M d domega/dt = Pm - D_paper domega - E V sin(delta)/Xs, M = 2H/omega_b."""
    rng = np.random.default_rng(11)
    k = 32
    xdp = rng.uniform(0.15, 0.4, k)
    m = GENTRA(
        gen=np.arange(k),
        mbase=np.full(k, S_BASE),  # the paper is on one base
        H=rng.uniform(2, 8, k),
        D=rng.uniform(0, 30, k),
        Tdop=rng.uniform(2, 9, k),
        xd=xdp + rng.uniform(0.5, 1.5, k),
        xq=xdp,
        xdp=xdp,
        ra=np.zeros(k),
    )
    delta = rng.uniform(-1.5, 2.5, k)
    omega = rng.uniform(-0.02, 0.02, k)
    e = rng.uniform(0.8, 1.6, k)
    uf, pm = rng.uniform(0.5, 3.0, k), rng.uniform(0.2, 1.2, k)
    v_inf, x_line = rng.uniform(0.9, 1.1, k), rng.uniform(0.1, 0.8, k)
    x = jnp.stack([delta, omega, e])
    dx = np.asarray(_rhs_on_infinite_bus(m, x, {"Efd": uf, "Pm": pm}, v_inf, x_line))

    xs, xds, t0 = m.xdp + x_line, m.xd + x_line, m.Tdop
    de = -xds / (xs * t0) * e + (m.xd - m.xdp) / (xs * t0) * v_inf * np.cos(delta)
    de = de + uf / t0
    dom = omega * WB  # the paper's domega (rad/s)
    p = e * v_inf * np.sin(delta) / xs
    ddom = (pm - m.D / WB * dom - p) / (2 * m.H / WB)
    np.testing.assert_allclose(dx[2], de, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dx[0], dom, rtol=1e-15, atol=1e-12)
    np.testing.assert_allclose(dx[1] * WB, ddom, rtol=0, atol=1e-12 * WB)


def test_gencls_on_an_infinite_bus_is_the_classical_swing_equation():
    """2H domega/dt = Pm - E' V sin(delta - theta_inf)/(X'd + X) - D omega, with the
    machine on a base other than the system's."""
    rng = np.random.default_rng(12)
    k = 32
    m = _random_machine("GENCLS", rng, k)
    m = eqx.tree_at(lambda g: g.ra, m, np.zeros(k))
    delta, omega = rng.uniform(-1.5, 2.5, k), rng.uniform(-0.02, 0.02, k)
    e, pm = rng.uniform(0.8, 1.4, k), rng.uniform(0.2, 1.2, k)
    th = rng.uniform(-0.3, 0.3, k)
    v_inf, x_line = rng.uniform(0.9, 1.1, k) * np.exp(1j * th), rng.uniform(0.1, 0.8, k)
    x = jnp.stack([delta, omega])
    dx = np.asarray(_rhs_on_infinite_bus(m, x, {"Efd": e, "Pm": pm}, v_inf, x_line))
    xs = m.xdp + x_line * m.mbase / S_BASE  # on the machine base
    pe = e * np.abs(v_inf) * np.sin(delta - th) / xs
    np.testing.assert_allclose(dx[0], WB * omega, rtol=1e-15)
    np.testing.assert_allclose(dx[1], (pm - pe - m.D * omega) / (2 * m.H), atol=1e-12)


# -- GENROU against ANDES --------------------------------------------------------------


def _ref_machine(**over):
    """The ANDES case's GENROU (make_andes_genrou_smib.GEN) in smibjax's names."""
    g = REF.GEN
    kw = dict(
        gen=[0],
        mbase=[g["Sn"]],
        H=[g["M"] / 2],
        D=[g["D"]],
        Tdop=[g["Td10"]],
        Tdopp=[g["Td20"]],
        Tqop=[g["Tq10"]],
        Tqopp=[g["Tq20"]],
        xd=[g["xd"]],
        xq=[g["xq"]],
        xdp=[g["xd1"]],
        xqp=[g["xq1"]],
        xdpp=[g["xd2"]],
        xl=[g["xl"]],
        ra=[g["ra"]],
        S10=[g["S10"]],
        S12=[g["S12"]],
        f_base=REF.F_BASE,
        speed_factor=False,  # ANDES's swing equation (PSS/E's has the speed factor)
    )
    kw.update(over)
    return GENROU(**kw)


def _ref_power_flow():
    """The case's power flow in closed form: |V1| = V_GEN, P = P_GEN through j X_LINE
    to V_INF at angle 0."""
    th = np.arcsin(REF.P_GEN * REF.X_LINE / (REF.V_GEN * REF.V_INF))
    v1 = REF.V_GEN * np.exp(1j * th)
    i = (v1 - REF.V_INF) / (1j * REF.X_LINE)
    return jnp.asarray([v1]), jnp.asarray([v1 * np.conj(i)])


N_SAVE = 502  # the fixture's time points; every run saves this many (one compile)


@eqx.filter_jit
def _simulate(machine, ts, t1):
    """The one-node system through the fault (REF's times and reactance) from the
    power flow's equilibrium, integrated to t1 with Tsit5 (rtol 1e-10, atol 1e-12);
    the states at ts (shape (N_SAVE, n_states, 1))."""
    v, s = _ref_power_flow()
    x0, held = machine.init(v, s, S_BASE)
    y_f = 1.0 / (1j * REF.XF)

    def f(t, x, args):
        on = (t >= REF.T_FAULT) & (t < REF.T_CLEAR)
        vt = _network_voltage(machine, x, held, REF.V_INF, REF.X_LINE, on * y_f)
        return machine.rhs(x, vt, held, held, S_BASE)

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(f),
        diffrax.Tsit5(),
        t0=0.0,
        t1=t1,
        dt0=1e-3,
        y0=x0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(
            rtol=1e-10, atol=1e-12, jump_ts=jnp.array([REF.T_FAULT, REF.T_CLEAR])
        ),
        max_steps=100_000,
    )
    return sol.ys


def _errors(run):
    """max |ours - ANDES's| of each state over ANDES's time points (omega: ANDES's
    speed less 1), and ANDES's angle swing (rad)."""
    ts, first = np.unique(run["t"], return_index=True)
    n = ts.size
    assert n <= N_SAVE
    pad = np.concatenate([ts, np.full(N_SAVE - n, ts[-1])])
    ys = np.asarray(_simulate(_ref_machine(), jnp.asarray(pad), jnp.asarray(ts[-1])))
    ys = ys[:n, :, 0]
    ref = {k: run[k][first] for k in GENROU.state_names}
    ref["omega"] = ref["omega"] - 1.0
    err = {k: float(np.max(np.abs(ys[:, i] - ref[k]))) for i, k in enumerate(ref)}
    np.testing.assert_allclose(ys[0], [ref[k][0] for k in ref], atol=1e-9)
    return err, float(np.ptp(ref["delta"]))


@pytest.fixture(scope="module")
def andes_run():
    return dict(np.load(DATA / "andes_genrou_smib.npz"))


def test_the_andes_fixture_is_the_scripts_case(andes_run):
    """The stored run was made from the script's current data (else: rerun it)."""
    assert list(andes_run["gen_names"]) == list(REF.GEN)
    np.testing.assert_array_equal(andes_run["gen_values"], list(REF.GEN.values()))
    case = [REF.S_BASE, REF.F_BASE, REF.P_GEN, REF.V_GEN, REF.V_INF, REF.X_LINE]
    case += [REF.XF, REF.T_FAULT, REF.T_CLEAR, REF.T_END, REF.STEP, REF.EVENT_EPS]
    np.testing.assert_array_equal(andes_run["case"], case)
    assert andes_run["t"].size == N_SAVE


def test_genrou_follows_andes_through_a_terminal_fault(andes_run):
    """Rotor angle, speed and the four fluxes over 5 s (fault 0.5-0.6 s through
    j0.05 at the terminal) against ANDES's stored trapezoidal run at 1 ms, from the
    same initial state. Measured (max over the run): delta 5.1e-6 rad, omega 1.2e-7
    pu, e1q 2.3e-7, e1d 1.0e-6, e2d 2.7e-6, e2q 7.7e-6 pu; ANDES's 1 ms step is most
    of it (with ANDES's default eps = 1e-4 s around events the angle differs by
    7.4e-5 rad, see make_andes_genrou_smib.py). The bounds leave a factor 5-20."""
    err, swing = _errors(andes_run)
    assert swing > 0.2  # the fault moves the rotor
    assert err["delta"] < 5e-5, err
    assert err["omega"] < 1e-6, err
    for k in ("e1q", "e1d", "e2d", "e2q"):
        assert err[k] < 5e-5, err


def test_genrou_follows_a_live_andes_run():
    """The same case through ANDES here (andes is not a test dependency): its power
    flow and GENROU initialisation against ours, and the first second of the run."""
    pytest.importorskip("andes")
    ss = REF.build()
    ss.PFlow.run()
    v, s = _ref_power_flow()
    v_a = ss.Bus.v.v[0] * np.exp(1j * ss.Bus.a.v[0])
    s_a = ss.PV.p.v[0] + 1j * ss.PV.q.v[0]
    np.testing.assert_allclose([v_a, s_a], [v[0], s[0]], atol=1e-6)  # PF tolerance
    ss.TDS.init()
    # from ANDES's power flow, the same initialisation to rounding
    m = _ref_machine()
    x0, held = m.init(jnp.asarray([v_a]), jnp.asarray([s_a]), S_BASE)
    g = ss.GENROU
    andes = [g.delta.v[0], g.omega.v[0] - 1] + [
        getattr(g, n).v[0] for n in ("e1q", "e1d", "e2d", "e2q")
    ]
    np.testing.assert_allclose(np.asarray(x0[:, 0]), andes, rtol=0, atol=1e-12)
    np.testing.assert_allclose(held["Efd"][0], g.vf0.v[0], rtol=0, atol=1e-12)
    pm = g.tm0.v[0] * S_BASE / m.mbase[0]  # ANDES's torque is on the system base
    np.testing.assert_allclose(held["Pm"][0], pm, rtol=0, atol=1e-12)
    err, _ = _errors(REF.run_andes(t_end=1.0, keep_every=5))
    assert err["delta"] < 5e-5, err


# -- saturation -------------------------------------------------------------------------


_se = jax.jit(saturation_factor, static_argnames="kind")


@pytest.mark.parametrize("kind", ["quadratic", "exponential"])
def test_saturation_fits_pass_through_their_data_points(kind):
    s10 = np.array([0.05, 0.1, 0.03, 0.2, 0.0])
    s12 = np.array([0.2, 0.4, 0.5, 0.25, 0.0])
    if kind == "exponential":  # S12 < S10: a falling factor, still through both
        s10, s12 = np.append(s10, 0.3), np.append(s12, 0.2)
    for psi, want in ((1.0, s10), (1.2, s12)):
        got = _se(jnp.full(s10.shape, psi), s10, s12, kind=kind)
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-15)
    psi = np.linspace(0.5, 1.5, 11)[:, None]
    se = np.asarray(_se(psi, s10, s12, kind=kind))
    if kind == "quadratic":
        # ANDES's ExcQuadSat (E1 = 1, E2 = 1.2): Se psi = B (psi - A)^2 above A
        a = np.sqrt(s10 / (1.2 * np.where(s12 > 0, s12, 1)))
        big_a = 1.2 - (1.0 - 1.2) / (a - 1)
        big_b = np.where(s12 > 0, s12 * 1.2 * (a - 1) ** 2 / 0.2**2, 0.0)
        want = np.where(psi > big_a, big_b * (psi - big_a) ** 2 / psi, 0.0)
        np.testing.assert_allclose(quadratic_fit(s10, s12)[0], big_a, rtol=1e-14)
    else:
        n = np.log(np.where(s10 > 0, s12 / np.where(s10 > 0, s10, 1), 1)) / np.log(1.2)
        want = s10 * psi**n
    np.testing.assert_allclose(se, want, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("kind", ["quadratic", "exponential"])
def test_s10_zero_is_no_saturation_whatever_s12(kind):
    """PSS/E: S(1.0) = 0 means no saturation at all. Before, the quadratic fit went
    through (1.0, 0) and (1.2, S12) and saturated from 1 pu (Se(1.2) = S12); and a
    GENROU with S10 = 0 < S12 must behave as one with S10 = S12 = 0 (init and rhs
    at a state whose air-gap flux is above 1.2 pu)."""
    s12 = np.array([0.3, 0.05, 1.0])
    psi = np.linspace(0.5, 2.0, 16)[:, None]
    assert np.all(np.asarray(_se(psi, np.zeros(3), s12, kind=kind)) == 0.0)
    sat = _ref_machine(S10=[0.0], S12=[0.4], saturation=kind)
    none = _ref_machine(S10=[0.0], S12=[0.0], saturation=kind)
    v, s = _ref_power_flow()
    v, s = v * 1.25, s * 1.2  # a high voltage: |E''| about 1.4 pu
    x0, held = none.init(v, s, S_BASE)
    x1, held1 = sat.init(v, s, S_BASE)
    assert float(jnp.abs(none._emf(x0))[0]) > 1.2
    np.testing.assert_array_equal(x1, x0)
    np.testing.assert_array_equal(held1["Efd"], held["Efd"])
    x = x0.at[2].multiply(1.1)  # off equilibrium, more flux
    dx = [m.rhs(x, v, held, held, S_BASE) for m in (sat, none)]
    np.testing.assert_array_equal(dx[0], dx[1])


def test_bad_machine_data_is_refused_with_one_line():
    base = dict(gen=[0], mbase=[100.0], H=[4.0], D=[0.0], Tdop=[6.0], xd=[1.8])
    base.update(xq=[0.3], xdp=[0.3], ra=[0.0])
    cases = [
        (GENTRA, dict(xq=[0.5]), r"GENTRA.xq = \[0.5\] is not allowed: transient"),
        (GENTRA, dict(S10=[0.3], S12=[0.2]), "S10 < 1.2 S12"),
        (GENTRA, dict(S10=[0.1], S12=[0.0], saturation="exponential"), "S12 > 0"),
        (GENTRA, dict(saturation="cubic"), "GENTRA.saturation = 'cubic'"),
        (GENTRA, dict(H=[0.0]), r"GENTRA.H = \[0.\] is not allowed: must be > 0"),
    ]
    for cls, over, msg in cases:
        with pytest.raises(ParameterError, match=msg) as err:
            cls(**{**base, **over})
        assert "\n" not in str(err.value)
    with pytest.raises(ParameterError, match="GENROU.xqpp = .* X''q = X''d") as err:
        _ref_machine(xqpp=[0.2])
    assert "\n" not in str(err.value)
    with pytest.raises(
        ParameterError, match=r"GENROU.xdp = \[0.1\] .* >= xdpp = \[0.25\]"
    ):
        _ref_machine(xdp=[0.1])
    _ref_machine(xqpp=[REF.GEN["xd2"]])  # equal is fine


# -- differentiability ------------------------------------------------------------------


def _angle_at_1s(h):
    """delta(1 s) of the fault run (REF's case) with inertia constant h (s): a run of
    its own, saving only t1 and with a small step budget, for reverse mode."""
    m = _ref_machine(H=jnp.reshape(h, (1,)))
    v, s = _ref_power_flow()
    x0, held = m.init(v, s, S_BASE)
    y_f = 1.0 / (1j * REF.XF)

    def f(t, x, args):
        on = (t >= REF.T_FAULT) & (t < REF.T_CLEAR)
        vt = _network_voltage(m, x, held, REF.V_INF, REF.X_LINE, on * y_f)
        return m.rhs(x, vt, held, held, S_BASE)

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(f),
        diffrax.Tsit5(),
        t0=0.0,
        t1=1.0,
        dt0=1e-3,
        y0=x0,
        saveat=diffrax.SaveAt(t1=True),
        stepsize_controller=diffrax.PIDController(
            rtol=1e-9, atol=1e-11, jump_ts=jnp.array([REF.T_FAULT, REF.T_CLEAR])
        ),
        max_steps=1024,
    )
    return sol.ys[-1, 0, 0]


# one compiled program: the gradient at h0 and the values at h0 +- eps (its forward
# pass). jax.grad of a jitted function and the function alone compiled three
# programs (the forward, its transpose, the primal); pytest of this test alone from
# a cold cache: 9.5 -> 8.6 CPU-s (user + sys, 2026-12-03)
_angle_and_gradient = eqx.filter_jit(jax.value_and_grad(_angle_at_1s))


def test_rotor_angle_gradient_with_respect_to_h_matches_finite_differences():
    """d delta(1 s) / dH of GENROU through the fault (0.5-0.6 s), reverse mode through
    diffrax, against a central difference."""
    h0, eps = REF.GEN["M"] / 2, 1e-4
    g = float(_angle_and_gradient(jnp.asarray(h0))[1])
    up, down = (_angle_and_gradient(jnp.asarray(h0 + e))[0] for e in (eps, -eps))
    fd = float((up - down) / (2 * eps))
    assert abs(g) > 1e-3  # the angle does depend on H
    np.testing.assert_allclose(g, fd, rtol=1e-6)


# -- GENSAL, GENSAE, GENROE ---------------------------------------------------------
#
# ANDES 2.0 has none of them, so (a) the limit where the model definitions coincide
# and (b) an independent integration of PSS/E's equations written here in numpy in
# OpenIPSL's variables (OpenIPSL.Electrical.Machines.PSSE.GENSAL/GENSAE/GENROE, the
# PSS/E-validated Modelica library): the stator and the one-node network solved as a
# 2x2 real system in the rotor frame (no Norton source), scipy's DOP853.

SALIENT = dict(
    Tdop=6.0, Tdopp=0.05, Tqopp=0.06, H=4.0, D=1.0, xd=1.8, xq=1.7, xdp=0.3,
    xdpp=0.25, xl=0.15, ra=0.003, S10=0.1, S12=0.4,
)  # fmt: skip


def _salient_machine(cls, **over):
    kw = {k: [v] for k, v in {**SALIENT, **over}.items()}
    return cls(gen=[0], mbase=[REF.GEN["Sn"]], f_base=REF.F_BASE, **kw)


def test_gensal_is_genrou_without_q_transient_circuit_and_saturation():
    """The model definitions coincide when GENROU's q-axis transient circuit is
    removed: X'q = X''q (= X''d) makes GENROU's psi''q = E'd (gq1 = 1, gq2 = 0), its
    T'qo dE'd/dt = -E'd + (Xq - X'') Iq is GENSAL's q-axis equation with T'qo =
    T''qo, and its damper state e2q drops out; the d axes are the same circuit; with
    Se = 0 (saturation differs: GENROU's on |psi''| on both axes, GENSAL's on E'q on
    the d axis) the two are one model. Checked on random machines and states: init,
    Norton source, rhs and measurements to rounding."""
    rng = np.random.default_rng(21)
    k = 16
    sal = _random_machine("GENSAL", rng, k)
    sal = eqx.tree_at(lambda m: (m.S10, m.S12), sal, (np.zeros(k), np.zeros(k)))
    rou = GENROU(
        gen=sal.gen, mbase=sal.mbase, H=sal.H, D=sal.D, Tdop=sal.Tdop,
        Tdopp=sal.Tdopp, Tqop=sal.Tqopp, Tqopp=rng.uniform(0.01, 0.1, k), xd=sal.xd,
        xq=sal.xq, xdp=sal.xdp, xqp=sal.xdpp, xdpp=sal.xdpp, xl=sal.xl, ra=sal.ra,
    )  # fmt: skip
    v, s = _random_operating_point(rng, sal)
    xs, hs = sal.init(v, s, S_BASE)
    xr, hr = rou.init(v, s, S_BASE)
    swap = np.array([0, 1, 2, 4, 3])  # GENROU's (.., e1q, e2d, e1d) = GENSAL's
    np.testing.assert_allclose(xr[swap], xs, rtol=0, atol=1e-13)
    np.testing.assert_allclose(hr["Efd"], hs["Efd"], rtol=0, atol=1e-13)
    np.testing.assert_allclose(hr["Pm"], hs["Pm"], rtol=0, atol=1e-13)
    # away from rest: random states, voltages and commands
    x_s = xs * rng.uniform(0.8, 1.2, xs.shape) + rng.uniform(-0.1, 0.1, xs.shape)
    x_r = jnp.stack([x_s[0], x_s[1], x_s[2], x_s[4], x_s[3], rng.uniform(-1, 1, k)])
    vv = v * rng.uniform(0.5, 1.1, k)
    cmd = {"Efd": rng.uniform(1, 3, k), "Pm": rng.uniform(0, 1, k)}
    np.testing.assert_allclose(
        rou.norton(x_r, hr, S_BASE)[0], sal.norton(x_s, hs, S_BASE)[0], atol=1e-13
    )
    dr, ds = rou.rhs(x_r, vv, cmd, hr, S_BASE), sal.rhs(x_s, vv, cmd, hs, S_BASE)
    np.testing.assert_allclose(dr[swap], ds, rtol=1e-12, atol=1e-12)
    mr, ms = rou.measure(x_r, vv, hr, S_BASE), sal.measure(x_s, vv, hs, S_BASE)
    assert set(mr) == set(ms)
    for key in mr:
        np.testing.assert_allclose(mr[key], ms[key], rtol=1e-12, atol=1e-12)
    # and saturation is where they differ (GENSAL: Se(E'q) E'q on the d axis only)
    sat = eqx.tree_at(lambda m: (m.S10, m.S12), sal, (np.full(k, 0.1), np.full(k, 0.4)))
    d_sat = sat.rhs(x_s, vv, cmd, hs, S_BASE) - ds
    e1q = x_s[2]
    se = np.asarray(saturation_factor(e1q, 0.1, 0.4))
    np.testing.assert_allclose(d_sat[2], -se * e1q / sal.Tdop, rtol=1e-12, atol=1e-14)
    assert np.all(np.asarray(d_sat)[[0, 1, 3, 4]] == 0.0)


def _se_quadratic(u, s10, s12):
    """OpenIPSL's SE (PTI PSS/E scaled quadratic, E1 = 1, E2 = 1.2), S10 = 0: none."""
    if s10 == 0.0 or u <= 0.0:
        return 0.0
    a = np.sqrt(s10 * 1.0 / (s12 * 1.2))
    big_a = 1.2 - (1.0 - 1.2) / (a - 1.0)
    big_b = s12 * 1.2 * (a - 1.0) ** 2 / (1.0 - 1.2) ** 2
    return 0.0 if u <= big_a else big_b * (u - big_a) ** 2 / u


def _se_exponential(u, s10, s12):
    """OpenIPSL's SE_exp: S10 u^X, X = ln(S12/S10) / ln(1.2)."""
    return 0.0 if s10 == 0.0 else s10 * u ** (np.log(s12 / s10) / np.log(1.2))


def _openipsl_rhs(model, p, se, efd, pm, fault):
    """dy/dt of OpenIPSL's PSSE machine `model` on REF's one-node network (machine
    base), y = (delta, w, Epq, PSIkd, PSIppq) for GENSAL/GENSAE and (delta, w, Epq,
    Epd, PSIkd, PSIkq) for GENROE."""
    mb = REF.GEN["Sn"] / S_BASE
    x_line, x_f = REF.X_LINE * mb, REF.XF * mb
    kv = 1.0 / (1.0 + x_line / x_f) if fault else 1.0  # V_t = kv (V_inf + j X I)
    xpp, xl = p["xdpp"], p["xl"]
    k3d = (xpp - xl) / (p["xdp"] - xl)
    k4d = (p["xdp"] - xpp) / (p["xdp"] - xl)
    k1d = (p["xdp"] - xpp) * (p["xd"] - p["xdp"]) / (p["xdp"] - xl) ** 2
    salient = model in ("GENSAL", "GENSAE")

    def f(t, y):
        delta, w, epq = y[0], y[1], y[2]
        psikd = y[3] if salient else y[4]
        psippd = epq * k3d + psikd * k4d
        if salient:
            psippq = y[4]
        else:
            epd, psikq = y[3], y[5]
            k3q = (xpp - xl) / (p["xqp"] - xl)
            k4q = (p["xqp"] - xpp) / (p["xqp"] - xl)
            psippq = epd * k3q + psikq * k4q
        # stator ud = PSIppq + X'' iq - Ra id, uq = PSIppd - X'' id - Ra iq against
        # the network ud = kv (V sin delta - X iq), uq = kv (V cos delta + X id)
        a = np.array([[-p["ra"], xpp + kv * x_line], [-(xpp + kv * x_line), -p["ra"]]])
        rhs = [
            kv * REF.V_INF * np.sin(delta) - psippq,
            kv * REF.V_INF * np.cos(delta) - psippd,
        ]
        i_d, i_q = np.linalg.solve(a, rhs)
        psi_d, psi_q = psippd - xpp * i_d, -psippq - xpp * i_q
        te = psi_d * i_q - psi_q * i_d
        # OpenIPSL's PSSE baseMachine: the mechanical torque at the rotor's speed
        d_w = ((pm - p["D"] * w) / (1.0 + w) - te) / (2 * p["H"])
        d_kd = (epq - psikd - (p["xdp"] - xl) * i_d) / p["Tdopp"]
        if salient:
            xad = (
                k1d * (epq - psikd - (p["xdp"] - xl) * i_d) + (p["xd"] - p["xdp"]) * i_d
            )
            d_ppq = -psippq + (p["xq"] - xpp) * i_q
            if model == "GENSAL":  # Se(E'q) E'q, the d axis only
                xad += (se(epq, p["S10"], p["S12"]) + 1) * epq
            else:  # GENSAE: Se(|psi''|) on both axes, as GENROE
                s = se(np.hypot(psippd, psippq), p["S10"], p["S12"])
                xad += epq + s * psippd
                d_ppq -= psippq * (p["xq"] - xl) / (p["xd"] - xl) * s
            return [WB * w, d_w, (efd - xad) / p["Tdop"], d_kd, d_ppq / p["Tqopp"]]
        s = se(np.hypot(psippd, psippq), p["S10"], p["S12"])
        k1q = (p["xqp"] - xpp) * (p["xq"] - p["xqp"]) / (p["xqp"] - xl) ** 2
        xad = k1d * (epq - psikd - (p["xdp"] - xl) * i_d) + epq
        xad += i_d * (p["xd"] - p["xdp"]) + s * psippd
        xaq = (
            k1q * (epd - psikq + (p["xqp"] - xl) * i_q)
            + epd
            - i_q * (p["xq"] - p["xqp"])
        )
        xaq += s * psippq * (p["xq"] - xl) / (p["xd"] - xl)
        d_kq = (epd - psikq + (p["xqp"] - xl) * i_q) / p["Tqopp"]
        return [WB * w, d_w, (efd - xad) / p["Tdop"], -xaq / p["Tqop"], d_kd, d_kq]

    return f


def _openipsl_run(model, p, se, y0, efd, pm, ts):
    """The fault run (REF's times) of `_openipsl_rhs`, the states at ts (n, n_y)."""
    from scipy.integrate import solve_ivp

    out, y = [], np.asarray(y0, float)
    edges = [0.0, REF.T_FAULT, REF.T_CLEAR, ts[-1]]
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        sel = ts[(ts >= a) & (ts < b)]
        f = _openipsl_rhs(model, p, se, efd, pm, fault=(k == 1))
        t_eval = np.append(sel, b)
        sol = solve_ivp(f, (a, b), y, "DOP853", t_eval=t_eval, rtol=1e-11, atol=1e-12)
        assert sol.success
        out.append(sol.y.T[:-1])
        y = sol.y[:, -1]
    out.append(y[None])
    return np.concatenate(out)


def _three_models():
    ref = _ref_machine()
    rou = {f.name: getattr(ref, f.name) for f in dataclasses.fields(GENROU)}
    rou.pop("saturation")
    rou.pop("speed_factor")  # PSS/E's (the default), as OpenIPSL's equations
    return {
        "GENSAL": _salient_machine(GENSAL),
        "GENSAE": _salient_machine(GENSAE),
        "GENROE": GENROE(**rou),
    }


@pytest.mark.parametrize("model", ["GENSAL", "GENSAE", "GENROE"])
def test_machine_follows_an_independent_integration_of_psse_equations(model):
    """GENSAL / GENSAE / GENROE through REF's terminal fault (0.5-0.6 s through
    j0.05) for 2 s against `_openipsl_run` (OpenIPSL's equations, numpy/scipy), from
    the same states; and smibjax's init is an equilibrium of those equations
    (|dy/dt| < 1e-9). Saturation is active (Se(E'q) above 0.02 at rest).
    Measured: delta 3e-11 (GENSAL, GENSAE) and 9e-11 rad (GENROE), omega 2e-12 pu,
    fluxes below 1.1e-9 pu (GENSAL's fast psi''q; Tsit5 at rtol 1e-10, DOP853 at
    rtol 1e-11)."""
    m = _three_models()[model]
    assert type(m).__name__ == model
    v, s = _ref_power_flow()
    x0, held = m.init(v, s, S_BASE)
    efd, pm = float(held["Efd"][0]), float(held["Pm"][0])
    p = {f.name: getattr(m, f.name) for f in dataclasses.fields(m)}
    p = {k: float(a[0]) for k, a in p.items() if np.ndim(a) == 1 and k != "gen"}
    se = _se_exponential if model in ("GENSAE", "GENROE") else _se_quadratic
    # smibjax's states in OpenIPSL's variables
    y0 = np.asarray(x0[:, 0])  # the same order (genrou.py, gensal.py)
    f0 = _openipsl_rhs(model, p, se, efd, pm, fault=False)(0.0, y0)
    assert np.max(np.abs(f0)) < 1e-9, f0
    assert se(float(x0[2, 0]), p["S10"], p["S12"]) > 0.02  # saturation matters
    ts = np.linspace(0.0, 2.0, N_SAVE)
    ref = _openipsl_run(model, p, se, y0, efd, pm, ts)
    ys = np.asarray(_simulate(m, jnp.asarray(ts), jnp.asarray(2.0)))[:, :, 0]
    assert np.ptp(ref[:, 0]) > 0.15  # the fault moves the rotor (0.197 rad GENSAL)
    err = np.max(np.abs(ys - ref), axis=0)
    assert err[0] < 1e-8 and err[1] < 1e-9 and np.all(err[2:] < 1e-8), err


def _angle_at_1s_of(value, model, name):
    """delta(1 s) of REF's fault run for the `_three_models()[model]` machine with
    parameter `name` set to `value` (reverse mode, as `_angle_at_1s`)."""
    m = eqx.tree_at(
        lambda g: getattr(g, name), _three_models()[model], jnp.reshape(value, (1,))
    )
    v, s = _ref_power_flow()
    x0, held = m.init(v, s, S_BASE)
    y_f = 1.0 / (1j * REF.XF)

    def f(t, x, args):
        on = (t >= REF.T_FAULT) & (t < REF.T_CLEAR)
        vt = _network_voltage(m, x, held, REF.V_INF, REF.X_LINE, on * y_f)
        return m.rhs(x, vt, held, held, S_BASE)

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(f),
        diffrax.Tsit5(),
        t0=0.0,
        t1=1.0,
        dt0=1e-3,
        y0=x0,
        saveat=diffrax.SaveAt(t1=True),
        stepsize_controller=diffrax.PIDController(
            rtol=1e-9, atol=1e-11, jump_ts=jnp.array([REF.T_FAULT, REF.T_CLEAR])
        ),
        max_steps=1024,
    )
    return sol.ys[-1, 0, 0]


_angle_and_gradient_of = jax.jit(
    jax.value_and_grad(_angle_at_1s_of), static_argnames=("model", "name")
)


@pytest.mark.parametrize(
    ("model", "name"), [("GENSAL", "xq"), ("GENSAE", "S12"), ("GENROE", "S10")]
)
def test_new_machine_gradient_matches_finite_differences(model, name):
    """d delta(1 s) / d(one parameter) through the fault, init included, reverse mode
    through diffrax, against a central difference: Xq (GENSAL's q axis), S12 and S10
    (the exponential saturation of GENSAE and GENROE)."""
    p0 = float(np.asarray(getattr(_three_models()[model], name))[0])
    eps = 1e-4 * p0
    g = float(_angle_and_gradient_of(jnp.asarray(p0), model=model, name=name)[1])
    up, down = (
        _angle_and_gradient_of(jnp.asarray(p0 + e), model=model, name=name)[0]
        for e in (eps, -eps)
    )
    fd = float((up - down) / (2 * eps))
    assert abs(g) > 1e-4, g  # the angle does depend on it
    np.testing.assert_allclose(g, fd, rtol=1e-5)


def test_new_machines_start_at_rest_in_a_real_case(tmp_path):
    """Nordic 44 (ANDES's N44_BC files, built in as `nordic44`) with every other
    GENSAL written as GENSAE and every other GENROU as GENROE (the same CONs): 80
    machines of the four models, saturation on (S10 > 0 on every record), the
    controllers smibjax lacks skipped. Every state derivative at t = 0 is below
    1e-8 (measured 1.5e-14 with GENSAL/GENROU only)."""
    import re
    import warnings

    from smibjax.grid.case import case_files, load_case
    from smibjax.grid.loop import evaluate, state_labels
    from smibjax.grid.network import stage_configs, stage_matrices
    from smibjax.grid.operating import operating_point

    raw, dyr = case_files("nordic44")
    seen = {"GENSAL": 0, "GENROU": 0}

    def swap(m):
        seen[m.group(1)] += 1
        if seen[m.group(1)] % 2:
            return m.group(0)
        return {"GENSAL": "'GENSAE'", "GENROU": "'GENROE'"}[m.group(1)]

    text = re.sub(r"'(GENSAL|GENROU)'", swap, dyr.read_text())
    path = tmp_path / "n44_mixed.dyr"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the skipped controllers
        case = load_case(raw, path, skip_unsupported=True)
    names = sorted(type(m).__name__ for m in case.machines)
    assert names == ["GENROE", "GENROU", "GENSAE", "GENSAL"]
    assert sum(len(m.gen) for m in case.machines) == 80
    op, _ = operating_point(case)

    @jax.jit
    def at_rest(op):
        mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
        return evaluate(case, op, mats, 0, op.y0)[0]

    dy = np.asarray(at_rest(op))
    worst = int(np.argmax(np.abs(dy)))
    assert np.abs(dy).max() < 1e-8, state_labels(case)[worst]
