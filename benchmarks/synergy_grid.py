"""The paper's law in a network (issue 30, stretch item 3): the decentralized
synergetic exciter (`SYNEX`, src/smibjax/grid/devices/synex.py) on all four machines
of Kundur's two-area system (`kundur-synex`: GENROU + SYNEX + TGOV1) against the
textbook PSSs and the gradient-tuned PSSs of benchmarks/tuning_grid.py
(`kundur`: GENROU + SEXS + IEEEST + TGOV1), on the same held-out Monte Carlo as
benchmarks/tuning_grid.py (the config's fault distribution and load range, `--n`
scenarios, seed `--seed`).

Judged as in benchmarks/tuning_grid.py (`tuning.grid_run.validate`): stable
fraction, mean and p95 settling of the COI angles and COI-referred speeds (inf where
a scenario never settles or is unstable), worst damping ratio of the
electromechanical, inter-area and 0.05-5 Hz oscillatory modes over the config's
`validation.load_factors` (`smibjax.grid.modes`: the linearization differentiates
the SYNEX law; with ALPHA < 1 the law's slope at phi = 0 is infinite and the
linearization uses the floored slope of `spow`, so those damping ratios describe a
very high-gain linear loop, not the finite-time law), and the peak field voltage.

The SYNEX sets: the paper's AFTSC and ASC gains (BETA = 50, T1 = 0.005, ALPHA = 5/7
or 1, C = 1), and the same law with a stable sliding manifold (BETA < 0,
docs/model.md section 2) at a few values of BETA; with `--tune N`, also the grid
tuner's gradient run of N steps (the PSS config's batch, loss and damping target) on
SYNEX.BETA, T1, ALPHA and C (one value each, shared by the four devices) from
BETA = -5, T1 = 0.005, ASC, C = 1.

    python benchmarks/synergy_grid.py [--n 64] [--seed 2026] [--tune 0]

Every set with all held-out faults stable also gets its critical clearing times at
`--cct-buses` (default 5, 8, 11, as benchmarks/tuning_grid.py: load factor 1, bolted
bus fault at 0.5 s, no tripping, bisection to 5 ms in [0, 1] s).

Prints a table and writes benchmarks/results/synergy_grid_kundur.json.
"""

from __future__ import annotations

from smibjax import configure

configure()

import argparse  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from _results import write_results  # noqa: E402
from tuning_grid import KEYS as GRID_KEYS  # noqa: E402
from tuning_grid import cct_of, print_table  # noqa: E402

from tuning.grid_config import check_grid_config, load_grid_config  # noqa: E402
from tuning.grid_problem import build_grid  # noqa: E402
from tuning.grid_run import _validation_fn, run_grid, validate  # noqa: E402

KEYS = (*GRID_KEYS, "efd_max")

# (label, BETA, T1, ALPHA, C): the paper's gains, then BETA < 0 (a stable
# manifold), then the weighted macro-variable C > 1 (docs/model.md section 2)
SYNEX_SETS = (
    ("SYNEX paper AFTSC (BETA = 50)", 50.0, 0.005, 5.0 / 7.0, 1.0),
    ("SYNEX paper ASC (BETA = 50)", 50.0, 0.005, 1.0, 1.0),
    ("SYNEX AFTSC, BETA = -1", -1.0, 0.005, 5.0 / 7.0, 1.0),
    ("SYNEX AFTSC, BETA = -5", -5.0, 0.005, 5.0 / 7.0, 1.0),
    ("SYNEX ASC, BETA = -1", -1.0, 0.005, 1.0, 1.0),
    ("SYNEX ASC, BETA = -5", -5.0, 0.005, 1.0, 1.0),
    ("SYNEX ASC, BETA = -20", -20.0, 0.005, 1.0, 1.0),
    ("SYNEX AFTSC, BETA = -5, C = 5", -5.0, 0.005, 5.0 / 7.0, 5.0),
    ("SYNEX ASC, BETA = -5, C = 5", -5.0, 0.005, 1.0, 5.0),
    ("SYNEX ASC, BETA = -2, C = 5", -2.0, 0.005, 1.0, 5.0),
)


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def raw_of(space, values: dict) -> dict:
    """The raw parameters of {name: value} (every trained name)."""
    return space.to_raw([float(values[n]) for n in space.names])


