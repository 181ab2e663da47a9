"""The paper config's tuned gains on its validation set and on held-out draws of its
scenario distribution (issue 33): for each gains file, the exact validation summary
(stable fraction, mean and p95 delta settling from fault inception (s), mean
overshoot (rad)) on 256 scenarios of seed 1000 (the tuner's validation set) and on
512 (seed 4242) and 1,024 (seed 777) held-out ones, with the floor of the case: the
mean of t_reclose - t_fault (s), the fraction of runs that settle before their line
recloses and the mean settling after the reclose (s); and delta - delta_e (rad) while
the line is out, on the paper's fault with the reclose at 9.5 s. Writes heldout.json
here.

    python studies/paper_heldout/paper_heldout.py [GAINS.json ...]

(default: tests/data/paper_tuned_gains.json and the gains files in this folder)
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from smibjax import configure

configure()

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the tuning package

from _cli import gains_args  # noqa: E402

from tuning.config import CONFIG_DIR, load_config  # noqa: E402
from tuning.problem import build, make_validation, validation_scenarios  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
SETS = (("validation", 1000, 256), ("held-out", 4242, 512), ("held-out", 777, 1024))
LARGE = (("held-out", 31337, 4096),)


def evaluate(gains: Path, seed: int, n: int) -> dict:
    """The summary of `gains` on n scenarios of `seed` drawn as paper.toml's
    validation set is drawn (its distribution, the accurate solver, exact metrics)."""
    cfg = load_config(CONFIG_DIR / "paper.toml")
    cfg["validation"].update(seed=seed, n=n)
    cfg["init"] = str(gains)
    problem = build(cfg)
    v, m = make_validation(cfg, problem)(problem.space.to_raw(problem.init))
    faults, _ = validation_scenarios(cfg, problem)
    reclose = np.asarray(faults.t_reclose) - np.asarray(faults.t_fault)
    ts = np.asarray(m.settling_delta)
    keys = ("stable_fraction", "settling_delta_mean", "settling_delta_p95")
    return {
        **{k: v[k] for k in (*keys, "overshoot_mean")},
        "reclose_floor_mean": float(reclose.mean()),
        "settled_before_reclose": float((ts < reclose).mean()),
        "after_reclose_mean": float(np.mean(ts - reclose)),
    }


def line_out(gains: Path) -> dict:
    """delta - delta_e (rad) at some times (s) of a fault at 0.5 s, cleared at 0.6 s,
    the line reclosed at 9.5 s (location 0.5, bolted), the paper plant."""
    import smibjax as sj

    cfg = load_config(CONFIG_DIR / "paper.toml")
    cfg["init"] = str(gains)
    problem = build(cfg)
    s = problem.setup
    ctrl = s.controller_of(problem.space.to_gains(problem.space.to_raw(problem.init)))
    fault = sj.Fault(0.5, 0.6, 9.5, 0.5, 0.0)
    tr = sj.simulate(ctrl, fault, s.plant, save=sj.SaveOptions(t_end=12.0))
    t = np.asarray(tr.t)
    e = np.asarray(tr.delta) - np.asarray(tr.delta_e)
    times = (0.7, 1.0, 2.0, 4.0, 6.0, 9.0, 9.4, 9.7, 10.0, 11.0, 11.9)
    return {f"{x:g}": float(e[np.searchsorted(t, x)]) for x in times}


def main() -> None:
    files, flags = gains_args(sys.argv[1:], __doc__, ("--large",))
    large = "--large" in flags
    files = files or [
        ROOT / "tests" / "data" / "paper_tuned_gains.json",
        *sorted(HERE.glob("*_gains.json")),
    ]
    path = HERE / "heldout.json"
    out = json.loads(path.read_text()) if path.exists() else {}
    for f in files:
        for name, seed, n in SETS + (LARGE if large else ()):
            t0 = time.perf_counter()
            r = evaluate(f, seed, n)
            out[f"{f.name} {name} seed {seed} n {n}"] = r
            print(
                f"{f.name:28} {name:10} seed {seed:5} n {n:5}: "
                f"{100 * r['stable_fraction']:.1f}% stable, "
                f"{r['settling_delta_mean']:.3f} / {r['settling_delta_p95']:.3f} s; "
                f"floor {r['reclose_floor_mean']:.3f} s, after the reclose "
                f"{r['after_reclose_mean']:.3f} s ({time.perf_counter() - t0:.0f} s)",
                flush=True,
            )
        out[f"{f.name} line out"] = lo = line_out(f)
        print(
            f"{f.name:28} line out: "
            + " ".join(f"{k} s {v:+.4f}" for k, v in lo.items())
        )
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(out, indent=1) + "\n")
        tmp.replace(path)  # after each file: a long run keeps what it finished


if __name__ == "__main__":
    main()
