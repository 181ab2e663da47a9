"""The governors IEEEG1, HYGOV, IEESGO and the stabilizers ST2CUT, STAB2A, IEEEST's
full filter (smibjax.grid.devices) against their equilibria, their transfer
functions (linearized with jax.jacfwd), closed-form limit responses, central
differences, ANDES 2.0 (tests/data/controls/make_andes_govpss.py) and a real case
at rest."""

import functools
import json
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax._validate import ParameterError
from smibjax.grid.devices.gast import GAST
from smibjax.grid.devices.hygov import HYGOV
from smibjax.grid.devices.ieeeg1 import IEEEG1
from smibjax.grid.devices.ieeest import IEEEST
from smibjax.grid.devices.ieesgo import IEESGO
from smibjax.grid.devices.pss2 import PSS2A, PSS2B
from smibjax.grid.devices.st2cut import ST2CUT
from smibjax.grid.devices.stab2a import STAB2A
from test_grid_controls import _interp, _rel_err, _solve

DATA = Path(__file__).parent / "data" / "controls"
FIXTURE = DATA / "andes_kundur_govpss.json"
K = 8  # devices per random group


def _u(r, lo, hi, zero_frac=0.0):
    x = r.uniform(lo, hi, K)
    if zero_frac:
        x[r.uniform(size=K) < zero_frac] = 0.0
    return x


def _ieeeg1(r):
    t1 = _u(r, 0.05, 0.5, 0.3)
    return IEEEG1(
        np.arange(K),
        JBUS=np.zeros(K, int),
        M=np.zeros(K, int),
        K=_u(r, 10, 30),
        T1=t1,
        T2=np.where(t1 > 0, _u(r, 0.0, 1.0), 0.0),
        T3=_u(r, 0.05, 0.5),
        UO=_u(r, 0.1, 1.0),
        UC=-_u(r, 0.1, 1.0),
        PMAX=_u(r, 1.0, 1.2),
        PMIN=_u(r, 0.0, 0.1),
        T4=_u(r, 0.05, 0.5, 0.3),
        K1=_u(r, 0.5, 0.8),
        K2=_u(r, 0.0, 0.2, 0.5),
        T5=_u(r, 3.0, 10.0, 0.3),
        K3=_u(r, 0.1, 0.4),
        K4=_u(r, 0.0, 0.2, 0.5),
        T6=_u(r, 0.2, 1.0, 0.3),
        K5=_u(r, 0.0, 0.4, 0.3),
        K6=_u(r, 0.0, 0.2, 0.5),
        T7=_u(r, 0.0, 1.0, 0.5),
        K7=_u(r, 0.0, 0.2, 0.5),
        K8=_u(r, 0.0, 0.2, 0.5),
    )


def _hygov(r):
    return HYGOV(
        np.arange(K),
        R=_u(r, 0.03, 0.08),
        r=_u(r, 0.2, 0.5),
        Tr=_u(r, 2.0, 8.0),
        Tf=_u(r, 0.02, 0.1),
        Tg=_u(r, 0.1, 0.5),
        VELM=_u(r, 0.1, 0.3),
        GMAX=_u(r, 1.0, 1.1),
        GMIN=_u(r, 0.0, 0.1),
        TW=_u(r, 0.5, 2.0),
        At=_u(r, 1.0, 1.3),
        Dturb=_u(r, 0.0, 0.5, 0.3),
        qNL=_u(r, 0.05, 0.15),
    )


def _ieesgo(r):
    t3 = _u(r, 0.1, 0.3, 0.3)
    return IEESGO(
        np.arange(K),
        T1=_u(r, 0.01, 0.3, 0.3),
        T2=np.where(t3 > 0, _u(r, 0.0, 0.1), 0.0),
        T3=t3,
        T4=_u(r, 0.1, 0.5, 0.3),
        T5=_u(r, 3.0, 10.0, 0.3),
        T6=_u(r, 0.2, 1.0, 0.3),
        K1=_u(r, 10, 30),
        K2=_u(r, 0.3, 0.8),
        K3=_u(r, 0.2, 0.6),
        PMAX=_u(r, 1.0, 1.2),
        PMIN=_u(r, 0.0, 0.1),
    )


def _gast(r):
    return GAST(
        np.arange(K),
        R=_u(r, 0.03, 0.08),
        T1=_u(r, 0.1, 0.5),
        T2=_u(r, 0.05, 0.5),
        T3=_u(r, 1.0, 5.0),
        AT=_u(r, 1.0, 1.2),
        KT=_u(r, 1.0, 3.0),
        VMAX=_u(r, 1.0, 1.2),
        VMIN=_u(r, -0.1, 0.0),
        Dturb=_u(r, 0.0, 0.5, 0.3),
    )


def _st2cut(r):
    t6, t8, t10 = (_u(r, 0.02, 0.1, 0.3) for _ in range(3))
    return ST2CUT(
        np.arange(K),
        ICS1=r.choice([0, 1, 3, 5], K),
        IB1=np.zeros(K, int),
        ICS2=r.choice([0, 1, 3], K),
        IB2=r.choice([0, 7], K),  # ignored for ICS 0, 1, 3
        K1=_u(r, -20, 20),
        K2=_u(r, -2, 2),
        T1=_u(r, 0.01, 0.05, 0.4),
        T2=_u(r, 0.01, 0.05, 0.4),
        T3=_u(r, 1.0, 10.0),
        T4=_u(r, 1.0, 10.0),
        T5=np.where(t6 > 0, _u(r, 0.05, 0.5), 0.0),
        T6=t6,
        T7=np.where(t8 > 0, _u(r, 0.05, 0.5), 0.0),
        T8=t8,
        T9=np.where(t10 > 0, _u(r, 0.05, 0.5), 0.0),
        T10=t10,
        LSMAX=np.full(K, 10.0),
        LSMIN=np.full(K, -10.0),
        VCU=np.zeros(K),
        VCL=np.zeros(K),
    )


