"""The comparison a reader wants (issue 14): under the realistic input limits, no
control, the conventional AVR + PSS + SVC regulator (textbook parameters) and the
paper's law (tuned gains files, with their context), on one Monte Carlo draw of the
default scenario distribution with D drawn in [0.1, 0.4], critical clearing times at
five fault locations (criteria synchronism and settled), and their trajectories on
the paper's fault.

    python benchmarks/controllers.py [--n 10000] [--gains LABEL:FILE ...]

Writes benchmarks/results/controllers.json, docs/figures/controllers_paper_fault.png.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from smibjax.cli.process import configure_process, enable_compilation_cache

configure_process(cache=False)

import numpy as np

import smibjax as sj
from smibjax.cct import critical_clearing_times
from smibjax.cli.files import read_gains_file
from smibjax.controllers import Synergetic, make_controller
from smibjax.montecarlo import MonteCarloSpec, compute_chunk, summarize
from smibjax.scenarios import ScenarioDistribution

LOCATIONS = (0.1, 0.3, 0.5, 0.7, 0.9)


def _from_file(path):
    """(controller name, parameters, adaptation, options, controller) of a gains
    file with its context."""
    gf = read_gains_file(path)
    ctrl = make_controller(gf.controller, gf.gains)
    if isinstance(ctrl, Synergetic):
        ctrl = Synergetic.from_options(ctrl.gains, gf.adaptation, gf.options)
    return gf.controller, gf.gains, gf.adaptation, gf.options, ctrl


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--chunk", type=int, default=1024)
    ap.add_argument("--gains", nargs="*", default=[], metavar="LABEL:FILE")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args(argv)
    enable_compilation_cache()
    plant = sj.Plant.preset("realistic")
    limits = {
        k: float(getattr(plant, k)) for k in ("uf_min", "uf_max", "ur_min", "ur_max")
    }
    sets = {
        "none": ("none", {}, "oracle", {}, make_controller("none")),
        "avr-pss (textbook)": ("avr-pss", {}, "oracle", {}, make_controller("avr-pss")),
    }
    for item in args.gains:
        label, _, path = item.partition(":")
        sets[label] = _from_file(path)
    dist = ScenarioDistribution.from_dict({"D": [0.1, 0.4]}).to_dict()
    results = {}
    for label, (name, gains, adaptation, options, ctrl) in sets.items():
        spec = MonteCarloSpec(
            n=args.n,
            chunk=min(args.chunk, args.n),
            controller=name,
            gains=gains,
            options=options,
            plant=limits,
            adaptation=adaptation,
            dist=dist,
        )
        t0 = time.perf_counter()
        chunks = [compute_chunk(spec, k) for k in range(spec.n_chunks)]
        rows = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
        mc = summarize(rows)
        mc["seconds"] = time.perf_counter() - t0
        cct = {}
        for criterion in ("synchronism", "settled"):
            r = critical_clearing_times(
                {label: ctrl},
                plant,
                fault_locations=LOCATIONS,
                criterion=criterion,
                adaptation=adaptation,
            )
            cct[criterion] = {
                "cct": r["sets"][label]["cct"],
                "status": r["sets"][label]["status"],
            }
        tr = sj.simulate(ctrl, sj.Fault(), plant)
        results[label] = {"montecarlo": mc, "cct": cct, "paper_fault": tr}
        s = mc["settling_time"]
        print(
            f"{label:28} stable {100 * mc['stable_fraction']:6.2f}%  settling mean "
            f"{s.get('mean', float('nan')):.3f} p95 {s.get('p95', float('nan')):.3f} s  "
            f"TV u_f {mc['physics']['tv_uf_mean']:.1f}  CCT synchronism "
            f"{cct['synchronism']['cct']}  settled {cct['settled']['cct']}",
            flush=True,
        )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    payload = {
        k: {"montecarlo": v["montecarlo"], "cct": v["cct"]} for k, v in results.items()
    }
    (out / "controllers.json").write_text(json.dumps(payload, indent=1, default=str))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    for label, v in results.items():
        tr = v["paper_fault"]
        t = np.asarray(tr.t)
        ax[0].plot(t, np.asarray(tr.delta), label=label)
        ax[1].plot(t, np.asarray(tr.Vt), label=label)
        ax[2].plot(t, np.asarray(tr.u_f), label=label)
        ax[3].plot(t, np.asarray(tr.B), label=label)
    for a, y in zip(
        ax, ("delta (rad)", "Vt (pu)", "u_f applied (pu)", "B (pu)"), strict=True
    ):
        a.set_ylabel(y)
        a.grid(alpha=0.3)
    ax[0].legend(fontsize=8)
    ax[-1].set_xlabel("t (s)")
    fig.suptitle("Paper's fault under the realistic limits (D = 0.2)", fontsize=10)
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "figures" / "controllers_paper_fault.png", dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
