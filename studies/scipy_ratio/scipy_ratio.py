"""Where the JAX-to-SciPy ratio of issue 33 comes from, for ASC (beta = -1): the same
model and Monte Carlo scenarios (seed 0) through SciPy's LSODA loop (vs_scipy's
`scipy_scenario`, tests/reference.py's right-hand side) and through smibjax's Tsit5.

- LSODA: steps and right-hand-side calls per scenario, microseconds per call;
- smibjax: accepted steps per scenario at rtol 1e-6 ... 1e-3 (atol = rtol / 100),
  and the largest over the mean within chunks of --chunk (vmap's waiting lanes);
- the closed loop's eigenvalues at rest (estimates at the truth, and at the initial
  estimates): the fastest bounds an explicit method's step;
- with --kvaerno: diffrax's implicit Kvaerno5 on --kvaerno scenarios (slow), its
  steps and time against Tsit5's on the same batch.

    python studies/scipy_ratio/scipy_ratio.py [--n-scipy 16] [--n 4096]
        [--chunk 1024] [--kvaerno 0] [--tag T]

Writes studies/scipy_ratio/scipy_ratio[_TAG].json.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # vs_scipy, _common, _results
sys.path.insert(0, str(ROOT / "tests"))  # reference.py

from smibjax import configure

configure(cache=False)

import argparse
import time

import diffrax as dfx
import jax
import numpy as np
import vs_scipy
from _common import result_name
from _results import write_results

import reference
import smibjax as sj
import smibjax._options as options
import smibjax._simulate as simulate_module
from smibjax._closed_loop import ClosedLoop, closed_loop_vector_field, initial_state
from smibjax._parameters import InitialEstimates
from smibjax._scenarios import ScenarioDistribution, sample_scenarios

GAINS = sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0)
RTOLS = (1e-6, 1e-5, 1e-4, 1e-3)


def lsoda(n: int) -> dict:
    """LSODA's steps, right-hand-side calls and time per scenario on scenarios
    0..n-1 (rtol 1e-6, atol 1e-8)."""
    gd = {k: float(getattr(GAINS, k)) for k in sj.GAIN_NAMES}
    plant = {k: float(getattr(sj.Plant(), k)) for k in sj.PLANT_NAMES}
    faults, _, _ = sample_scenarios(0, 0, n, ScenarioDistribution(), sj.Plant())
    calls, steps = [0], [0]
    rhs, solve = reference.rhs, vs_scipy.solve_ivp

    def counted_rhs(*a):
        calls[0] += 1
        return rhs(*a)

    def counted_solve(*a, **k):
        sol = solve(*a, **k)
        steps[0] += len(sol.t) - 1
        return sol

    reference.rhs, vs_scipy.solve_ivp = counted_rhs, counted_solve
    try:
        t0 = time.perf_counter()
        for i in range(n):
            fl = {k: float(getattr(faults, k)[i]) for k in sj.FAULT_NAMES}
            vs_scipy.scipy_scenario(gd, plant, fl, "LSODA", 10.0, (1e-6, 1e-8))
        seconds = time.perf_counter() - t0
    finally:
        reference.rhs, vs_scipy.solve_ivp = rhs, solve
    return {
        "scenarios": n,
        "scenarios_per_s": n / seconds,
        "steps_per_scenario": steps[0] / n,
        "rhs_calls_per_scenario": calls[0] / n,
        "us_per_rhs_call": 1e6 * seconds / calls[0],
    }


def batch_steps(n: int, method: str, rtol: float) -> tuple[np.ndarray, float]:
    """Accepted steps per scenario of scenarios 0..n-1 (10 s) and the seconds of a
    second call of the jitted, vmapped batch."""
    faults, _, _ = sample_scenarios(0, 0, n, ScenarioDistribution(), sj.Plant())
    solver = sj.SolverOptions(method=method, rtol=rtol, atol=rtol / 100)
    run = jax.jit(jax.vmap(lambda f: sj.simulate(GAINS, f, solver=solver).num_steps))
    jax.block_until_ready(run(faults))
    t0 = time.perf_counter()
    steps = np.asarray(jax.block_until_ready(run(faults)))
    return steps, time.perf_counter() - t0


def eigenvalues() -> dict:
    """The closed loop's eigenvalues (1/s) at the operating point: the estimates at
    the truth (as test_modes's manifold test) and at their initial values."""
    plant, op = sj.Plant(), sj.OperatingPoint()
    loop = ClosedLoop(GAINS, sj.Fault(), plant, op)
    y0 = initial_state(op, plant, InitialEstimates(), loop.controller)
    out = {}
    for label, y in (
        ("estimates_true", y0.at[4].set(-plant.D).at[5].set(plant.Pm)),
        ("estimates_initial", y0),
    ):
        n = loop.n_dynamic
        A = jax.jacfwd(lambda y: closed_loop_vector_field(0.0, y, loop))(y)[:n, :n]
        lam = np.linalg.eigvals(np.asarray(A))
        out[label] = sorted([float(z.real), float(z.imag)] for z in lam)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-scipy", type=int, default=16)
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--chunk", type=int, default=1024)
    ap.add_argument("--kvaerno", type=int, default=0, help="scenarios (0: skip)")
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)
    for name in ("n_scipy", "n", "chunk"):
        if getattr(args, name) < 1:
            ap.error(f"--{name.replace('_', '-')} {getattr(args, name)}: must be >= 1")

    res = {"lsoda": lsoda(args.n_scipy), "eigenvalues": eigenvalues(), "tsit5": {}}
    print(f"LSODA: {res['lsoda']}", flush=True)
    for rtol in RTOLS:
        steps, seconds = batch_steps(args.n, "tsit5", rtol)
        chunks = [
            float(c.max() / c.mean())
            for c in np.array_split(steps, max(1, args.n // args.chunk))
        ]
        res["tsit5"][f"{rtol:g}"] = {
            "mean_steps": float(steps.mean()),
            "max_over_mean_per_chunk": chunks,
            "scenarios_per_s": args.n / seconds,
        }
        print(f"Tsit5 rtol {rtol:g}: {res['tsit5'][f'{rtol:g}']}", flush=True)
    if args.kvaerno:
        # one try, patched in: Kvaerno5 is not among SolverOptions' methods
        options.METHODS = (*options.METHODS, "kvaerno5")
        simulate_module._SOLVERS["kvaerno5"] = lambda: dfx.Kvaerno5(
            root_finder=dfx.VeryChord(rtol=1e-6, atol=1e-8)
        )
        rows = {}
        for method in ("tsit5", "kvaerno5"):
            steps, seconds = batch_steps(args.kvaerno, method, 1e-6)
            rows[method] = {"mean_steps": float(steps.mean()), "seconds": seconds}
        res["kvaerno5_vs_tsit5"] = rows
        print(f"Kvaerno5 against Tsit5: {rows}", flush=True)
    config = {
        "gains": "Gains.paper('asc', beta1=-1, beta2=-1)",
        "scenarios": "sample_scenarios(0, 0, n, ScenarioDistribution(), Plant()), 10 s",
        "n_scipy": args.n_scipy,
        "n": args.n,
        "chunk": args.chunk,
        "kvaerno": args.kvaerno,
        "devices": len(jax.devices()),
    }
    path = write_results(HERE, result_name("scipy_ratio", args.tag), config, res)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