def _stab2a(r):
    return STAB2A(
        np.arange(K),
        K2=_u(r, 0.5, 2.0),
        T2=_u(r, 1.0, 5.0),
        K3=_u(r, 0.0, 1.0, 0.3),
        T3=_u(r, 0.5, 3.0, 0.3),
        K4=_u(r, 0.05, 1.0),
        K5=_u(r, 0.5, 2.0),
        T5=_u(r, 0.01, 0.05, 0.3),
        HLIM=np.full(K, 10.0),
    )


def _meas(r):
    return {
        "omega": jnp.asarray(_u(r, -1e-3, 1e-3)),
        "Pe": jnp.asarray(_u(r, 0.2, 0.9)),
        "Vt": jnp.asarray(_u(r, 0.95, 1.05)),
    }


MODELS = {
    "IEEEG1": (_ieeeg1, lambda r: _u(r, 0.3, 0.6)),
    "HYGOV": (_hygov, lambda r: _u(r, 0.3, 0.8)),
    "IEESGO": (_ieesgo, lambda r: _u(r, 0.3, 0.9)),
    "GAST": (_gast, lambda r: _u(r, 0.3, 0.8)),
    "ST2CUT": (_st2cut, lambda r: np.zeros(K)),
    "STAB2A": (_stab2a, lambda r: np.zeros(K)),
}


