"""Where the engine's time goes, per core (issue 33): ASC (beta = -1) on one host
device, a batch of Monte Carlo scenarios (seed 0), 10 s.

Times, best of --repeat calls after a first (compiling) one:

- `engine`: the batch engine (`smibjax._batch.Engine.run`), as throughput.py calls it;
- `solve`: diffrax's loop alone as `simulate` sets it up (Tsit5, PID control with the
  switch times as jump times, the loss-of-synchronism event, samples every 10 ms),
  without the engine's sampling of the outputs and metrics;
- the same without the 10 ms samples (`no_samples`: only the end state), without the
  event (`no_event`), and with the Runge-Kutta stages unrolled (`unrolled_stages`:
  `UnrolledTsit5` below, the same tableau and FSAL rule as diffrax's Tsit5, whose
  stages run in an inner loop);
- `bare_field`: the closed-loop vector field alone, vmapped and iterated as many
  times per lane as the solve evaluates it (7 a step: diffrax re-evaluates the first
  stage in every lane when any lane has just stepped over a switch time, which in a
  batch of random faults is nearly every step).

Each variant's largest difference from `solve`'s samples (rad, delta) says whether
it is the same computation.

    python studies/scipy_ratio/engine_profile.py [--n 1024] [--repeat 2] [--tag T]

Writes studies/scipy_ratio/engine_profile[_TAG].json.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results

from smibjax import configure

configure(cache=False)

import argparse

import diffrax as dfx
import equinox.internal as eqxi
import jax
import jax.lax as lax
import jax.numpy as jnp
import numpy as np
from _common import result_name, timed
from _results import write_results

import smibjax as sj
from smibjax._batch import Engine, Scenarios
from smibjax._closed_loop import (
    ClosedLoop,
    closed_loop_vector_field,
    healthy,
    initial_state,
)
from smibjax._parameters import InitialEstimates
from smibjax._scenarios import ScenarioDistribution, sample_scenarios
from smibjax._simulate import _RmsDynamic
from smibjax._stepping import RigidSteps

GAINS = sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0)
_TAB = dfx.Tsit5.tableau
_NS = 7  # Tsit5's stages
_A = np.zeros((_NS, _NS))
for _i, _row in enumerate(_TAB.a_lower):
    _A[_i + 1, : _i + 1] = _row
_C = np.concatenate([[0.0], _TAB.c])


class UnrolledTsit5(dfx.Tsit5):
    """diffrax's Tsit5 with its seven stages written out (no inner loop): the same
    tableau, FSAL rule and dense output."""

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        first_step, f0 = solver_state
        dt = t1 - t0
        control = terms.contr(t0, t1)
        again = eqxi.unvmap_any(first_step | made_jump)
        f0 = lax.cond(again, lambda: terms.vf(t0, y0, args), lambda: f0)
        a = jnp.asarray(_A, dtype=y0.dtype)
        ks = jnp.zeros((_NS, *y0.shape), y0.dtype).at[0].set(terms.prod(f0, control))
        yi, fi = y0, f0
        for i in range(1, _NS):
            yi = y0 + jnp.tensordot(a[i], ks, axes=1, precision=lax.Precision.HIGHEST)
            ti = t1 if _C[i] == 1 else t0 + _C[i] * dt
            fi = terms.vf(ti, yi, args)
            ks = ks.at[i].set(terms.prod(fi, control))
        err = jnp.tensordot(
            jnp.asarray(_TAB.b_error, y0.dtype), ks, axes=1, precision="highest"
        )
        dense = dict(y0=y0, y1=yi, k=ks)
        return yi, err, dense, (False, fi), dfx.RESULTS.successful


def solve_program(samples=True, event=True, unrolled=False):
    """jit(vmap) of diffrax's loop as `simulate` builds it, with the variant's
    changes; returns (delta samples, accepted steps, rejected steps)."""
    plant, op, init = sj.Plant(), sj.OperatingPoint(), InitialEstimates()
    ctrl = sj.controllers.as_controller(GAINS).with_static_alpha(True)
    ts = jnp.linspace(0.0, 10.0, 1001)

    def one(fault):
        loop = ClosedLoop(ctrl, fault, plant, op)
        y0 = initial_state(op, plant, init, ctrl)
        jumps = jnp.stack([fault.t_fault, fault.t_clear, fault.t_reclose])
        pid = dfx.PIDController(rtol=1e-6, atol=1e-8, norm=_RmsDynamic(loop.n_dynamic))
        sol = dfx.diffeqsolve(
            dfx.ODETerm(closed_loop_vector_field),
            UnrolledTsit5() if unrolled else dfx.Tsit5(),
            0.0,
            10.0,
            None,
            y0,
            args=loop,
            saveat=dfx.SaveAt(ts=ts, t1=True) if samples else dfx.SaveAt(t1=True),
            stepsize_controller=dfx.ClipStepSizeController(
                RigidSteps(pid), jump_ts=jumps
            ),
            event=dfx.Event(cond_fn=lambda t, y, args, **kw: ~healthy(t, y, args))
            if event
            else None,
            max_steps=50_000,
            throw=False,
        )
        return (
            sol.ys[:, 0],
            sol.stats["num_accepted_steps"],
            sol.stats["num_rejected_steps"],
        )

    return jax.jit(jax.vmap(one))


def bare_field_program(evals: int):
    """jit(vmap) of `evals` closed-loop field evaluations per lane, chained so that
    none can be hoisted."""
    plant, op, init = sj.Plant(), sj.OperatingPoint(), InitialEstimates()
    ctrl = sj.controllers.as_controller(GAINS).with_static_alpha(True)

    def one(fault):
        loop = ClosedLoop(ctrl, fault, plant, op)
        y0 = initial_state(op, plant, init, ctrl)

        def body(_, c):
            t, y = c
            return t + 1e-3, y + 1e-6 * closed_loop_vector_field(t, y, loop)

        return lax.fori_loop(0, evals, body, (jnp.asarray(0.0), y0))[1]

    return jax.jit(jax.vmap(one))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)
    for name in ("n", "repeat"):
        if getattr(args, name) < 1:
            ap.error(f"--{name} {getattr(args, name)}: must be >= 1")
    faults, _, _ = sample_scenarios(0, 0, args.n, ScenarioDistribution(), sj.Plant())
    dev = jax.devices()[:1]
    faults = jax.device_put(faults, dev[0])
    engine = Engine()
    rows = {}
    _, s, _ = timed(
        lambda: jax.block_until_ready(
            engine.run(GAINS, Scenarios(faults), devices=dev)
        ),
        args.repeat,
    )
    rows["engine"] = {"seconds": s}
    ref = None
    for name, kw in (
        ("solve", {}),
        ("no_samples", {"samples": False}),
        ("no_event", {"event": False}),
        ("unrolled_stages", {"unrolled": True}),
    ):
        fn = solve_program(**kw)
        _, s, (delta, acc, rej) = timed(
            lambda fn=fn: jax.block_until_ready(fn(faults)), args.repeat
        )
        delta = np.asarray(delta)
        row = {
            "seconds": s,
            "steps_max": int(np.max(np.asarray(acc) + np.asarray(rej))),
        }
        if name == "solve":
            ref = delta
            row["mean_accepted"] = float(np.mean(acc))
            row["mean_rejected"] = float(np.mean(rej))
        if kw.get("samples", True):
            both = np.isfinite(delta) & np.isfinite(ref)
            row["max_abs_delta_difference_rad"] = float(
                np.max(np.abs(delta - ref)[both])
            )
        rows[name] = row
        print(name, row, flush=True)
    evals = _NS * rows["solve"]["steps_max"]
    fn = bare_field_program(evals)
    _, s, _ = timed(lambda: jax.block_until_ready(fn(faults)), args.repeat)
    rows["bare_field"] = {
        "seconds": s,
        "evals_per_lane": evals,
        "us_per_lane_eval": 1e6 * s / (evals * args.n),
    }
    for r in rows.values():
        r["share_of_engine"] = r["seconds"] / rows["engine"]["seconds"]
    print(f"{'':16s} {'s':>7s} {'x engine':>9s}")
    for name, r in rows.items():
        print(f"{name:16s} {r['seconds']:7.3f} {r['share_of_engine']:9.2f}")
    config = {
        "gains": "Gains.paper('asc', beta1=-1, beta2=-1)",
        "scenarios": "sample_scenarios(0, 0, n, ScenarioDistribution(), Plant()), 10 s",
        "n": args.n,
        "repeat": args.repeat,
        "devices": 1,
    }
    path = write_results(HERE, result_name("engine_profile", args.tag), config, rows)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
