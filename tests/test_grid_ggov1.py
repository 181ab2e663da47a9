"""GGOV1 (smibjax.grid.devices.ggov1) against its equilibrium, closed-form limit
responses, an independent integration (SciPy's DOP853) of PSS/E's block diagram
written out below in NumPy, central differences, and a case at rest."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from smibjax._validate import ParameterError
from smibjax.grid.devices.ggov1 import DELT, GGOV1
from test_grid_controls import _solve

NAMES = GGOV1.con_names
# ACTIVSg2000's GGOV1 at bus 1048 (NREL-Sienna/PowerSystemsTestData)
ACTIVS = dict(
    zip(
        ("Rselect", "Flag", *NAMES),
        [1, 1, 0.04, 1, 0.05, -0.05, 10, 2, 0, 1, 1, 0.15, 0.1289, 1.3041, 0.2, 0.5]
        + [0, 0, 3, 1, 1, 1, 0, 0.1, -0.1, 0, 0.01, 10, 0.1, 390.24, 0, 4, 5, 99, -99],
        strict=True,
    )
)


def _dev(*recs, mbase=400.0):
    return GGOV1.from_params(
        list(range(len(recs))), [{**ACTIVS, "MBASE": mbase, **r} for r in recs]
    )


# every flag and optional block, one device each
VARIANTS = [
    {},
    {"Rselect": 0, "R": 0.0, "Flag": 0, "Trate": 0.0},
    {"Rselect": -1, "Kdgov": 0.5, "Tdgov": 0.2, "Kimw": 0.05, "db": 0.001},
    {"Rselect": -2, "Dm": -0.5, "Tc": 0.2, "Tb": 0.4, "Kpgov": 0.0, "Kigov": 1.5},
    {"Dm": 0.3, "Tpelec": 0.0, "Tb": 0.0, "Tsa": 0.0, "Tsb": 0.0, "Ka": 0.0},
    {"Tfload": 0.0, "Flag": 0, "Kpload": 2.0, "Kiload": 0.67, "Trate": 600.0},
]


def _meas(omega, pe):
    return {"omega": jnp.asarray(omega, float), "Pe": jnp.asarray(pe, float)}


def test_init_is_an_exact_equilibrium_for_every_flag():
    dev = _dev(*VARIANTS)
    k = len(VARIANTS)
    y0 = np.linspace(0.3, 0.8, k)
    meas = _meas(np.linspace(-2e-3, 2e-3, k), y0 * 0.98)
    x0, ref = dev.init(jnp.asarray(y0), meas)
    assert x0.shape == (len(GGOV1.state_names), k) and ref.shape == (6, k)
    assert float(jnp.max(jnp.abs(dev.rhs(x0, meas, ref)))) < 1e-12
    np.testing.assert_allclose(dev.out(x0, meas, ref), y0, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# PSS/E's GGOV1 block diagram written out independently (NumPy, one device), for
# SciPy's DOP853. States: the transducer, the Kimw integrator, the derivative
# filter, the PID integrator, the gate output one step back, the acceleration
# filter, the valve stroke, the turbine lead-lag, the temperature lead-lag, the
# temperature lag, the load limiter integrator.


def _psse_ggov1(p, mbase, pm0, pe_of, w_of):
    trate = p["Trate"] or mbase
    k = mbase / trate  # machine base -> turbine base
    w0, pe0 = w_of(0.0), pe_of(0.0) * k
    spd0 = 1 + w0 if p["Flag"] == 1 else 1.0
    pt0 = pm0 * k + (p["Dm"] * w0 if p["Dm"] > 0 else 0.0)
    wf0 = pt0 / p["Kturb"] + p["Wfnl"]
    s0 = wf0 / spd0
    t0 = wf0 * ((1 + w0) ** p["Dm"] if p["Dm"] < 0 else 1.0)
    fb0 = {1: pe0, 0: 0.0, -1: s0, -2: s0}[p["Rselect"]]
    pref, pmwset = w0 + p["R"] * fb0, pe0
    kt = p["Kturb"]
    x0 = np.array([pe0, 0, 0, s0, s0, w0, s0, kt * (wf0 - p["Wfnl"]), t0, t0, s0])

    def lagd(x, u, T):  # (y, dx) of 1/(1 + sT)
        return (x, (u - x) / T) if T > 0 else (u, 0.0)

    def leadlagd(x, u, a, b):  # (1 + s a)/(1 + s b)
        return (x + a / b * (u - x), (u - x) / b) if b > 0 else (u, 0.0)

    def parts(t, x):
        w, pe_in = w_of(t), pe_of(t) * k
        pe, dpe = lagd(x[0], pe_in, p["Tpelec"])
        dmw = p["Kimw"] * (pmwset - pe)
        if (x[1] >= 1.1 * p["R"] and dmw > 0) or (x[1] <= -1.1 * p["R"] and dmw < 0):
            dmw = 0.0
        fb = {1: pe, 0: 0.0, -1: x[4], -2: x[6]}[p["Rselect"]]
        err = pref + x[1] - w - p["R"] * fb
        db = p["db"]
        err = err - db if err > db else (err + db if err < -db else 0.0)
        e = min(max(err, p["minerr"]), p["maxerr"])
        if p["Tdgov"] > 0:
            yd, dd = p["Kdgov"] / p["Tdgov"] * (e - x[2]), (e - x[2]) / p["Tdgov"]
        else:
            yd, dd = 0.0, 0.0
        fsrn = p["Kpgov"] * e + x[3] + yd
        accel = (w - x[5]) / p["Ta"] if p["Ta"] > 0 else 0.0
        fsra = x[4] + p["Ka"] * DELT * (p["Aset"] - accel) if p["Ka"] > 0 else np.inf
        spd = 1 + w if p["Flag"] == 1 else 1.0
        wf = x[6] * spd
        tin = wf * ((1 + w) ** p["Dm"] if p["Dm"] < 0 else 1.0)
        yts, dts = leadlagd(x[8], tin, p["Tsa"], p["Tsb"])
        texm, dtf = lagd(x[9], yts, p["Tfload"])
        fsrt = min(x[10] + p["Kpload"] * (p["Ldref"] / kt + p["Wfnl"] - texm), 1.0)
        fsr = min(max(min(fsrn, fsrt, fsra), p["Vmin"]), p["Vmax"])
        if p["Kpgov"] > 0:
            di = p["Kigov"] / p["Kpgov"] * (fsr - x[3])
        else:
            di = p["Kigov"] * e
        dl = min(max(p["Kiload"] / p["Kpload"] * (fsr - x[10]), p["Rdown"]), p["Rup"])
        dstroke = min(max((fsr - x[6]) / p["Tact"], p["Rclose"]), p["Ropen"])
        ytb, dtb = leadlagd(x[7], kt * (wf - p["Wfnl"]), p["Tc"], p["Tb"])
        pm = (ytb - (p["Dm"] * w if p["Dm"] > 0 else 0.0)) / k
        dw = accel
        dx = [dpe, dmw, dd, di, (fsr - x[4]) / DELT, dw, dstroke, dtb, dts, dtf, dl]
        return pm, np.array(dx), (fsrn, fsrt, fsra)

    return x0, parts


def _scipy(p, mbase, pm0, pe_of, w_of, ts):
    x0, parts = _psse_ggov1(p, mbase, pm0, pe_of, w_of)
    sol = solve_ivp(
        lambda t, x: parts(t, x)[1],
        (ts[0], ts[-1]),
        x0,
        method="DOP853",
        t_eval=ts,
        rtol=1e-10,
        atol=1e-12,
        max_step=0.05,
    )
    assert sol.success
    out = np.array([parts(t, x)[0] for t, x in zip(sol.t, sol.y.T, strict=True)])
    gates = np.array([parts(t, x)[2] for t, x in zip(sol.t, sol.y.T, strict=True)])
    return out, sol.y.T, gates


def _clip(t, lo, hi):
    return (jnp if isinstance(t, jax.Array) else np).clip(t, lo, hi)


# the disturbances: the speed and the electrical power (machine base) as functions
# of t; each scenario drives one device
SCENARIOS = {
    # a small underspeed: the PID in control, linear
    "pid": ({}, lambda t: -0.002 * (t > 0.5), lambda t: 0.7 + 0.05 * (t > 0.5)),
    # a 4% overspeed: the error limit and the closing rate bind, the stroke ramps
    # down to Vmin
    "close": ({"Rclose": -0.2}, lambda t: 0.04 * (t > 0.2), lambda t: 0.7 + 0 * t),
    # the speed ramps up at 0.05 pu/s for 1 s: the acceleration limiter takes over
    "accel": (
        {"Kpgov": 20.0},
        lambda t: 0.05 * _clip(t - 0.5, 0.0, 1.0) - 0.06 * (t > 0.5),
        lambda t: 0.7 + 0 * t,
    ),
    # an 8% underspeed with a low load reference: the load limiter takes over
    "load": (
        {"Ldref": 0.85, "Ropen": 1.0},
        lambda t: -0.08 * (t > 0.2),
        lambda t: 0.7 + 0 * t,
    ),
    # the other feedback signals, fuel flow and temperature options
    "flags": (
        VARIANTS[3] | {"Kimw": 0.2},
        lambda t: -0.003 * (t > 0.5),
        lambda t: 0.7 + 0.1 * (t > 0.5),
    ),
    "flags2": (
        VARIANTS[2],
        lambda t: 0.004 * (t > 0.5),
        lambda t: 0.7 - 0.1 * (t > 0.5),
    ),
}


@functools.cache
def _runs():
    """Every scenario as one device of one group (one compile), and each through
    SciPy."""
    ts = np.linspace(0.0, 6.0, 121)
    mbase, pm0 = 400.0, 0.7
    scen = list(SCENARIOS.values())
    dev = _dev(*(over for over, _, _ in scen), mbase=mbase)

    def m(t):
        return {
            "omega": jnp.stack([jnp.asarray(w(t), float) for _, w, _ in scen]),
            "Pe": jnp.stack([jnp.asarray(pe(t), float) for _, _, pe in scen]),
        }

    x0, r = dev.init(jnp.full(len(scen), pm0), m(0.0))
    out, xs = _solve({"g": (dev, x0, r, m)}, ts, (0.2, 0.5, 1.5))["g"]
    res = {n: (out[:, k], xs[:, :, k]) for k, n in enumerate(SCENARIOS)}
    ref = {
        n: _scipy({**ACTIVS, **over}, mbase, pm0, pe_of, w_of, ts)
        for n, (over, w_of, pe_of) in SCENARIOS.items()
    }
    return ts, res, ref


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_against_an_independent_integration_of_the_block_diagram(name):
    """smibjax's GGOV1 (diffrax Tsit5) and the diagram above (SciPy DOP853) agree on
    Pm to 1e-6 pu over 6 s; each scenario moves Pm and puts the control it names in
    charge of the gate."""
    ts, res, ref = _runs()
    out, xs = res[name]
    want, xs_ref, gates = ref[name]
    assert np.ptp(want) > 0.01
    np.testing.assert_allclose(out, want, rtol=0, atol=1e-6)
    np.testing.assert_allclose(xs, xs_ref, rtol=0, atol=1e-6)
    fsrn, fsrt, fsra = gates.T
    which = {"pid": fsrn, "close": fsrn, "accel": fsra, "load": fsrt}
    if name in which:  # the named control is the gate's lowest input at some point
        assert np.any(which[name] <= np.minimum(np.minimum(fsrn, fsrt), fsra) + 1e-12)
        if name != "pid" and name != "close":
            assert np.any(which[name] < fsrn - 1e-3)


def test_valve_closes_at_rclose_down_to_vmin():
    """A 4% overspeed saturates the speed error at minerr: the PID asks Kpgov minerr
    = -0.5 below the stroke, so the valve closes at Rclose = -0.2 pu/s from 0.2 s,
    stroke = s0 - 0.2 (t - 0.2), with s0 = Pm0 (MBASE/Trate)/Kturb + Wfnl, and Pm
    (Tb = 0.5, Flag: the fuel flow is stroke (1 + omega)) follows the lag of the
    ramp."""
    ts, res, _ = _runs()
    _, xs = res["close"]
    s0 = 0.7 * 400 / 390.24 / 1.3041 + 0.2
    ramp = (ts >= 0.3) & (ts <= 2.8)  # until fsr - stroke < Tact Rclose
    np.testing.assert_allclose(xs[ramp, 6], s0 - 0.2 * (ts[ramp] - 0.2), atol=1e-7)
    assert abs(xs[-1, 6] - 0.15) < 1e-6  # held at Vmin


# ---------------------------------------------------------------------------
# gradient: d(Pm 2 s after a step)/d(parameter) against central differences

GRAD = ("Kpgov", "Kturb", "Tb", "Trate")


def _pm_after_step(values):
    """Pm 2 s after a step (speed -2e-3, Pe +0.05), device k with parameter GRAD[k]
    set to values[k]: one group (a device per parameter), a fixed-step RK4 (10 ms) in
    a lax.scan, cheap to compile; the gradient and the differences see the same
    discretization."""
    dev = _dev(VARIANTS[2], {}, {}, {})
    for k, n in enumerate(GRAD):
        dev = eqx.tree_at(
            lambda d, n=n: getattr(d, n),
            dev,
            jnp.asarray(getattr(dev, n), float).at[k].set(values[k]),
        )
    m0 = _meas(np.zeros(4), np.full(4, 0.7))
    m1 = _meas(np.full(4, -2e-3), np.full(4, 0.75))
    x0, r = dev.init(jnp.full(4, 0.7), m0)

    def step(x, _):
        h = 0.01
        k1 = dev.rhs(x, m1, r)
        k2 = dev.rhs(x + h / 2 * k1, m1, r)
        k3 = dev.rhs(x + h / 2 * k2, m1, r)
        k4 = dev.rhs(x + h * k3, m1, r)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), None

    x, _ = jax.lax.scan(step, x0, None, length=200)
    return dev.out(x, m1, r)


def test_gradients_match_central_differences():
    """Each device's Pm depends on its own parameter only: one forward-mode
    derivative along all four gives every d(Pm_k)/d(p_k), two evaluations at p0 +- h
    every central difference."""
    p0 = jnp.asarray(
        [VARIANTS[2].get("Kpgov", ACTIVS["Kpgov"])]
        + [float(ACTIVS[n]) for n in GRAD[1:]]
    )
    jvp = jax.jit(lambda p, t: jax.jvp(_pm_after_step, (p,), (t,)))
    _, dout = jvp(p0, jnp.ones_like(p0))
    h = 1e-4 * jnp.abs(p0)
    fd = (jvp(p0 + h, h)[0] - jvp(p0 - h, h)[0]) / (2 * h)
    for k, name in enumerate(GRAD):
        assert abs(float(fd[k])) > 1e-6, name
        assert float(dout[k]) == pytest.approx(float(fd[k]), rel=1e-5, abs=1e-10), name


# ---------------------------------------------------------------------------
# in a case: the MBASE that build_case passes, an exact equilibrium

KUNDUR_GGOV1 = """\
1 'GENROU' 1 8.0 0.03 0.4 0.05 6.5 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
1 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
1 'GGOV1' 1 1 1 0.04 1 0.05 -0.05 10 2 0 1 1 0.15 0.5 1.5 0.2 0.5 0 0 3 1 1 1 0
  0.1 -0.1 0 0.01 10 0.1 0 0 4 5 99 -99 /
