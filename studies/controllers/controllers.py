"""The comparison a reader wants (issue 14): under the realistic input limits, no
control, the conventional AVR + PSS + SVC regulator (textbook parameters) and any
tuned controller (gains files, with their context), on one Monte Carlo draw of the
default scenario distribution with D drawn in [0.1, 0.4], critical clearing times at
five fault locations (criteria synchronism and settled), and their trajectories on
the paper's fault.

    python studies/controllers/controllers.py [--n 10000] [--gains LABEL:FILE ...]
        [--work DIR]

Writes studies/controllers/controllers.json (per controller: Monte Carlo summary,
effort, peak Vt and commanded inputs, CCT, the paper's fault), controllers.md (the
table) and docs/figures/controllers_paper_fault.png. `--work DIR` keeps each
controller's finished results there and reuses them on a rerun with the same
--n (a long run that is interrupted loses only the controller in progress).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _results

from smibjax._process import configure, enable_compilation_cache

configure(cache=False)

import numpy as np
from _results import write_results

import smibjax as sj
from smibjax._cct import critical_clearing_times
from smibjax._files import read_gains_file, write_text
from smibjax._metrics import PHYSICS, metrics
from smibjax._montecarlo import MonteCarloSpec, compute_chunk, summarize
from smibjax._scenarios import ScenarioDistribution
from smibjax.cli.plotting import save_figure
from smibjax.controllers import Synergetic, make_controller

LOCATIONS = (0.1, 0.3, 0.5, 0.7, 0.9)


def _work_name(label: str, n: int) -> str:
    safe = "".join(c if c.isalnum() else "_" for c in label)
    return f"{safe}_n{n}.json"


def _cached(work, label, n, name, gains, options, adaptation):
    """The finished results of `label` in `work` for the same controller, or None."""
    if work is None or not (work / _work_name(label, n)).is_file():
        return None
    done = json.loads((work / _work_name(label, n)).read_text())
    same = (name, gains, options, adaptation)
    return done if same == tuple(done[k] for k in _KEY) else None


_KEY = ("controller", "gains", "options", "adaptation")


def _extra(rows) -> dict:
    """What `summarize` leaves out: effort (integral of u_f^2 + u_r^2, pu^2 s), the
    peak SVC-bus voltage, the commanded inputs' peaks (before limits) and the time on
    a limit, as means and 95th percentiles over all scenarios."""
    effort = rows["effort_uf"] + rows["effort_ur"]
    out = {"effort_mean": float(np.mean(effort))}
    for k in ("Vt_max", "peak_uf_cmd", "peak_ur_cmd", "limit_time_uf", "tv_uf"):
        v = np.asarray(rows[k], dtype=float)
        out[f"{k}_mean"] = float(np.mean(v))
        out[f"{k}_p95"] = float(np.percentile(v, 95))
    for k in ("limit_time_ur", "tv_ur"):
        out[f"{k}_mean"] = float(np.mean(np.asarray(rows[k], dtype=float)))
    return out


def _print_row(label, v) -> None:
    mc, cct = v["montecarlo"], v["cct"]
    s = mc["settling_time"]
    print(
        f"{label:34} stable {100 * mc['stable_fraction']:6.2f}%  settling mean "
        f"{s.get('mean', float('nan')):.3f} p95 {s.get('p95', float('nan')):.3f} s  "
        f"TV u_f {mc['physics']['tv_uf_mean']:.1f}  MC {mc['seconds']:.0f} s  CCT "
        f"synchronism {cct['synchronism']['cct']}  settled {cct['settled']['cct']}",
        flush=True,
    )


def _cct_cell(c) -> str:
    return " / ".join(">1.5" if x is None else f"{x:.3f}" for x in c["cct"])


def table_markdown(payload) -> str:
    """Two markdown tables: the Monte Carlo (stable fraction, settling, overshoot,
    effort, chatter, peak Vt, commanded peaks, time on a limit) and the CCT."""
    n, sets = payload["n"], payload["sets"]
    head = (
        f"| controller ({n:,} scenarios) | stable | settling mean / p95 (s) | "
        "overshoot mean (rad) | effort mean (pu^2 s) | TV u_f / u_r mean (pu) | "
        "peak Vt p95 / max (pu) | peak commanded u_f / u_r p95 (pu) | "
        "time on limit u_f / u_r (mean) |"
    )
    rows = [head, "|" + "---|" * 9]
    for label, v in sets.items():
        mc, e = v["montecarlo"], v["montecarlo"]["extra"]
        s, ph = mc["settling_time"], mc["physics"]
        rows.append(
            f"| {label} | {100 * mc['stable_fraction']:.2f}% | "
            f"{s.get('mean', float('nan')):.2f} / {s.get('p95', float('nan')):.2f} | "
            f"{mc['overshoot'].get('mean', float('nan')):.3f} | "
            f"{e['effort_mean']:.1f} | {ph['tv_uf_mean']:.1f} / "
            f"{ph['tv_ur_mean']:.2f} | {e['Vt_max_p95']:.3f} / {ph['Vt_max']:.3f} | "
            f"{e['peak_uf_cmd_p95']:.3g} / {e['peak_ur_cmd_p95']:.3g} | "
            f"{ph['limit_time_uf_mean']:.3f} / {ph['limit_time_ur_mean']:.3f} |"
        )
    locs = " / ".join(f"{x:g}" for x in payload["locations"])
    rows += [
        "",
        f"| controller | CCT synchronism at {locs} (s) | CCT settled (s) |",
        "|---|---|---|",
    ]
    for label, v in sets.items():
        rows.append(
            f"| {label} | {_cct_cell(v['cct']['synchronism'])} | "
            f"{_cct_cell(v['cct']['settled'])} |"
        )
    return "\n".join(rows)


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
    ap.add_argument("--out", default=str(HERE))
    ap.add_argument("--work", help="folder of finished per-controller results")
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
    work = Path(args.work) if args.work else None
    for label, (name, gains, adaptation, options, ctrl) in sets.items():
        cached = _cached(work, label, args.n, name, gains, options, adaptation)
        if cached is not None:
            results[label] = {
                **cached,
                "paper_fault": sj.simulate(ctrl, sj.Fault(), plant),
            }
            _print_row(label, results[label])
            continue
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
        mc["extra"] = _extra(rows)
        t0 = time.perf_counter()
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
                "cct": r.sets[label].cct,
                "status": r.sets[label].status,
            }
        cct["seconds"] = time.perf_counter() - t0
        tr = sj.simulate(ctrl, sj.Fault(), plant)
        m = metrics(tr)
        done = {
            "controller": name,
            "adaptation": adaptation,
            "options": options,
            "gains": gains,
            "montecarlo": mc,
            "cct": cct,
            "paper_fault_metrics": {
                k: float(m._asdict()[k])
                for k in ("settling_delta", "overshoot", *PHYSICS[:6], "Vt_max")
            },
        }
        if work is not None:
            work.mkdir(parents=True, exist_ok=True)
            write_text(
                work / _work_name(label, args.n),
                json.dumps(done, indent=1, default=str),
            )
        results[label] = {**done, "paper_fault": tr}
        _print_row(label, results[label])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    payload = {
        k: {kk: vv for kk, vv in v.items() if kk != "paper_fault"}
        for k, v in results.items()
    }
    payload = {"n": args.n, "locations": list(LOCATIONS), "sets": payload}
    payload = json.loads(json.dumps(payload, default=str))
    config = {"n": args.n, "chunk": args.chunk, "gains": args.gains, "limits": limits}
    write_results(out, "controllers", config, payload)
    write_text(out / "controllers.md", table_markdown(payload) + "\n")
    print(table_markdown(payload))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(5, 1, figsize=(8, 11), sharex=True)
    styles = ["-", "--", "-.", ":"]
    for i, (label, v) in enumerate(results.items()):
        tr = v["paper_fault"]
        t = np.asarray(tr.t)
        kw = dict(label=label, ls=styles[i % len(styles)], lw=1.2)
        ax[0].plot(t, np.asarray(tr.delta), **kw)
        ax[1].plot(t, np.asarray(tr.Vt), **kw)
        ax[2].plot(t, np.asarray(tr.u_f), **kw)
        ax[3].plot(t, np.asarray(tr.u_r), **kw)
        ax[4].plot(t, np.asarray(tr.B), **kw)
    names = ("delta (rad)", "Vt (pu)", "u_f applied (pu)", "u_r applied (pu)", "B (pu)")
    for a, y in zip(ax, names, strict=True):
        a.set_ylabel(y)
        a.grid(alpha=0.3)
    ax[0].legend(fontsize=8)
    ax[-1].set_xlim(0.0, 5.0)  # settled after 5 s
    ax[-1].set_xlabel("t (s)")
    fig.suptitle("Paper's fault under the realistic limits (D = 0.2)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, ROOT / "docs" / "figures" / "controllers_paper_fault.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
