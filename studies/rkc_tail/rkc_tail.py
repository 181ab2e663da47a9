"""Does a stabilized explicit method shorten the settled tail? (issue 15, ASC)

ASC's settled tail is held near 15 ms a step by the stability of Tsit5 on the stiff
-1/T1 = -200 1/s mode. A Runge-Kutta-Chebyshev method (second order, s stages, real
stability interval about 0.65 s^2: Sommeijer, Shampine and Verwer, "RKC: an explicit
solver for parabolic PDEs", J. Comput. Appl. Math. 88, 1997) is stable there with far
longer steps. This script measures whether accuracy then lets it take them.

Every Monte Carlo scenario 0..--n-1 (seed 0, default distribution, beta1 = beta2 =
-1, oracle, paper plant, rtol 1e-6, atol 1e-8, one core) is integrated in two
phases: Tsit5 from 0 to t_reclose + --delay (every switch is behind it), then the
tail to 10 s with Tsit5 again or with `RKC2(s)` for each --stages s (the same PID
step control, norm and event as `simulate`; dense output by cubic Hermite
interpolation). The table gives the tail's accepted and rejected steps and field
evaluations (Tsit5 6 a step, RKC2 s a step), and the largest differences of the
samples (delta, omega, E', B) and of delta's settling time from the all-Tsit5
two-phase run. First it checks the method's order on y' = -50 y + cos t. Writes
studies/rkc_tail/rkc_tail.json.

    python studies/rkc_tail/rkc_tail.py [--n 128] [--delay 1.0] [--stages 4 6 8]
        [--controller asc]
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results

os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=1"

from smibjax import configure

configure(cache=False)

import argparse
from typing import ClassVar

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
from _results import write_results

import smibjax as sj
from smibjax._closed_loop import (
    ClosedLoop,
    closed_loop_vector_field,
    healthy,
    initial_state,
)
from smibjax._metrics import settling_time
from smibjax._scenarios import ScenarioDistribution, sample_scenarios
from smibjax._simulate import _RmsDynamic

T_END = 10.0


def rkc_coefficients(s: int, eps: float = 2.0 / 13.0):
    """RKC's recurrence coefficients (mu, nu, mu~, gamma~, c; index j = stage) and its
    real stability interval beta (the method is stable for h*lambda in [-beta, 0])."""
    w0 = 1.0 + eps / s**2
    T, dT, ddT = np.zeros(s + 1), np.zeros(s + 1), np.zeros(s + 1)
    T[0], T[1], dT[1] = 1.0, w0, 1.0
    for j in range(2, s + 1):  # Chebyshev polynomials and derivatives at w0
        T[j] = 2 * w0 * T[j - 1] - T[j - 2]
        dT[j] = 2 * T[j - 1] + 2 * w0 * dT[j - 1] - dT[j - 2]
        ddT[j] = 4 * dT[j - 1] + 2 * w0 * ddT[j - 1] - ddT[j - 2]
    w1 = dT[s] / ddT[s]
    b = np.zeros(s + 1)
    b[2:] = ddT[2:] / dT[2:] ** 2
    b[0] = b[1] = b[2]
    a = 1.0 - b * T
    mu, nu, mut, gat, c = (np.zeros(s + 1) for _ in range(5))
    mut[1] = c[1] = b[1] * w1
    for j in range(2, s + 1):
        mu[j] = 2 * b[j] * w0 / b[j - 1]
        nu[j] = -b[j] / b[j - 2]
        mut[j] = 2 * b[j] * w1 / b[j - 1]
        gat[j] = -a[j - 1] * mut[j]
        c[j] = mu[j] * c[j - 1] + nu[j] * c[j - 2] + mut[j] + gat[j]
    return mu, nu, mut, gat, c, (w0 + 1) * ddT[s] / dT[s]


class RKC2(dfx.AbstractAdaptiveSolver):
    """Second-order RKC, `s` stages, damping 2/13; error estimate
    (12 (y0 - y1) + 6 h (f0 + f1)) / 15 (SSV97); first same as last (s field
    evaluations a step). For a tail with no switch in it: a jump is not handled."""

    s: int = 6
    term_structure: ClassVar = dfx.AbstractTerm
    interpolation_cls: ClassVar = dfx.ThirdOrderHermitePolynomialInterpolation

    def order(self, terms):
        return 2

    def init(self, terms, t0, t1, y0, args):
        return terms.vf(t0, y0, args)

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, f0, made_jump):
        mu, nu, mut, gat, c, _ = rkc_coefficients(self.s)
        h = t1 - t0
        y_prev, y_cur = y0, y0 + mut[1] * h * f0
        for j in range(2, self.s + 1):
            fj = terms.vf(t0 + c[j - 1] * h, y_cur, args)
            y_next = (1 - mu[j] - nu[j]) * y0 + mu[j] * y_cur + nu[j] * y_prev
            y_next = y_next + mut[j] * h * fj + gat[j] * h * f0
            y_prev, y_cur = y_cur, y_next
        f1 = terms.vf(t1, y_cur, args)
        err = (12.0 * (y0 - y_cur) + 6.0 * h * (f0 + f1)) / 15.0
        dense = dict(y0=y0, y1=y_cur, k0=h * f0, k1=h * f1)
        return y_cur, err, dense, f1, dfx.RESULTS.successful


def order_check(s: int) -> list[float]:
    """Errors at t = 1 of y' = -50 y + cos t, y(0) = 0, steps 0.02, 0.01, 0.005."""
    term = dfx.ODETerm(lambda t, y, a: -50.0 * y + jnp.cos(t))
    exact = (50 * np.cos(1.0) + np.sin(1.0) - 50 * np.exp(-50.0)) / 2501
    out = []
    for dt in (0.02, 0.01, 0.005):
        sol = dfx.diffeqsolve(term, RKC2(s), 0.0, 1.0, dt, jnp.array(0.0))
        out.append(float(sol.ys[-1]) - exact)
    return out