@pytest.mark.parametrize("name", list(MODELS))
def test_init_is_an_equilibrium(name):
    make, y0f = MODELS[name]
    r = np.random.default_rng(1)
    dev, y0, meas = make(r), y0f(r), _meas(r)
    x0, ref = dev.init(jnp.asarray(y0), meas)
    assert x0.shape == (len(dev.state_names), K)
    assert float(jnp.max(jnp.abs(dev.rhs(x0, meas, ref)))) < 1e-12
    np.testing.assert_allclose(dev.out(x0, meas, ref), y0, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# transfer functions: C (jw I - A)^-1 B + D from jax.jacfwd at rest, against the
# block diagram's transfer function evaluated directly


def _frequency_response(dev, meas, y0, key, ws):
    """H(jw) per device from input `key` to the output, linearized at rest."""
    x0, ref = dev.init(jnp.asarray(y0), meas)

    @jax.jit
    def lin(x0, u0):
        def m(u):
            return {**meas, key: u}

        return (
            jax.jacfwd(lambda x: dev.rhs(x, m(u0), ref))(x0),
            jax.jacfwd(lambda u: dev.rhs(x0, m(u), ref))(u0),
            jax.jacfwd(lambda x: dev.out(x, m(u0), ref))(x0),
            jax.jacfwd(lambda u: dev.out(x0, m(u), ref))(u0),
        )

    A, B, C, D = (np.asarray(a) for a in lin(x0, meas[key]))
    n, k = x0.shape
    out = np.zeros((k, len(ws)), complex)
    for i in range(k):
        Ai, Bi, Ci, Di = A[:, i, :, i], B[:, i, i], C[i, :, i], D[i, i]
        for j, w in enumerate(ws):
            out[i, j] = Ci @ np.linalg.solve(1j * w * np.eye(n) - Ai, Bi) + Di
    return out


WS = np.array([0.05, 0.3, 1.0, 4.0, 20.0, 100.0])


def _p(dev, i):
    return {f: float(np.asarray(getattr(dev, f))[i]) for f in dev.con_names}


def _lag(s, T):
    return 1.0 / (1.0 + s * T)


def _ll(s, a, b):
    return (1.0 + s * a) / (1.0 + s * b)


def _assert_tf(h, want):
    np.testing.assert_allclose(h, want, rtol=1e-9, atol=1e-12)


def test_ieeeg1_transfer_function():
    """-K (1 + s T2)/(1 + s T1) / (1 + s T3) (K1 L4 + K3 L4 L5 + K5 L4 L5 L6 + K7 L4
    L5 L6 L7) from speed to the machine's power: the LP fractions K2, K4, K6, K8 do
    not reach it (no second machine)."""
    r = np.random.default_rng(2)
    dev, y0, meas = _ieeeg1(r), _u(r, 0.3, 0.6), _meas(r)
    h = _frequency_response(dev, meas, y0, "omega", WS)
    s = 1j * WS
    for i in range(K):
        p = _p(dev, i)
        L4, L5 = _lag(s, p["T4"]), _lag(s, p["T5"])
        L6, L7 = _lag(s, p["T6"]), _lag(s, p["T7"])
        stages = p["K1"] * L4 + p["K3"] * L4 * L5 + p["K5"] * L4 * L5 * L6
        stages = stages + p["K7"] * L4 * L5 * L6 * L7
        want = -p["K"] * _ll(s, p["T2"], p["T1"]) * _lag(s, p["T3"]) * stages
        _assert_tf(h[i], want)


def test_ieesgo_transfer_function():
    """-K1 (1 + s T2)/((1 + s T1)(1 + s T3)) / (1 + s T4) ((1 - K2) + (1 - K3) K2 L5
    + K3 K2 L5 L6)."""
    r = np.random.default_rng(3)
    dev, y0, meas = _ieesgo(r), _u(r, 0.3, 0.9), _meas(r)
    h = _frequency_response(dev, meas, y0, "omega", WS)
    s = 1j * WS
    for i in range(K):
        p = _p(dev, i)
        L5, L6 = _lag(s, p["T5"]), _lag(s, p["T6"])
        turb = (
            (1 - p["K2"]) + (1 - p["K3"]) * p["K2"] * L5 + p["K3"] * p["K2"] * L5 * L6
        )
        gov = -p["K1"] * _ll(s, p["T2"], p["T3"]) * _lag(s, p["T1"])
        _assert_tf(h[i], gov * _lag(s, p["T4"]) * turb)


def test_gast_transfer_function_below_the_load_limit():
    """-(1/R)/((1 + s T1)(1 + s T2)) - Dturb: the low-value gate passes the speed
    governor while the operating point is below AT, and x3 then reaches nothing."""
    r = np.random.default_rng(12)
    dev, y0, meas = _gast(r), _u(r, 0.3, 0.8), _meas(r)
    h = _frequency_response(dev, meas, y0, "omega", WS)
    s = 1j * WS
    for i in range(K):
        p = _p(dev, i)
        want = -1 / p["R"] * _lag(s, p["T1"]) * _lag(s, p["T2"]) - p["Dturb"]
        _assert_tf(h[i], want)


def test_hygov_transfer_function_is_the_linearized_water_column():
    """At rest (h = 1, q0 = g0): dc = -G/(1 + R G) domega with G = (1 + s Tr)/(r Tr s
    (1 + s Tf)); dg = dc/(1 + s Tg); the penstock gives dh = -2 TW s dg/(q0 TW s +
    2), dq = 2 dg/(q0 TW s + 2); dPm = At ((q0 - qNL) dh + dq) - Dturb g0 domega
    (the non-minimum-phase water hammer), at omega0 = 0."""
    r = np.random.default_rng(4)
    dev, y0, meas = _hygov(r), _u(r, 0.3, 0.8), _meas(r)
    meas = {**meas, "omega": jnp.zeros(K)}
    h = _frequency_response(dev, meas, y0, "omega", WS)
    s = 1j * WS
    for i in range(K):
        p = _p(dev, i)
        q0 = y0[i] / p["At"] + p["qNL"]
        G = (1 + s * p["Tr"]) / (p["r"] * p["Tr"] * s * (1 + s * p["Tf"]))
        dg = -G / (1 + p["R"] * G) * _lag(s, p["Tg"])
        dh = -2 * p["TW"] * s * dg / (q0 * p["TW"] * s + 2)
        dq = 2 * dg / (q0 * p["TW"] * s + 2)
        want = p["At"] * ((q0 - p["qNL"]) * dh + dq) - p["Dturb"] * q0
        _assert_tf(h[i], want)


@pytest.mark.parametrize("key,code", [("omega", 1), ("Pe", 3), ("Vt", 5)])
def test_st2cut_transfer_functions_of_both_inputs(key, code):
    """Vs = (K1/(1 + s T1) u1 + K2/(1 + s T2) u2) s T3/(1 + s T4) (1 + s T5)/(1 + s
    T6) (1 + s T7)/(1 + s T8) (1 + s T9)/(1 + s T10), each input by its code."""
    r = np.random.default_rng(5 + code)
    dev, meas = _st2cut(r), _meas(r)
    h = _frequency_response(dev, meas, np.zeros(K), key, WS)
    s = 1j * WS
    ics1, ics2 = np.asarray(dev.ICS1), np.asarray(dev.ICS2)
    assert (ics1 == code).any() and (ics2 != code).any()
    for i in range(K):
        p = _p(dev, i)
        gain = (ics1[i] == code) * p["K1"] * _lag(s, p["T1"]) + (ics2[i] == code) * p[
            "K2"
        ] * _lag(s, p["T2"])
        rest = s * p["T3"] * _lag(s, p["T4"]) * _ll(s, p["T5"], p["T6"])
        rest = rest * _ll(s, p["T7"], p["T8"]) * _ll(s, p["T9"], p["T10"])
        _assert_tf(h[i], gain * rest)


def test_stab2a_transfer_function():
    """-(K2 s T2/(1 + s T2))^3 (K3/(1 + s T3) + K4) K5^2/(1 + s T5)^2 from Pe."""
    r = np.random.default_rng(9)
    dev, meas = _stab2a(r), _meas(r)
    h = _frequency_response(dev, meas, np.zeros(K), "Pe", WS)
    s = 1j * WS
    for i in range(K):
        p = _p(dev, i)
        w = p["K2"] * s * p["T2"] * _lag(s, p["T2"])
        mid = p["K3"] * _lag(s, p["T3"]) + p["K4"]
        _assert_tf(h[i], -(w**3) * mid * (p["K5"] * _lag(s, p["T5"])) ** 2)


def _ieeest_full(A):
    """IEEEST groups with the filter coefficients A (6, n) and neutral rest."""
    n = A.shape[1]
    z = np.zeros(n)
    return IEEEST(
        np.arange(n),
        ICS=np.ones(n, int),
        IB=np.zeros(n, int),
        **{f"A{i + 1}": A[i] for i in range(6)},
        T1=np.full(n, 0.2),
        T2=np.full(n, 0.05),
        T3=z,
        T4=z,
        T5=np.full(n, 2.0),
        T6=np.full(n, 2.0),
        KS=np.full(n, 10.0),
        LSMAX=np.full(n, 10.0),
        LSMIN=np.full(n, -10.0),
        VCU=z,
        VCL=z,
    )


# columns: A1..A6 per device. 0: A3 = A4 = 0 under a second-order numerator (the
# refused PSS/E data of issue 45), 1: the same with a first-order numerator, 2: two
# first-order factors under a second-order numerator, 3: the drawn order (A4 > 0)
IEEEST_A = np.array(
    [
        [0.05, 0.001, 0.0, 0.0, 0.02, 0.0003],
        [0.05, 0.001, 0.0, 0.0, 0.02, 0.0],
        [0.05, 0.0, 0.03, 0.0, 0.02, 0.0004],
        [0.05, 0.0, 0.03, 0.0004, 0.02, 0.0002],
    ]
).T


def test_ieeest_full_filter_with_a3_a4_zero_is_its_transfer_function():
    """(1 + A5 s + A6 s^2)/((1 + A1 s + A2 s^2)(1 + A3 s + A4 s^2)) whatever factor
    carries the poles; then (1 + s T1)/(1 + s T2), KS s T5/(1 + s T6)."""
    dev = _ieeest_full(IEEEST_A)
    n = IEEEST_A.shape[1]
    meas = {"omega": jnp.full(n, 1e-3), "Pe": jnp.zeros(n), "Vt": jnp.ones(n)}
    h = _frequency_response(dev, meas, np.zeros(n), "omega", WS)
    s = 1j * WS
    for i in range(n):
        a = IEEEST_A[:, i]
        F = (1 + a[4] * s + a[5] * s**2) / (
            (1 + a[0] * s + a[1] * s**2) * (1 + a[2] * s + a[3] * s**2)
        )
        _assert_tf(h[i], F * _ll(s, 0.2, 0.05) * 10.0 * s * 2.0 * _lag(s, 2.0))


def test_ieeest_refuses_only_an_improper_filter():
    """The whole denominator must be of degree >= the numerator's: A6 != 0 needs
    degree 2 (from either factor or both), A5 != 0 degree 1."""
    bad = IEEEST_A[:, :1].copy()
    bad[:4] = [[0.05], [0.0], [0.0], [0.0]]  # degree 1 under A6 != 0
    with pytest.raises(ParameterError, match=r"^IEEEST\.A6 = \[0\.0003\] is not allo"):
        _ieeest_full(bad)
    bad[:4] = 0.0
    bad[5] = 0.0  # degree 0 under A5 != 0
    with pytest.raises(ParameterError, match=r"^IEEEST\.A5 = \[0\.02\] is not allowed"):
        _ieeest_full(bad)


def test_ieeest_remote_bus_is_ignored_for_speed_and_power():
    """IB names the bus of a bus signal (ICS 2, 5, 6): with ICS 1 or 3 PSS/E reads
    it and ignores it, so IB = 7 loads and gives IB = 0's output."""
    a = _ieeest_full(IEEEST_A)
    b = eqx.tree_at(lambda d: d.IB, a, np.full(4, 7))
    IEEEST(**{f: getattr(b, f) for f in ("gen", "ICS", "IB", *IEEEST.con_names)})
    meas = {"omega": jnp.full(4, 1e-3), "Pe": jnp.zeros(4), "Vt": jnp.ones(4)}
    x0, ref = a.init(jnp.zeros(4), meas)
    m1 = {**meas, "omega": jnp.full(4, 2e-3)}
    np.testing.assert_array_equal(a.out(x0, m1, ref), b.out(x0, m1, ref))
    assert float(jnp.max(jnp.abs(a.out(x0, m1, ref)))) > 0


# ---------------------------------------------------------------------------
# PSS2A, PSS2B (not in ANDES): transfer functions of IEEE 421.5's diagram


def _pss2(cls, r, n=K):
    def u(lo, hi, z=0.0):
        x = r.uniform(lo, hi, n)
        x[r.uniform(size=n) < z] = 0.0
        return x

    t2, t4 = u(0.02, 0.1, 0.3), u(0.02, 0.1, 0.3)
    M = r.integers(0, 6, n)
    N = np.where(M > 0, r.integers(1, 9, n) // np.maximum(M, 1), r.integers(0, 3, n))
    N = np.minimum(N, 8 // np.maximum(M, 1))
    p = dict(
        ICS1=np.ones(n, int),
        IB1=np.zeros(n, int),
        ICS2=np.full(n, 3),
        IB2=np.zeros(n, int),
        M=M,
        N=N,
        TW1=u(1.0, 10.0),
        TW2=u(1.0, 10.0, 0.3),
        T6=u(0.0, 0.05, 0.3),
        TW3=u(1.0, 10.0),
        TW4=u(1.0, 10.0, 0.3),
        T7=u(1.0, 10.0, 0.2),
        KS2=u(0.1, 1.0),
        KS3=u(0.5, 1.5),
        T8=u(0.2, 0.6),
        T9=u(0.05, 0.2),
        KS1=u(5.0, 20.0),
        T1=np.where(t2 > 0, u(0.1, 0.3), 0.0),
        T2=t2,
        T3=np.where(t4 > 0, u(0.1, 0.3), 0.0),
        T4=t4,
        VSTMAX=np.full(n, 10.0),
        VSTMIN=np.full(n, -10.0),
    )
    if cls is PSS2B:
        t11 = u(0.02, 0.1, 0.3)
        p.update(
            T10=np.where(t11 > 0, u(0.1, 0.3), 0.0),
            T11=t11,
            VS1MAX=np.full(n, 10.0),
            VS1MIN=np.full(n, -10.0),
            VS2MAX=np.full(n, 10.0),
            VS2MIN=np.full(n, -10.0),
        )
    return cls(np.arange(n), **p)


def _wo(s, T):
    return s * T * _lag(s, T) if T > 0 else 1.0


@pytest.mark.parametrize("cls", [PSS2A, PSS2B])
@pytest.mark.parametrize("key", ["omega", "Pe"])
def test_pss2_transfer_functions_of_both_channels(cls, key):
    """From speed (channel 1): KS1 R(s) W1 W2/(1 + s T6) LL; from power (channel 2):
    KS1 (KS3 R(s) - 1) W3 W4 KS2/(1 + s T7) LL, with R(s) = [(1 + s T8)/(1 + s
    T9)^M]^N (1 where M N = 0), Wi = s TWi/(1 + s TWi) (1 where TWi = 0 for the
    second washouts), LL the lead-lags (1 + s T1)/(1 + s T2) (1 + s T3)/(1 + s T4)
    [PSS2B: (1 + s T10)/(1 + s T11)] (IEEE Std 421.5-2005, PSS2A/PSS2B)."""
    r = np.random.default_rng(21)
    dev, meas = _pss2(cls, r), _meas(r)
    assert (np.asarray(dev.M) * np.asarray(dev.N) == 0).any()
    assert (np.asarray(dev.M) * np.asarray(dev.N) > 1).any()
    h = _frequency_response(dev, meas, np.zeros(K), key, WS)
    s = 1j * WS
    for i in range(K):
        p = {
            f: float(np.asarray(getattr(dev, f))[i]) for f in ("M", "N", *dev.con_names)
        }
        M, N = int(p["M"]), int(p["N"])
        R = ((1 + s * p["T8"]) * _lag(s, p["T9"]) ** M) ** N if M * N else 1.0
        LL = _ll(s, p["T1"], p["T2"]) * _ll(s, p["T3"], p["T4"])
        if cls is PSS2B:
            LL = LL * _ll(s, p["T10"], p["T11"])
        if key == "omega":
            ch = R * _wo(s, p["TW1"]) * _wo(s, p["TW2"]) * _lag(s, p["T6"])
        else:
            ch = (p["KS3"] * R - 1) * _wo(s, p["TW3"]) * _wo(s, p["TW4"])
            ch = ch * p["KS2"] * _lag(s, p["T7"])
        _assert_tf(h[i], p["KS1"] * ch * LL)


def test_pss2b_input_limits_clip_the_signal():
    """PSS2B's input limits: a speed beyond VS1MAX reaches the washouts clipped (the
    first washout's derivative is (clip(u) - x)/TW1)."""
    r = np.random.default_rng(22)
    dev = _pss2(PSS2B, r, n=1)
    dev = eqx.tree_at(
        lambda d: (d.VS1MAX, d.VS1MIN), dev, (np.array([0.01]), np.array([-0.01]))
    )
    meas = {"omega": jnp.zeros(1), "Pe": jnp.full(1, 0.5), "Vt": jnp.ones(1)}
    x0, ref = dev.init(jnp.zeros(1), meas)
    big = {**meas, "omega": jnp.full(1, 0.05)}
    d = dev.rhs(x0, big, ref)
    assert float(d[0, 0]) == pytest.approx(0.01 / float(dev.TW1[0]), rel=1e-12)


# ---------------------------------------------------------------------------
# limits against closed forms


@functools.cache
def _limit_runs():
    ts = np.linspace(0.0, 20.0, 201)
    g1 = IEEEG1(
        [0, 1],
        JBUS=[0, 0],
        M=[0, 0],
        K=[20.0, 20.0],
        T1=[0.0, 0.0],
        T2=[0.0, 0.0],
        T3=[0.1, 0.1],
        UO=[0.1, 10.0],
        UC=[-0.2, -10.0],
        PMAX=[0.9, 0.9],
        PMIN=[0.0, 0.0],
        T4=[0.0, 0.0],
        K1=[1.0, 1.0],
        **{f"K{i}": [0.0, 0.0] for i in range(2, 9)},
        T5=[0.0, 0.0],
        T6=[0.0, 0.0],
        T7=[0.0, 0.0],
    )
    w0 = {"omega": jnp.zeros(2)}
    hy = HYGOV(
        [0],
        R=0.05,
        r=0.05,
        Tr=5.0,
        Tf=0.05,
        Tg=0.2,
        VELM=0.02,
        GMAX=1.0,
        GMIN=0.0,
        TW=1.0,
        At=1.2,
        Dturb=0.0,
        qNL=0.08,
    )
    h0 = {"omega": jnp.zeros(1)}
    ga = GAST(
        [0],
        R=0.05,
        T1=0.2,
        T2=0.1,
        T3=1.0,
        AT=0.9,
        KT=2.0,
        VMAX=1.5,
        VMIN=0.0,
        Dturb=0.0,
    )
    cases = {
        # device 0: a 1% underspeed asks 0.5 + 0.2: the valve opens at UO = 0.1 pu/s
        # device 1: a 3% underspeed with fast rates asks 1.1: it stops at PMAX = 0.9
        "ieeeg1": (
            g1,
            *g1.init(jnp.array([0.5, 0.5]), w0),
            lambda t: {"omega": jnp.array([-0.01, -0.03])},
        ),
        # a 2% overspeed: the gate closes at VELM = 0.02 pu/s
        "hygov": (
            hy,
            *hy.init(jnp.array([0.7]), h0),
            lambda t: {"omega": 0.02 + 0 * t},
        ),
        # a 5% underspeed asks 0.6 + 1: the load limit takes over
        "gast": (
            ga,
            *ga.init(jnp.array([0.6]), h0),
            lambda t: {"omega": -0.05 + 0 * t},
        ),
    }
    return ts, _solve(cases, ts)


def test_ieeeg1_valve_rate_and_position_limits():
    """Rate-limited opening GV = 0.5 + UO t up to the demand 0.5 + K 0.01 = 0.7 (T3
    0.1 s, so the rate limit binds until 2 s); with fast rates a demand of 0.9 + ...
    stops at PMAX (non-windup: the state is held at the limit), reached at
    t = -T3 ln(1 - 0.4/0.6) = 0.11 s."""
    ts, res = _limit_runs()
    _, xs = res["ieeeg1"]
    ramp = ts <= 1.5
    np.testing.assert_allclose(xs[ramp, 1, 0], 0.5 + 0.1 * ts[ramp], atol=1e-7)
    assert abs(xs[-1, 1, 0] - 0.7) < 1e-3
    np.testing.assert_allclose(xs[ts >= 0.5, 1, 1], 0.9, atol=1e-6)


def test_hygov_gate_velocity_limit():
    """c closes at VELM: c = c0 - 0.02 t while the governor asks for more. Its
    unlimited rate is (e + Tr de/dt)/(r Tr) with e = -0.02 + R (c0 - c) once the
    filter has settled: on the ramp de/dt = 0.05 * 0.02, so it asks (-0.02 + 0.005)
    / 0.25 = -0.06 pu/s. (Without the limit the droop loop would settle at
    dc/dt = e/((r + R) Tr) = -0.04.)"""
    ts, res = _limit_runs()
    _, xs = res["hygov"]
    c0 = 0.7 / 1.2 + 0.08
    early = (ts > 0.3) & (ts <= 1.0)
    np.testing.assert_allclose(np.diff(xs[early, 1, 0]) / 0.1, -0.02, atol=1e-6)
    c3 = xs[ts == 3.0, 1, 0][0]
    assert c0 - 0.02 * 3.0 - 1e-6 <= c3 < c0 - 0.02 * 2.5


def test_gast_load_limit_takes_over():
    """A 5% underspeed asks the valve for 0.6 + 0.05/0.05 = 1.6; the low-value gate
    passes the load limit AT + KT (AT - x3) <= 1.5 from t = 0 on, so the states
    follow the linear loop x' = A (x - AT) exactly: x(t) = AT + expm(A t)(x0 - AT)
    with A = [[-1/T1, 0, -KT/T1], [1/T2, -1/T2, 0], [0, 1/T3, -1/T3]] (closed form),
    settling at Pm = AT = 0.9, below VMAX = 1.5."""
    from scipy.linalg import expm

    ts, res = _limit_runs()
    out, xs = res["gast"]
    T1, T2, T3, KT, AT = 0.2, 0.1, 1.0, 2.0, 0.9
    A = np.array([[-1 / T1, 0, -KT / T1], [1 / T2, -1 / T2, 0], [0, 1 / T3, -1 / T3]])
    want = np.array([AT + expm(A * t) @ np.full(3, 0.6 - AT) for t in ts])
    np.testing.assert_allclose(xs[:, :, 0], want, atol=1e-7)
    np.testing.assert_allclose(out[-1, 0], AT, atol=1e-6)


# ---------------------------------------------------------------------------
# gradients: d(output at 2 s after an input step)/d(one parameter) against central
# differences, the re-initialization included

GRAD_PARAMS = {
    "IEEEG1": "K",
    "HYGOV": "TW",
    "IEESGO": "K2",
    "GAST": "T2",
    "ST2CUT": "T3",
    "STAB2A": "K4",
    "IEEEST": "A6",
    "PSS2A": "KS3",
}


def _grad_devices():
    r = np.random.default_rng(11)
    one = {n: m[0](r) for n, m in MODELS.items()}
    devs = {n: jax.tree_util.tree_map(lambda a: a[:1], d) for n, d in one.items()}
    devs["IEEEST"] = _ieeest_full(IEEEST_A[:, :1])
    devs["PSS2A"] = _pss2(PSS2A, np.random.default_rng(13), n=1)
    st = devs["ST2CUT"]  # both inputs in use: speed and electrical power
    devs["ST2CUT"] = eqx.tree_at(
        lambda d: (d.ICS1, d.ICS2), st, (np.array([1]), np.array([3]))
    )
    return devs


def _step_output(values):
    """The outputs 2 s after input steps (speed +2e-3, Pe +0.05), each device's
    parameter GRAD_PARAMS[name] set to values[k]: a fixed-step RK4 (10 ms) in a
    lax.scan, cheap to compile and differentiate (the gradient and the differences
    see the same discretization)."""
    devs = _grad_devices()
    y0 = {"IEEEG1": 0.5, "HYGOV": 0.6, "IEESGO": 0.6, "GAST": 0.6}
    cases = {}
    for k, (n, par) in enumerate(GRAD_PARAMS.items()):
        d = eqx.tree_at(lambda d, par=par: getattr(d, par), devs[n], values[k : k + 1])
        m0 = {"omega": jnp.zeros(1), "Pe": jnp.full(1, 0.5), "Vt": jnp.ones(1)}
        x0, ref = d.init(jnp.full(1, y0.get(n, 0.0)), m0)
        m1 = {**m0, "omega": m0["omega"] + 2e-3, "Pe": m0["Pe"] + 0.05}
        cases[n] = (d, x0, ref, m1)

    def f(x):
        return {n: d.rhs(x[n], m, r) for n, (d, _, r, m) in cases.items()}

    def step(x, _):
        h = 0.01
        k1 = f(x)
        k2 = f(jax.tree_util.tree_map(lambda a, b: a + h / 2 * b, x, k1))
        k3 = f(jax.tree_util.tree_map(lambda a, b: a + h / 2 * b, x, k2))
        k4 = f(jax.tree_util.tree_map(lambda a, b: a + h * b, x, k3))
        return jax.tree_util.tree_map(
            lambda a, b1, b2, b3, b4: a + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4),
            x,
            k1,
            k2,
            k3,
            k4,
        ), None

    x, _ = jax.lax.scan(step, {n: c[1] for n, c in cases.items()}, None, length=200)
    return jnp.stack([d.out(x[n], m, r)[0] for n, (d, _, r, m) in cases.items()])


def test_gradients_match_central_differences():
    """Each output depends on its own device's parameter only, so one forward-mode
    derivative along all parameters at once gives every d(out_k)/d(p_k), and two
    evaluations at p0 +- h (every parameter moved) give every central difference:
    one compiled program."""
    devs = _grad_devices()
    p0 = jnp.asarray([float(getattr(devs[n], p)[0]) for n, p in GRAD_PARAMS.items()])
    jvp = jax.jit(lambda p, t: jax.jvp(_step_output, (p,), (t,)))
    _, dout = jvp(p0, jnp.ones_like(p0))
    h = 1e-4 * jnp.abs(p0)
    fd = (jvp(p0 + h, h)[0] - jvp(p0 - h, h)[0]) / (2 * h)
    for k, name in enumerate(GRAD_PARAMS):
        assert abs(float(fd[k])) > 1e-6, name  # the output depends on the parameter
        assert float(dout[k]) == pytest.approx(float(fd[k]), rel=1e-5, abs=1e-10), name


# ---------------------------------------------------------------------------
# ANDES 2.0 on the Kundur two-area case (tests/data/controls/make_andes_govpss.py)


@functools.cache
def _andes():
    d = json.loads(FIXTURE.read_text())
    ts, te = np.asarray(d["t"]), d["t_event"]
    cases = {}
    govs = (("IEEEG1", IEEEG1), ("HYGOV", HYGOV), ("IEESGO", IEESGO), ("GAST", GAST))
    for name, cls in govs:
        rec = d[name]
        dev = cls.from_params([0], [rec["params"]])
        w = _interp(ts, rec["omega"], te)

        def m(t, w=w):
            return {"omega": jnp.reshape(w(t), (1,))}

        cases[name] = (dev, *dev.init(jnp.array([rec["Pm"][0]]), m(0.0)), m)
    rec = d["ST2CUT"]
    st = ST2CUT.from_params([0], [rec["params"]])
    s1, s2 = _interp(ts, rec["signal1"], te), _interp(ts, rec["signal2"], te)

    def ms(t):
        return {
            "omega": jnp.reshape(s1(t), (1,)),
            "Pe": jnp.reshape(s2(t), (1,)),
            "Vt": jnp.ones(1),
        }

    cases["ST2CUT"] = (st, *st.init(jnp.zeros(1), ms(0.0)), ms)
    return d, _solve(cases, ts, jumps=(te,))


@pytest.mark.parametrize("name", ["IEEEG1", "HYGOV", "IEESGO", "GAST"])
def test_governor_against_andes(name):
    """Driven by ANDES's recorded speed after the line trip, the mechanical power
    follows ANDES's to 1e-3 of its swing. The parameters are PSS/E's for the model
    ANDES ran (the fixture's `params`: ANDES applies IEEEG1's UO, UC, IEESGO's K1 and
    HYGOV's TW, Dturb on the system base); IEEEG1 has K1 + K3 + K5 + K7 = 1, where
    ANDES's normalization of the K's changes nothing, and its valve rate limit
    binds; HYGOV has r Tr = Sn/Sb, where ANDES's integral gain is PSS/E's."""
    d, res = _andes()
    rec = d[name]
    assert np.ptp(rec["Pm"]) > 4e-3
    assert _rel_err(res[name][0][:, 0], rec["Pm"]) < 1e-3


def test_st2cut_against_andes():
    """Two inputs, speed (ICS1 = 1) and electrical power (ICS2 = 3): within 1e-4 of
    the output's swing from 100 ms after the trip on, and within 2e-3 at the first
    sample after it (6 ms), where ANDES's 2 ms trapezoid step smooths the jump of
    the power signal through the lead-lags (1.4e-3 there)."""
    d, res = _andes()
    rec = d["ST2CUT"]
    assert np.ptp(rec["Vs"]) > 0.05
    out, want = res["ST2CUT"][0][:, 0], np.asarray(rec["Vs"])
    assert _rel_err(out, want) < 2e-3
    after = np.asarray(d["t"]) >= d["t_event"] + 0.1
    assert np.max(np.abs(out - want)[after]) / np.ptp(want) < 1e-4


# ---------------------------------------------------------------------------
# a real case at rest, and bad input

KUNDUR_DYR = """\
1 'GENROU' 1 8.0 0.03 0.4 0.05 6.5 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
1 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
1 'ST2CUT' 1 1 0 3 0 20.0 -0.5 0.0 0.02 10.0 10.0 0.05 0.02 3.0 5.4 0.0 0.0 0.2 -0.2 0 0 /
1 'IEEEG1' 1 0 0 20.0 0.1 0.0 0.2 1.0 -1.0 0.95 0.0 0.1 0.3 0.0 7.0 0.3 0.0 0.5 0.4
   0.0 0.0 0.0 0.0 /
2 'GENROU' 1 8.0 0.03 0.4 0.05 6.5 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
2 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
2 'STAB2A' 1 1.0 4.5 0.87 2.0 0.087 1.0 0.01 0.04 /
2 'HYGOV' 1 0.06 0.4 5.0 0.05 0.2 0.2 1.0 0.0 1.0 1.1 0.5 0.1 /
3 'GENROU' 1 8.0 0.03 0.4 0.05 6.175 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
3 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
3 'IEEEST' 1 1 0 0.02 0.0005 0.0 0.0 0.01 0.0002 0.05 0.02 3.0 5.4 10.0 10.0 20.0
   0.2 -0.2 0.0 0.0 /
3 'IEESGO' 1 0.01 0.0 0.15 0.3 8.0 0.4 20.0 0.7 0.43 1.0 0.0 /
4 'GENROU' 1 8.0 0.03 0.4 0.05 6.175 0.0 1.8 1.7 0.3 0.55 0.25 0.2 0.039175 0.22268 /
4 'SEXS' 1 1.0 1.0 200.0 0.01 -6.4 7.0 /
4 'GAST' 1 0.05 0.4 0.1 3.0 1.0 2.0 1.0 0.0 0.1 /
4 'PSS2B' 1 1 0 3 0 5 1 10.0 10.0 0.0 10.0 0.0 10.0 1.0 1.0 0.5 0.1 20.0 0.15 0.025
   0.15 0.025 0.0 0.0 0.2 -0.2 2.0 -2.0 0.1 -0.1 /
"""


def test_kundur_with_every_new_model_starts_at_an_exact_equilibrium(tmp_path):
    """Kundur's four GENROU machines with an IEEEG1 + ST2CUT (speed and power),
    a HYGOV + STAB2A (Nordic 44's data), an IEESGO (Nordic 44's, K1 = 20) + IEEEST
    with A3 = A4 = 0 and A6 != 0, and a GAST + PSS2B (speed and power, M = 5,
    N = 1, TW4 = 0): every derivative at t = 0 is below
    1e-8, and the governors hold the machines' Pm0."""
    from smibjax.grid.case import case_files, load_case
    from smibjax.grid.loop import evaluate, state_labels
    from smibjax.grid.network import stage_configs, stage_matrices
    from smibjax.grid.operating import operating_point

    dyr = tmp_path / "kundur_govpss.dyr"
    dyr.write_text(KUNDUR_DYR)
    case = load_case(case_files("kundur")[0], dyr)
    names = sorted(type(c).__name__ for c in case.controllers)
    assert names == sorted(
        ["IEEEG1", "HYGOV", "IEESGO", "GAST", "ST2CUT", "STAB2A", "IEEEST", "PSS2B"]
        + ["SEXS"]
    )
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
    assert float(jnp.max(jnp.abs(meas["Vs"]))) == 0.0


def _rec(cls, **over):
    base = {
        "IEEEG1": dict(
            zip(
                IEEEG1.con_names,
                [20, 0.1, 0, 0.2, 1, -1, 0.95, 0, 0.1, 0.3, 0, 7, 0.3, 0, 0.5, 0.4]
                + [0, 0, 0, 0],
                strict=True,
            ),
            JBUS=0,
            M=0,
        ),
        "HYGOV": dict(
            zip(
                HYGOV.con_names,
                [0.06, 0.4, 5, 0.05, 0.2, 0.2, 1, 0, 1, 1.1, 0.5, 0.1],
                strict=True,
            )
        ),
        "ST2CUT": dict(
            zip(
                ST2CUT.con_names,
                [20, -0.5, 0, 0.02, 10, 10, 0.05, 0.02, 3, 5.4, 0, 0, 0.2, -0.2, 0, 0],
                strict=True,
            ),
            ICS1=1,
            IB1=0,
            ICS2=3,
            IB2=0,
        ),
        "GAST": dict(
            zip(GAST.con_names, [0.05, 0.4, 0.1, 3, 1, 2, 1, 0, 0.1], strict=True)
        ),
        "STAB2A": dict(
            zip(STAB2A.con_names, [1, 4.5, 0.87, 2, 0.087, 1, 0.01, 0.04], strict=True)
        ),
        "IEESGO": dict(
            zip(
                IEESGO.con_names,
                [0.01, 0, 0.15, 0.3, 8, 0.4, 20, 0.7, 0.43, 1, 0],
                strict=True,
            )
        ),
    }[cls.__name__]
    return cls.from_params([0], [{**base, **over}])


@pytest.mark.parametrize(
    "cls,over,match",
    [
        (IEEEG1, {"JBUS": 5}, r"^IEEEG1\.JBUS = 5 is not supported: only 0"),
        (IEEEG1, {"T3": 0.0}, r"^IEEEG1\.T3 = \[0\.\] is not allowed: must be > 0$"),
        (IEEEG1, {"UC": 0.5}, r"^IEEEG1\.UC = \[0\.5\] is not allowed: must be <= 0"),
        (IEEEG1, {"T1": 0.0, "T2": 0.3}, r"^IEEEG1\.T1 = \[0\.\] is not allowed"),
        (
            IEEEG1,
            {"PMIN": 2.0},
            r"^IEEEG1\.PMAX = \[0\.95\] is not allowed: must be >=",
        ),
        (HYGOV, {"Tf": 0.0}, r"^HYGOV\.Tf = \[0\.\] is not allowed: must be > 0$"),
        (HYGOV, {"GMIN": 1.5}, r"^HYGOV\.GMAX = \[1\.\] is not allowed"),
        (IEESGO, {"T3": 0.0, "T2": 0.1}, r"^IEESGO\.T3 = \[0\.\] is not allowed"),
        (ST2CUT, {"ICS2": 2}, r"^ST2CUT\.ICS2 = 2 is not supported"),
        (ST2CUT, {"ICS1": 5, "IB1": 7}, r"^ST2CUT\.IB1 = 7 is not supported"),
        (ST2CUT, {"T4": 0.0}, r"^ST2CUT\.T4 = \[0\.\] is not allowed: must be > 0$"),
        (GAST, {"T3": 0.0}, r"^GAST\.T3 = \[0\.\] is not allowed: must be > 0$"),
        (STAB2A, {"T2": -1.0}, r"^STAB2A\.T2 = \[-1\.\] is not allowed: must be > 0$"),
    ],
)
def test_bad_parameters_are_refused_in_one_line(cls, over, match):
    with pytest.raises(ParameterError, match=match):
        _rec(cls, **over)


def test_an_operating_point_beyond_the_valve_is_refused():
    with pytest.raises(ParameterError, match=r"^IEEEG1\.Pm0 = \[1\.2\] is not allowed"):
        _rec(IEEEG1).init(jnp.array([1.2]), {"omega": jnp.zeros(1)})
    with pytest.raises(ParameterError, match=r"^HYGOV\.Pm0 = \[1\.5\] is not allowed"):
        _rec(HYGOV).init(jnp.array([1.5]), {"omega": jnp.zeros(1)})
    with pytest.raises(ParameterError, match=r"^GAST\.Pm0 = \[1\.1\] is not allowed"):
        _rec(GAST).init(jnp.array([1.1]), {"omega": jnp.zeros(1)})
