"""EXDC2's moving regulator limits on IEEE 39 against ANDES 2.0 (issue 28).

The bus-16 fault of `benchmarks/vs_andes.py` (through j 1e-4 pu, 1.0-1.1 s, 10 s,
angles referred to the centre of inertia, max over 10 s and machines) on IEEE 39
GENROU + exciter + TGOV1.

smibjax: every IEEEX1 record read as EXDC2 (limits VRMIN Vt, VRMAX Vt) with the
sweeping moving-limit rule at each --sweeps and --rtols, and with main 0bbe1d7's
held rule at --stale-rtols; and its IEEEX1 (constant limits) at the tightest rtol.
atol = rtol / 100, 400,000 steps at most; each run in a fresh process (the rule is
read when the model is traced); steps, whether the budget ran out, CPU seconds.

ANDES 2.0.0 (trapezoid, fixed steps --andes-tsteps, tol 1e-8), three variants:
`IEEEX1` as shipped (its limiter keeps VRMAX/VRMIN: the VRMAX v it defines never
reaches the limiter, so its limits are constant); `IEEEX1_vt`, its limiter pointed
at VRMAX v / VRMIN v in this run (moving limits, the state reset to the limit); and
`EXDC2`, the records renamed (constant limits, Efd multiplied by the speed).

Writes benchmarks/results/exdc2_limits.json (exdc2_limits_TAG.json).

    python benchmarks/exdc2_limits.py                    # ~10 min here
    python benchmarks/exdc2_limits.py --sweeps 10 30 100 --stale-rtols
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import numpy as np

RAW, DYR, BUS = "ieee39.raw", "ieee39.dyr", 16


def renamed(src: str, old: str, new: str, folder: str) -> str:
    """A copy of dyr file `src` in `folder` with model name 'old' read as 'new'."""
    text = Path(src).read_text()
    assert f"'{old}'" in text
    out = Path(folder) / f"{Path(src).stem}_{new.lower()}.dyr"
    out.write_text(text.replace(f"'{old}'", f"'{new}'"))
    return str(out)


def smib_run(raw, dyr, rtol, rule, sweep):
    """smibjax on the bus-16 fault: (ts, delta, dict of run facts). `rule`: 'sweep'
    (this branch) or 'stale' (main 0bbe1d7's rule for EXDC2: held, not swept)."""
    from smibjax import configure

    configure(min_devices=1, cache=False)
    import equinox as eqx
    import jax
    from vs_andes import T_CLEAR, T_END, T_FAULT, XF, smib_setup

    from smibjax.grid.devices import _blocks, ieeex1
    from smibjax.grid.events import BusFault
    from smibjax.grid.simulate import simulate_case

    _blocks.SWEEP = float(sweep)
    if rule == "stale":
        ieeex1.lag_nonwindup = lambda *a, moving=False: _blocks.lag_nonwindup(*a)
    else:
        ieeex1.lag_nonwindup = _blocks.lag_nonwindup
    case, op = smib_setup(raw, dyr)
    ev = (
        BusFault(
            bus=case.system.bus_index(BUS), t_on=T_FAULT, t_off=T_CLEAR, r=0.0, x=XF
        ),
    )
    # a fresh jit per run: SWEEP and the rule are read at trace time
    fn = eqx.filter_jit(
        lambda c, o, e: simulate_case(
            c,
            o,
            e,
            t_end=T_END,
            dt_save=1e-3,
            rtol=rtol,
            atol=rtol / 100,
            max_steps=400_000,
        )
    )
    t0 = time.process_time()
    tr = jax.block_until_ready(fn(case, op, ev))
    cpu = time.process_time() - t0
    facts = {
        "rtol": rtol,
        "atol": rtol / 100,
        "rule": rule,
        "sweep": float(sweep) if rule == "sweep" else None,
        "steps": int(tr.n_steps),
        "exhausted": bool(tr.exhausted),
        "stable": bool(tr.stable),
        "cpu_s_incl_compile": cpu,
    }
    return np.asarray(tr.ts), np.asarray(tr.delta), facts


def smib_fresh(raw, dyr, rtol, rule, sweep):
    """`smib_run` in a fresh process (the rule and SWEEP are read when the model is
    traced, and traces are cached per process): (case, ts, delta, facts)."""
    import multiprocessing as mp

    from vs_andes import smib_setup

    with mp.get_context("spawn").Pool(1) as pool:
        ts, d, facts = pool.apply(smib_run, (raw, dyr, rtol, rule, sweep))
    return smib_setup(raw, dyr)[0], ts, d, facts


def andes_ieee39(raw, dyr, tstep, vt_limits=False):
    """ANDES 2.0 on the bus-16 fault (vs_andes.andes_run's set-up), trapezoid at
    `tstep`, tol 1e-8. ANDES 2.0.0's IEEEX1 defines VRTMAX = VRMAX v, VRTMIN = VRMIN v
    and sets them as its lag's `upper`/`lower` after the lag has built its limiter,
    whose bounds stay VRMAX/VRMIN: in effect its limits are constant. `vt_limits`
    points the limiter at VRTMAX/VRTMIN (the model as its source intends)."""
    from vs_andes import T_CLEAR, T_FAULT, andes_run

    def scaled(ss):
        ss.IEEEX1.LA.lim.upper = ss.IEEEX1.VRTMAX
        ss.IEEEX1.LA.lim.lower = ss.IEEEX1.VRTMIN

    keep = []
    t, d, keys, secs, done = andes_run(
        raw,
        dyr,
        "GENROU",
        BUS,
        T_FAULT,
        T_CLEAR,
        tstep,
        1e-8,
        before_setup=scaled if vt_limits else None,
        keep=keep,
    )
    ss = keep[0]
    out = {"t": t, "d": d, "buses": keys, "tds_s": secs, "reached_t_end": done}
    if vt_limits:  # the limiter's bounds did move: the lowest ceiling reached
        lim = np.asarray(ss.dae.ts.y)[:, ss.Bus.v.a][
            :, [list(ss.Bus.idx.v).index(b) for b in ss.IEEEX1.bus.v]
        ]
        out["min_ceiling_pu"] = float((lim * np.asarray(ss.IEEEX1.VRMAX.v)).min())
    return out


def diff(case, ts, d, a):
    from vs_andes import compare

    ok = np.isfinite(d).all(axis=1)
    if not ok.any():
        return None
    e = compare(case, ts[ok], d[ok], a["t"], a["d"], a["buses"], t_stop=ts[ok][-1])
    return float(e.max())


def smib_vs_smib(case, ts, d, ts_ref, d_ref):
    from vs_andes import coi

    ok = np.isfinite(d).all(axis=1) & np.isfinite(d_ref).all(axis=1)
    return float(np.abs(coi(case, d[ok]) - coi(case, d_ref[ok])).max())


def jvp_cost(repeat: int = 2000) -> dict:
    """Option (a)'s price: the IEEE 39 vector field (fault on) against the same with
    dVt/dt, the jvp of the network evaluation along dy/dt; best of 15 loops of
    `repeat` calls, microseconds per call (wall)."""
    import jax
    from vs_andes import T_CLEAR, T_FAULT, XF, case_path, smib_setup

    from smibjax.grid.events import BusFault
    from smibjax.grid.loop import evaluate
    from smibjax.grid.network import stage_configs, stage_matrices

    case, op = smib_setup(case_path(RAW), case_path(DYR))
    ev = (
        BusFault(
            bus=case.system.bus_index(BUS), t_on=T_FAULT, t_off=T_CLEAR, r=0.0, x=XF
        ),
    )
    mats = stage_matrices(op.grid, stage_configs(op.grid, ev), ev)
    y = op.y0 + 1e-3 * np.sin(np.arange(op.y0.size))

    @jax.jit
    def f(y):
        return evaluate(case, op, mats, 1, y)[0]

    @jax.jit
    def f_dvt(y):
        dy = evaluate(case, op, mats, 1, y)[0]
        vt = jax.jvp(lambda z: evaluate(case, op, mats, 1, z)[1]["Vt"], (y,), (dy,))
        return dy, vt[1]

    def best(g):
        jax.block_until_ready(g(y))
        out = np.inf
        for _ in range(15):
            t0 = time.perf_counter()
            for _ in range(repeat):
                r = g(y)
            jax.block_until_ready(r)
            out = min(out, (time.perf_counter() - t0) / repeat)
        return out * 1e6

    a, b = best(f), best(f_dvt)
    print(f"  vector field {a:.1f} us, with dVt/dt by jvp {b:.1f} us ({b / a:.2f}x)")
    return {"vector_field_us": a, "with_dvt_dt_us": b, "ratio": b / a}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtols", type=float, nargs="+", default=[1e-6, 1e-8, 1e-10])
    ap.add_argument("--andes-tsteps", type=float, nargs="+", default=[0.005, 0.002])
    ap.add_argument("--sweeps", type=float, nargs="+", default=[30.0])
    ap.add_argument(
        "--stale-rtols",
        type=float,
        nargs="*",
        default=[1e-6, 1e-8],
        help="rtols for main 0bbe1d7's held rule (none: skip it)",
    )
    ap.add_argument(
        "--jvp-only", action="store_true", help="only the cost of dVt/dt (option a)"
    )
    ap.add_argument("--tag", default="")
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args(argv)

    from smibjax import configure

    configure(min_devices=1, cache=False)
    from _results import write_results

    if args.jvp_only:
        res = {"load_average_start": list(os.getloadavg()), "jvp_cost": jvp_cost()}
        res["load_average_end"] = list(os.getloadavg())
        name = f"exdc2_limits_{args.tag or 'jvp'}"
        write_results(args.out, name, vars(args), res)
        print(f"wrote {Path(args.out) / name}.json")
        return
    import andes
    from vs_andes import case_path

    res = {"andes": andes.__version__, "load_average_start": list(os.getloadavg())}
    res["fault"] = (
        "IEEE 39 bus 16, through j 1e-4 pu, 1.0-1.1 s, 10 s; max over 10 s and over "
        "machines of |COI angle difference| (rad)"
    )
    res["andes_variants"] = {
        "IEEEX1": "ANDES 2.0.0's IEEEX1 as shipped: its limiter keeps VRMAX, VRMIN "
        "(the VRMAX v, VRMIN v it defines are not passed to the limiter), so its "
        "limits are constant",
        "IEEEX1_vt": "ANDES's IEEEX1 with its lag's limiter pointed at VRTMAX = VRMAX v, "
        "VRTMIN = VRMIN v (patched in this run): moving limits, reset to the limit "
        "(AntiWindup)",
        "EXDC2": "the IEEEX1 records renamed EXDC2: ANDES 2.0 EXDC2, constant limits "
        "VRMAX, VRMIN, output Efd = omega * vp (multiplied by the speed)",
    }
    raw, dyr = case_path(RAW), case_path(DYR)
    hs = args.andes_tsteps
    with tempfile.TemporaryDirectory() as tmp:
        dyr_exdc2 = renamed(dyr, "IEEEX1", "EXDC2", tmp)
        an = {}
        for h in hs:
            an[("IEEEX1", h)] = andes_ieee39(raw, dyr, h)
            an[("IEEEX1_vt", h)] = andes_ieee39(raw, dyr, h, vt_limits=True)
            an[("EXDC2", h)] = andes_ieee39(raw, dyr_exdc2, h)
            print(f"ANDES at {h * 1e3:g} ms done", flush=True)
        res["andes_runs"] = {
            f"{k} {h * 1e3:g} ms": {
                kk: vv for kk, vv in a.items() if kk not in ("t", "d", "buses")
            }
            for (k, h), a in an.items()
        }

        def against(case, ts, d):
            return {
                f"{k} {h * 1e3:g} ms": diff(case, ts, d, a) for (k, h), a in an.items()
            }

        runs = []
        plan = [("EXDC2", "sweep", sw, r) for sw in args.sweeps for r in args.rtols]
        plan += [("EXDC2", "stale", args.sweeps[0], r) for r in args.stale_rtols]
        plan += [("IEEEX1", "constant", args.sweeps[0], min(args.rtols))]
        for model, rule, sweep, rtol in plan:
            path = dyr_exdc2 if model == "EXDC2" else dyr
            case, ts, d, f = smib_fresh(raw, path, rtol, rule, sweep)
            f["smibjax_model"] = model
            if rule == "constant":
                f["rule"] = "constant limits (held)"
                f["sweep"] = None
            ok = np.isfinite(d).all(axis=1)
            f["t_reached_s"] = float(ts[ok][-1]) if ok.any() else 0.0
            # an exhausted run stops early: no difference over 10 s to report
            f["max_abs_coi_diff_rad_vs_andes"] = (
                None if f["exhausted"] else against(case, ts, d)
            )
            f["_traj"] = (ts, d)
            runs.append(f)
            best = {
                k: round(v, 4)
                for k, v in (f["max_abs_coi_diff_rad_vs_andes"] or {}).items()
            }
            print(
                f"  {model} {rule} sweep {f['sweep']} rtol {rtol:g}: {f['steps']} "
                f"steps, exhausted {f['exhausted']} at {f['t_reached_s']:.3f} s, "
                f"vs ANDES {best}",
                flush=True,
            )
        # each run against its rule's tightest completed run (its own convergence)
        for f in runs:
            same = [
                g
                for g in runs
                if (g["smibjax_model"], g["rule"], g["sweep"])
                == (f["smibjax_model"], f["rule"], f["sweep"])
                and not g["exhausted"]
            ]
            ref = min(same, key=lambda g: g["rtol"]) if same else None
            if ref is not None and ref is not f and not f["exhausted"]:
                f["vs_own_tightest_rad"] = smib_vs_smib(
                    case, *f["_traj"], *ref["_traj"]
                )
                f["own_tightest_rtol"] = ref["rtol"]
        # every EXDC2 run against the reference: the sweeping rule with the largest
        # SWEEP (the closest to integrate-then-clamp) at the tightest rtol
        sweeps = [g for g in runs if g["rule"] == "sweep" and not g["exhausted"]]
        if sweeps:
            ref = max(sweeps, key=lambda g: (g["sweep"], -g["rtol"]))
            res["reference_run"] = {"sweep": ref["sweep"], "rtol": ref["rtol"]}
            for f in runs:
                if f["smibjax_model"] == "EXDC2" and not f["exhausted"]:
                    f["vs_reference_rad"] = smib_vs_smib(
                        case, *f["_traj"], *ref["_traj"]
                    )
        for f in runs:
            f.pop("_traj")
        res["smibjax_runs"] = runs
    res["load_average_end"] = list(os.getloadavg())
    name = f"exdc2_limits_{args.tag}" if args.tag else "exdc2_limits"
    write_results(args.out, name, vars(args), res)
    print(f"wrote {Path(args.out) / name}.json")


if __name__ == "__main__":
    main()
