"""An independent NumPy/SciPy implementation of MODEL.md, for the tests.

Written from the specification alone (closed forms, no JAX, no import of smibjax), so
that agreement with it checks the JAX code rather than repeating it. Segments between
switch times are integrated separately with `scipy.integrate.solve_ivp` (DOP853).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

PLANT = dict(
    H=5.0,
    D=0.2,
    T0=4.0,
    V=1.0,
    Xd=1.1,
    Xdp=0.2,
    XT=0.1,
    XL=0.2,
    Tr=1.0,
    Pm=1.0,
    f=60.0,
    B0=0.0,
    uf_min=-np.inf,
    uf_max=np.inf,
    ur_min=-np.inf,
    ur_max=np.inf,
)
GAINS = dict(
    beta1=50.0,
    beta2=50.0,
    T1=0.005,
    T2=1.0,
    alpha=5 / 7,
    gamma1=5.0,
    gamma2=5.0,
    k1=1.0,
    k2=1.0,
)
FAULT = dict(t_fault=0.5, t_clear=0.7, t_reclose=2.0, lam=0.5, Xf=0.0)
DELTA_E, PM_REF, TH0 = 0.4964, 1.0, (-0.5, 0.0)


def spow(y, a):
    return math.copysign(abs(y) ** a, y)


def stages(p, fl):
    """[(X2, Bf)] for pre-fault, fault, post-fault, restored (MODEL.md section 1)."""
    xl = p["XL"]
    za, zb, zc = fl["lam"] * 2 * xl, (1 - fl["lam"]) * 2 * xl, fl["Xf"]
    if zc == 0.0:
        fault = (2 * xl, -1 / za)
    else:
        s = za * zb + zb * zc + zc * za
        z_minf, z_mg = s / zc, s / zb
        fault = (1 / (1 / (2 * xl) + 1 / z_minf), -1 / z_mg)
    return [(xl, 0.0), fault, (2 * xl, 0.0), (xl, 0.0)]


def rhs(t, y, p, g, stage, oracle=True):
    delta, dw, E, B, th1, th2 = y[:6]
    x1c = p["Xdp"] + p["XT"]
    M = 2 * p["H"] / (2 * math.pi * p["f"])
    # controller on the nominal network
    X2n = p["XL"]
    Xs = x1c + X2n
    Xds = p["Xd"] + p["XT"] + X2n
    a = Xds / (Xs * p["T0"])
    c = (p["Xd"] - p["Xdp"]) / (Xs * p["T0"])
    x3 = E * p["V"] * math.sin(delta) / Xs
    den = Xs - x1c * X2n * B
    Mt = Xs / den - 1
    x4 = Mt * x3
    f3 = (-a + dw / math.tan(delta)) * x3 + c * p["V"] ** 2 * math.sin(2 * delta) / (
        2 * Xs
    )
    g31 = p["V"] * math.sin(delta) / Xs
    Nt = -x3 * x1c * X2n * Xs / den**2
    f4 = Mt * f3 + Nt * (B - p["B0"]) / p["Tr"]
    g41, g42 = Mt * g31, -Nt
    e1, e2, e3, e4 = delta - DELTA_E, dw, x3 - PM_REF, x4
    b1, b2, al = g["beta1"], g["beta2"], g["alpha"]
    phi1 = e1 + e2 + b1 * e3
    phi2 = e1 + e2 + b2 * e4
    xd2 = (th2 + th1 * dw - x3 - x4) / M
    v1 = -(b1 * f3 + dw + xd2 - spow(-phi1 / g["T1"], al)) / (b1 * g31)
    v2 = -(b2 * (f4 + g41 * v1) + dw + xd2 - spow(-phi2 / g["T2"], al)) / (b2 * g42)
    uf = min(max(p["T0"] * v1, p["uf_min"]), p["uf_max"])
    ur = min(max(p["Tr"] * v2, p["ur_min"]), p["ur_max"])
    k1, k2 = (g["k1"], g["k2"]) if oracle else (0.0, 0.0)
    dth1 = g["gamma1"] * (k1 * spow(-p["D"] - th1, al) + dw * (phi1 + phi2) / M)
    dth2 = g["gamma2"] * (k2 * spow(p["Pm"] - th2, al) + (phi1 + phi2) / M)
    # plant on the network stage in force
    X2, Bf = stage
    Xs_ = x1c + X2
    Xds_ = p["Xd"] + p["XT"] + X2
    P = E * p["V"] * math.sin(delta) / (Xs_ - x1c * X2 * (B + Bf))
    return np.array(
        [
            dw,
            (p["Pm"] - p["D"] * dw - P) / M,
            -Xds_ / (Xs_ * p["T0"]) * E
            + c * Xs / Xs_ * p["V"] * math.cos(delta)
            + uf / p["T0"],
            (-(B - p["B0"]) + ur) / p["Tr"],
            dth1,
            dth2,
        ]
    )


def simulate(
    gains=None,
    plant=None,
    fault=None,
    t_end=10.0,
    dt_save=0.01,
    rtol=1e-11,
    atol=1e-13,
    oracle=True,
):
    """Sampled (t, y) with y = (delta, domega, E, B, th1, th2) on a uniform grid."""
    g = {**GAINS, **(gains or {})}
    p = {**PLANT, **(plant or {})}
    fl = {**FAULT, **(fault or {})}
    Xs = p["Xdp"] + p["XT"] + p["XL"]
    y = np.array(
        [DELTA_E, 0.0, PM_REF * Xs / (p["V"] * math.sin(DELTA_E)), p["B0"], *TH0]
    )
    n = int(round(t_end / dt_save)) + 1
    ts = np.linspace(0.0, t_end, n)
    out = np.full((n, 6), np.nan)
    bounds = [0.0, fl["t_fault"], fl["t_clear"], fl["t_reclose"], np.inf]
    for i, st in enumerate(stages(p, fl)):
        a, b = max(bounds[i], 0.0), min(bounds[i + 1], t_end)
        if b <= a:
            continue
        # grid points in [a, b) belong to this stage (the last stage also takes t_end)
        sel = (ts >= a) & ((ts < b) | ((b == t_end) & (ts <= b)))
        sol = solve_ivp(
            rhs,
            (a, b),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            args=(p, g, st, oracle),
            dense_output=True,
        )
        assert sol.success, sol.message
        if sel.any():
            out[sel] = sol.sol(ts[sel]).T
        y = sol.y[:, -1]
    return ts, out