def synex_config(cfg: dict, steps: int = 1, start: dict | None = None) -> dict:
    """The PSS config's scenarios, loss and validation on `kundur-synex`, training
    SYNEX.BETA, SYNEX.T1, SYNEX.ALPHA and SYNEX.C (one value each, shared by the four
    devices; linear in BETA and ALPHA, log in T1 and C), starting from BETA = -5,
    T1 = 0.005, ASC, C = 1."""
    out = copy.deepcopy(cfg)
    out["steps"] = max(int(steps), 1)
    out["case"] = {
        "name": "kundur-synex",
        "raw": "",
        "dyr": "",
        "set": {
            "TGOV1.VMAX": 1.1,
            "SYNEX.BETA": -5.0,
            "SYNEX.T1": 0.005,
            "SYNEX.ALPHA": 1.0,
            "SYNEX.C": 1.0,
            **(start or {}),
        },
    }
    out["gains"] = {
        "names": ["SYNEX.BETA", "SYNEX.T1", "SYNEX.ALPHA", "SYNEX.C"],
        "per_device": False,
        "bounds": {
            "SYNEX.BETA": [-100.0, 100.0],
            "SYNEX.T1": [1e-3, 1.0],
            "SYNEX.ALPHA": [0.51, 1.0],
            "SYNEX.C": [0.1, 20.0],
        },
        "transform": {
            "SYNEX.BETA": "linear",
            "SYNEX.T1": "log",
            "SYNEX.ALPHA": "linear",
            "SYNEX.C": "log",
        },
        "tie": {},
    }
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=str(ROOT / "tuning/configs/kundur_pss.toml"))
    p.add_argument(
        "--pss-result",
        default=str(ROOT / "benchmarks/results/tuning_grid_kundur.json"),
        help="benchmarks/tuning_grid.py's result: its tuned PSS gains",
    )
    p.add_argument("--n", type=int, default=64, help="held-out scenarios")
    p.add_argument("--seed", type=int, default=2026, help="held-out seed")
    p.add_argument("--tune", type=int, default=0, help="gradient steps on SYNEX")
    p.add_argument(
        "--tune-start",
        default="",
        help="start values of the tuning other than BETA = -5, T1 = 0.005, "
        "ALPHA = 1, C = 1, e.g. C=5,BETA=-3",
    )
    p.add_argument(
        "--cct-buses",
        default="5,8,11",
        help="fault buses of the CCTs of every set with 100%% stable held-out "
        "faults (as benchmarks/tuning_grid.py; empty: none)",
    )
    p.add_argument("--out", default=str(ROOT / "benchmarks/results"))
    args = p.parse_args(argv)
    try:
        buses = [int(b) for b in args.cct_buses.split(",") if b.strip()]
    except ValueError:
        print(f"--cct-buses {args.cct_buses!r}: not bus numbers", file=sys.stderr)
        return 2
    start = {}
    for item in filter(None, args.tune_start.split(",")):
        name, _, value = item.partition("=")
        try:
            start[f"SYNEX.{name.strip().upper()}"] = float(value)
        except ValueError:
            print(f"--tune-start {item!r}: not NAME=NUMBER", file=sys.stderr)
            return 2
        if name.strip().upper() not in ("BETA", "T1", "ALPHA", "C"):
            print(
                f"--tune-start {item!r}: NAME must be BETA, T1, ALPHA or C",
                file=sys.stderr,
            )
            return 2

    cfg = load_grid_config(args.config)
    check_grid_config(cfg)
    held_cfg = {**cfg, "validation": {**cfg["validation"], "n": args.n}}
    pss = build_grid(held_cfg)
    held = pss.batch(0, n=args.n, seed=args.seed)
    rows, timing, gains, raws = {}, {}, {}, {}

    t0, c0 = time.perf_counter(), cpu_seconds()
    val = _validation_fn(pss)
    tuned = json.loads(Path(args.pss_result).read_text())["gains"]["gradient (tuned)"]
    textbook = dict(zip(pss.space.names, pss.space.start, strict=True))
    for label, values in (
        ("textbook PSS", textbook),
        ("tuned PSS (gradient, tuning_grid.py)", tuned),
    ):
        raws[label] = (pss, raw_of(pss.space, values))
        rows[label] = validate(pss, raws[label][1], val, held)
        gains[label] = {n: float(values[n]) for n in pss.space.names}
        print(f"{label}: {rows[label]}", file=sys.stderr, flush=True)
    timing["pss_sets"] = {
        "wall_s": time.perf_counter() - t0,
        "cpu_s": cpu_seconds() - c0,
    }

    syn_cfg = synex_config(held_cfg, args.tune, start)
    check_grid_config(syn_cfg)
    syn = build_grid(syn_cfg)
    t0, c0 = time.perf_counter(), cpu_seconds()
    sval = _validation_fn(syn)
    for label, beta, t1, alpha, c in SYNEX_SETS:
        values = {
            "SYNEX.BETA": beta,
            "SYNEX.T1": t1,
            "SYNEX.ALPHA": alpha,
            "SYNEX.C": c,
        }
        raws[label] = (syn, raw_of(syn.space, values))
        rows[label] = validate(syn, raws[label][1], sval, held)
        gains[label] = values
        print(f"{label}: {rows[label]}", file=sys.stderr, flush=True)
    timing["synex_sets"] = {
        "wall_s": time.perf_counter() - t0,
        "cpu_s": cpu_seconds() - c0,
    }
    tuning_start = ", ".join(
        f"{n.split('.')[1]} = {syn_cfg['case']['set'][n]:g}" for n in syn.space.names
    )
    if args.tune > 0:
        t0, c0 = time.perf_counter(), cpu_seconds()
        with tempfile.TemporaryDirectory() as tmp:
            syn_train, state = run_grid(syn_cfg, Path(tmp), quiet=False)
        timing["synex_tuning"] = {
            "wall_s": time.perf_counter() - t0,
            "cpu_s": cpu_seconds() - c0,
            "steps": args.tune,
            "batch": syn_cfg["batch"],
            "best_step": state.best.step,
        }
        label = f"SYNEX tuned ({args.tune} gradient steps from {tuning_start})"
        values = {k: float(v) for k, v in syn.space.values(state.best.raw).items()}
        raws[label] = (syn, state.best.raw)
        rows[label] = validate(syn, state.best.raw, sval, held)
        gains[label] = values
        print(f"{label}: {values} {rows[label]}", file=sys.stderr, flush=True)

    t0, c0 = time.perf_counter(), cpu_seconds()
    for label, (problem, raw) in raws.items():
        if buses and rows[label]["stable_fraction"] == 1.0:
            rows[label]["cct"] = cct_of(problem, raw, buses)
            print(f"{label}: CCT {rows[label]['cct']}", file=sys.stderr, flush=True)
    timing["cct"] = {"wall_s": time.perf_counter() - t0, "cpu_s": cpu_seconds() - c0}

    print_table(
        f"kundur: held-out Monte Carlo of {args.n} scenarios (seed {args.seed})",
        rows,
        KEYS,
        buses,
        width=40,
    )
    for k, t in timing.items():
        print(f"{k}: {json.dumps(t)}")
    write_results(
        args.out,
        "synergy_grid_kundur",
        {
            "config": str(Path(args.config).resolve().relative_to(ROOT)),
            "synex_case": "kundur-synex",
            "n_held_out": args.n,
            "held_out_seed": args.seed,
            "tune_steps": args.tune,
            "tune_start": tuning_start,
            "cct_buses": buses,
        },
        {
            "rows": rows,
            "gains": gains,
            "timing": timing,
            "note": "wall times on a shared, loaded 2-core machine; cpu_s is this "
            "process's user+system CPU time; settling inf = some scenario never "
            "settled or was unstable; cct: s at load factor 1 (bolted bus fault at "
            "0.5 s, no tripping), null = stable with a 1 s fault, computed only for "
            "the sets with every held-out fault stable",
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
