"""Nonlinear loads against the impedance path (issue 47): scenarios per second of a
batch of bus faults on Kundur and IEEE 39, with every load a constant impedance (the
linear network, one matrix-vector product per evaluation) and with ZIP loads (the
Newton solve on the load buses), side by side in one run.

Per case (the built-in `kundur` and `ieee39`, their dyr files' machines and controls)
and load model: a batch of `--n` scenarios, each a fault through j1e-4 pu at one bus
(cycling over the buses), cleared after 50 to 150 ms, `--t-end` s saved every 10 ms,
Tsit5 at rtol 1e-6, atol 1e-8 (`simulate_batch`); the first call (compile + run) and
the best of `--repeat` warm calls, wall and process CPU seconds, scenarios/s warm, the
stable count and the mean number of steps. The ZIP model is PSS/E-like: P 40 %
constant power, 30 % current, 30 % impedance; Q 20/30/50; PQBRAK 0.7. Target: the
ZIP batch keeps at least half the impedance batch's scenarios/s.

    python benchmarks/loads_batch.py                     # kundur, ieee39; n 64
    python benchmarks/loads_batch.py --cases kundur --n 8 --t-end 2 --tag tiny

Writes benchmarks/results/loads_batch.json (loads_batch_TAG.json with --tag), with
the load averages before and after: the 2 cores are shared, so wall figures are
loaded ones; CPU seconds are given too.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ZIP = "p=0.4,0.3,0.3 q=0.2,0.3,0.5"


def _events(case, n: int):
    import jax.numpy as jnp
    import numpy as np

    from smibjax.grid.events import BusFault

    fixed = set(int(b) for b in np.asarray(case.layout.source_bus))
    buses = [b for b in range(case.system.n_bus) if b not in fixed]
    pick = np.array([buses[k % len(buses)] for k in range(n)])
    clear = 1.0 + np.linspace(0.05, 0.15, n)
    return (
        BusFault(
            bus=jnp.asarray(pick),
            t_on=1.0,
            t_off=jnp.asarray(clear),
            r=0.0,
            x=1e-4,
        ),
    )


def _one(case_name: str, model: str | None, n: int, t_end: float, repeat: int):
    import jax
    import numpy as np

    from smibjax.grid.case import load_case
    from smibjax.grid.loads import parse_load_model, with_load_model
    from smibjax.grid.operating import operating_point
    from smibjax.grid.simulate import simulate_batch

    case = load_case(case_name)
    case = with_load_model(case, None if model is None else parse_load_model(model))
    op, _ = operating_point(case)
    ev = _events(case, n)
    kw = dict(t_end=t_end, dt_save=0.01)

    def run():
        tr = simulate_batch(case, op, ev, **kw)
        jax.block_until_ready(tr.delta)
        return tr

    w0, c0 = time.perf_counter(), time.process_time()
    tr = run()
    first = (time.perf_counter() - w0, time.process_time() - c0)
    warm = []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        run()
        warm.append((time.perf_counter() - w0, time.process_time() - c0))
    wall, cpu = min(w for w, _ in warm), min(c for _, c in warm)
    return {
        "case": case_name,
        "loads": model or "impedance",
        "injector_ports": len(case.layout.inj_ports),
        "n": n,
        "first_wall_s": round(first[0], 3),
        "first_cpu_s": round(first[1], 3),
        "warm_wall_s": round(wall, 3),
        "warm_cpu_s": round(cpu, 3),
        "scenarios_per_s": round(n / wall, 3),
        "scenarios_per_cpu_s": round(n / cpu, 3),
        "stable": int(np.sum(np.asarray(tr.stable))),
        "collapsed": int(np.sum(np.asarray(tr.collapsed))),
        "mean_steps": float(np.mean(np.asarray(tr.n_steps))),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["kundur", "ieee39"])
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--t-end", type=float, default=5.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--tag", default="")
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args(argv)
    from smibjax._process import configure

    configure(min_devices=1, host_devices=False)
    import jax

    jax.config.update("jax_enable_x64", True)
    sys.path.insert(0, str(HERE))
    from _results import write_results

    load0 = os.getloadavg()
    rows = []
    for name in args.cases:
        for model in (None, ZIP):
            r = _one(name, model, args.n, args.t_end, args.repeat)
            rows.append(r)
            print(
                f"{name:8s} {r['loads']:28s} ports {r['injector_ports']:3d}  "
                f"{r['scenarios_per_s']:8.2f} scen/s warm ({r['warm_cpu_s']:.1f} CPU-s)"
                f"  first {r['first_wall_s']:.1f} s  stable {r['stable']}/{r['n']}"
                f"  steps {r['mean_steps']:.0f}",
                flush=True,
            )
    ratios = {}
    for name in args.cases:
        z, p = (
            next(r for r in rows if r["case"] == name and r["loads"] == m)
            for m in ("impedance", ZIP)
        )
        ratios[name] = {
            "wall": round(p["scenarios_per_s"] / z["scenarios_per_s"], 3),
            "cpu": round(p["scenarios_per_cpu_s"] / z["scenarios_per_cpu_s"], 3),
        }
        print(
            f"{name}: ZIP / impedance scenarios/s = {ratios[name]['wall']:.2f} "
            f"(CPU {ratios[name]['cpu']:.2f}); target >= 0.5"
        )
    config = vars(args) | {"zip": ZIP}
    payload = {"rows": rows, "ratio": ratios, "loadavg": [load0, os.getloadavg()]}
    name = "loads_batch" + (f"_{args.tag}" if args.tag else "")
    print(f"wrote {write_results(args.out, name, config, payload)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