2 'GENROU' 1 8.0 0.03 0.4 0.05 6.5 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
2 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
2 'GGOV1' 1 -1 0 0.05 1 0.05 -0.05 10 2 0.5 0.2 1 0.15 0.5 1.5 0.2 0.5 0.1 0 3 2
  0.67 1 -0.5 0.1 -0.1 0.1 0.01 10 0.1 1000 0.001 4 5 99 -99 /
3 'GENROU' 1 8.0 0.03 0.4 0.05 6.175 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
3 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
3 'GGOV1' 1 -2 1 0.04 0 0.05 -0.05 0 2 0 1 1 0.15 0.5 1.5 0.2 0 0 0 0 1 1 1 0.3
  0.1 -0.1 0 0.01 0 0.1 950 0 0 0 99 -99 /
4 'GENROU' 1 8.0 0.03 0.4 0.05 6.175 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
4 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
4 'GGOV1' 1 0 1 0 1 0.05 -0.05 10 2 0 1 1 0.15 0.5 1.5 0.2 0.5 0 0 3 1 1 1 0
  0.1 -0.1 0 0.01 10 0.1 0 0 4 5 99 -99 /
"""


def test_kundur_with_ggov1_starts_at_an_exact_equilibrium(tmp_path):
    """Kundur's four machines each with a GGOV1 (every Rselect, both Flags, Dm of
    both signs, Trate 0 and not): every derivative at t = 0 below 1e-8, Pm = Pm0, and
    each group received its machine's MBASE (900 MVA)."""
    from smibjax.grid.case import case_files, load_case
    from smibjax.grid.loop import evaluate, state_labels
    from smibjax.grid.network import stage_configs, stage_matrices
    from smibjax.grid.operating import operating_point

    dyr = tmp_path / "kundur_ggov1.dyr"
    dyr.write_text(KUNDUR_GGOV1)
    case = load_case(case_files("kundur")[0], dyr)
    (gov,) = [c for c in case.controllers if isinstance(c, GGOV1)]
    np.testing.assert_array_equal(gov.mbase, 900.0)
    np.testing.assert_array_equal(gov.Rselect, [1, -1, -2, 0])
    op, _ = operating_point(case)

    @jax.jit
    def at_rest(op):
        mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
        dy, meas, _ = evaluate(case, op, mats, 0, op.y0)
        return dy, meas

    dy, meas = at_rest(op)
    worst = int(np.argmax(np.abs(dy)))
    assert float(jnp.max(jnp.abs(dy))) < 1e-8, state_labels(case)[worst]
    pm0 = np.concatenate([np.asarray(h["Pm"]) for h in op.held])
    np.testing.assert_allclose(meas["Pm"], pm0, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize(
    "over,match",
    [
        ({"Teng": 0.1}, r"^GGOV1\.Teng = 0\.1 is not supported: only 0"),
        ({"Rselect": 2}, r"^GGOV1\.Rselect = \[2\] is not allowed: must be one of"),
        ({"Flag": -1}, r"^GGOV1\.Flag = \[-1\] is not allowed: must be one of 0, 1$"),
        ({"Tact": 0.0}, r"^GGOV1\.Tact = \[0\.\] is not allowed: must be > 0$"),
        ({"Kpload": 0.0}, r"^GGOV1\.Kpload = \[0\.\] is not allowed: must be > 0$"),
        ({"Tc": 0.3, "Tb": 0.0}, r"^GGOV1\.Tb = \[0\.\] is not allowed"),
        ({"Kdgov": 1.0, "Tdgov": 0.0}, r"^GGOV1\.Tdgov = \[0\.\] is not allowed"),
        ({"Vmin": 1.2}, r"^GGOV1\.Vmax = \[1\.\] is not allowed: must be >= Vmin$"),
        ({"Rclose": 0.1}, r"^GGOV1\.Rclose = \[0\.1\] is not allowed: must be <= 0"),
    ],
)
def test_bad_parameters_are_refused_in_one_line(over, match):
    with pytest.raises(ParameterError, match=match):
        _dev(over)


def test_limits_the_operating_point_lies_beyond_move_to_it():
    """Pm0 = 1.1 pu of MBASE is a stroke of 1.065 (Vmax = 1) and an exhaust
    temperature above the load reference Ldref/Kturb + Wfnl: the unit starts on
    the moved limits, at rest, and a 1% underspeed cannot open the valve further."""
    dev = _dev({})
    m = _meas([0.0], [1.1])
    x0, ref = dev.init(jnp.array([1.1]), m)
    s0 = 1.1 * 400 / 390.24 / 1.3041 + 0.2
    np.testing.assert_allclose(ref[3], s0, rtol=1e-14)  # Vmax in force
    np.testing.assert_allclose(ref[4], s0, rtol=1e-14)  # the load limiter's ceiling
    assert float(jnp.max(jnp.abs(dev.rhs(x0, m, ref)))) < 1e-12
    m1 = _meas([-0.01], [1.1])
    assert float(dev.rhs(x0, m1, ref)[6, 0]) == 0.0  # the stroke stays on Vmax
    with pytest.raises(ParameterError, match=r"^GGOV1\.Pm0 = \[-1\.\] is not allowed"):
        dev.init(jnp.array([-1.0]), _meas([0.0], [-1.0]))