def solve(solver, loop, y0, t0, t1, ts, jumps):
    """One adaptive phase with simulate's step control, norm and event."""
    return dfx.diffeqsolve(
        dfx.ODETerm(closed_loop_vector_field),
        solver,
        t0=t0,
        t1=t1,
        dt0=None,
        y0=y0,
        args=loop,
        saveat=dfx.SaveAt(ts=jnp.clip(ts, t0, t1), t1=True),
        stepsize_controller=dfx.ClipStepSizeController(
            dfx.PIDController(rtol=1e-6, atol=1e-8, norm=_RmsDynamic(6)),
            jump_ts=jumps,
        ),
        event=dfx.Event(cond_fn=lambda t, y, args, **kw: ~healthy(t, y, args)),
        max_steps=50_000,
        throw=False,
    )


def two_phase(ctrl, fault, tail_solver, delay, ts):
    """Samples (n, 4), tail accepted and rejected steps, stopped: Tsit5 to
    t_reclose + delay, then `tail_solver` to T_END."""
    plant, op = sj.Plant(), sj.OperatingPoint()
    loop = ClosedLoop(ctrl, fault, plant, op)
    y0 = initial_state(op, plant, sj.InitialEstimates(), ctrl)
    jumps = jnp.stack([fault.t_fault, fault.t_clear, fault.t_reclose])
    t_switch = jnp.minimum(fault.t_reclose + delay, T_END)
    head = solve(dfx.Tsit5(), loop, y0, 0.0, t_switch, ts, jumps)
    k = jnp.sum(jnp.isfinite(head.ts)) - 1
    stopped = head.result != dfx.RESULTS.successful
    t0 = jnp.where(stopped, head.ts[k], t_switch)
    tail = solve(
        tail_solver, loop, head.ys[k], t0, jnp.where(stopped, t0, T_END), ts, jumps
    )
    n = ts.shape[0]
    ys = jnp.where((ts <= t_switch)[:, None], head.ys[:n], tail.ys[:n])
    return (
        ys[:, :4],
        tail.stats["num_accepted_steps"],
        tail.stats["num_rejected_steps"],
        stopped | (tail.result != dfx.RESULTS.successful),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--delay", type=float, default=1.0)
    ap.add_argument("--stages", type=int, nargs="+", default=[4, 6, 8])
    ap.add_argument("--controller", choices=("asc", "aftsc"), default="asc")
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args()
    if args.n < 1:
        ap.error(f"--n {args.n} is not allowed: must be >= 1")
    if not 0.0 <= args.delay < T_END:
        ap.error(f"--delay {args.delay} is not allowed: must be in [0, {T_END:g}) s")
    if min(args.stages) < 2:
        ap.error(f"--stages {min(args.stages)} is not allowed: RKC needs s >= 2")
    orders = {}
    for s in args.stages:
        errs = order_check(s)
        beta = float(rkc_coefficients(s)[5])
        orders[s] = {"errors_h_0.02_0.01_0.005": errs, "stability_interval": beta}
        ratio = ", ".join(f"{errs[i] / errs[i + 1]:.2f}" for i in range(2))
        print(f"RKC2({s}): stable to h*lambda = -{beta:.1f}; error ratios {ratio}")
    g = sj.Gains.paper(args.controller, beta1=-1.0, beta2=-1.0)
    ctrl = sj.controllers.Synergetic(g).with_static_alpha()
    plant, op = sj.Plant(), sj.OperatingPoint()
    fault, _, _ = sample_scenarios(0, 0, args.n, ScenarioDistribution(), plant)
    ts = jnp.asarray(np.linspace(0.0, T_END, 1001))
    tails = {"tsit5": (dfx.Tsit5(), 6)}
    tails.update({f"rkc2_s{s}": (RKC2(s), s) for s in args.stages})
    out = {}
    for name, (solver, _) in tails.items():
        run = jax.jit(
            jax.vmap(lambda f, sv=solver: two_phase(ctrl, f, sv, args.delay, ts))
        )
        out[name] = jax.tree_util.tree_map(np.asarray, run(fault))
    ref = out["tsit5"][0]

    def settle(d):
        fn = jax.vmap(lambda x, tf: settling_time(ts, x, op.delta_e, 0.01, tf))
        return np.asarray(fn(jnp.asarray(d), fault.t_fault))

    st_ref = settle(ref[:, :, 0])
    rows = {}
    print(
        f"{'tail':>10} {'accepted':>9} {'rejected':>9} {'evals':>7} "
        f"{'delta':>8} {'omega':>8} {'E':>8} {'B':>8} {'settle ms':>9}"
    )
    for name, (ys, acc, rej, stopped) in out.items():
        evals = tails[name][1]
        diff = np.abs(ys - ref).max(axis=(0, 1))
        fin = np.isfinite(st_ref)
        st = settle(ys[:, :, 0])
        row = {
            "tail_accepted_mean": float(acc.mean()),
            "tail_rejected_mean": float(rej.mean()),
            "tail_evaluations_mean": float(evals * (acc + rej).mean()),
            "max_diff_delta_omega_E_B": diff.tolist(),
            "settling_max_diff_s": float(np.abs(st[fin] - st_ref[fin]).max()),
            "verdicts_equal": bool(np.array_equal(stopped, out["tsit5"][3])),
        }
        rows[name] = row
        print(
            f"{name:>10} {row['tail_accepted_mean']:9.1f} "
            f"{row['tail_rejected_mean']:9.1f} {row['tail_evaluations_mean']:7.0f} "
            + " ".join(f"{x:8.1e}" for x in diff)
            + f" {1e3 * row['settling_max_diff_s']:9.3f}"
        )
    path = write_results(
        args.out,
        "rkc_tail",
        {
            "n": args.n,
            "delay_s": args.delay,
            "controller": args.controller,
            "gains": "paper, beta1 = beta2 = -1, oracle",
            "tolerances": "rtol 1e-6, atol 1e-8 (both phases)",
        },
        {"order_check": orders, "rows": rows},
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
