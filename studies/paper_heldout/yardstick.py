"""Which yardstick gives "about 1.8 s for bfd8280" (issue 33)? The mean delta settling
(s) of gains files on the 1,024 held-out draws (seed 777) of paper.toml's scenario
distribution, under today's definition (0.01 rad band, last exit after fault
inception, interpolated: bfd8280's definition too) and under alternatives: measured
from clearing, a 0.02 rad band, and the same faults with the reclose 0.5 s earlier
(reclose delay 0.5-2.0 s instead of 1.0-2.5 s). Runs: the validation's solver
(adaptive Tsit5, rtol 1e-6, atol 1e-8, 50,000 steps), 10 s sampled every 5 ms.
Writes yardstick.json here.

    python studies/paper_heldout/yardstick.py [GAINS.json ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from smibjax import configure

configure()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import smibjax as sj  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the tuning package

from _cli import gains_args  # noqa: E402

from tuning.config import CONFIG_DIR, load_config  # noqa: E402
from tuning.problem import build, validation_scenarios  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
DT = 0.005  # s, sampling of the trajectories


def settling(t, dev, band, t_from):
    """Last time (s, from `t_from`) at which dev > band for t >= t_from, the exit
    interpolated linearly between samples; 0 if never outside, inf if outside at the
    end (the rule of smibjax's metrics, in NumPy, per row)."""
    out = np.empty(dev.shape[0])
    for i in range(dev.shape[0]):
        outside = np.nonzero((dev[i] > band) & (t >= t_from[i]))[0]
        if outside.size == 0:
            out[i] = 0.0
            continue
        j = outside[-1]
        if j == t.size - 1:
            out[i] = np.inf
            continue
        d0, d1 = dev[i, j], dev[i, j + 1]
        frac = np.clip((d0 - band) / (d0 - d1), 0.0, 1.0) if d0 > d1 else 0.0
        out[i] = max(t[j] + frac * (t[j + 1] - t[j]) - t_from[i], 0.0)
    return out


def runs(gains_file: Path, faults: sj.Fault):
    """(t, |delta - delta_e| per fault, stable per fault) of the gains on `faults`."""
    cfg = load_config(CONFIG_DIR / "paper.toml")
    cfg["init"] = str(gains_file)
    problem = build(cfg)
    s = problem.setup
    ctrl = s.controller_of(problem.space.to_gains(problem.space.to_raw(problem.init)))
    solver = sj.SolverOptions()  # the validation engine's
    save = sj.SaveOptions(t_end=10.0, dt_save=DT)

    @jax.jit
    def one(f):
        tr = sj.simulate(ctrl, f, s.plant, solver=solver, save=save)
        return tr.t, jnp.abs(tr.delta - tr.delta_e), tr.stable

    t, dev, stable = jax.lax.map(one, faults, batch_size=64)
    return np.asarray(t[0]), np.asarray(dev), np.asarray(stable)


def summary(ts, stable):
    """Mean and p95 (s) over the stable runs, and the stable fraction."""
    x = ts[stable & np.isfinite(ts)]
    return {
        "stable_fraction": float(stable.mean()),
        "mean": float(x.mean()),
        "p95": float(np.quantile(x, 0.95)),
    }


def main() -> None:
    files = gains_args(sys.argv[1:], __doc__)[0] or [
        HERE / "bfd8280_gains.json",
        HERE / "paper_grad_gains.json",
    ]
    cfg = load_config(CONFIG_DIR / "paper.toml")
    cfg["validation"].update(seed=777, n=1024)
    faults, _ = validation_scenarios(cfg, build(cfg))
    early = sj.Fault(
        faults.t_fault,
        faults.t_clear,
        faults.t_reclose - 0.5,
        faults.lam,
        faults.Xf,
    )
    tf, tc = np.asarray(faults.t_fault), np.asarray(faults.t_clear)
    out = {}
    for f in files:
        t, dev, stable = runs(f, faults)
        rows = {
            "today (0.01 rad, from inception)": settling(t, dev, 0.01, tf),
            "from clearing": settling(t, dev, 0.01, tc),
            "0.02 rad band": settling(t, dev, 0.02, tf),
        }
        res = {k: summary(v, stable) for k, v in rows.items()}
        t, dev, stable = runs(f, early)
        res["reclose 0.5 s earlier"] = summary(settling(t, dev, 0.01, tf), stable)
        out[f.name] = res
        for k, v in res.items():
            print(
                f"{f.name:26} {k:34} {100 * v['stable_fraction']:.1f}% stable, "
                f"mean {v['mean']:.3f} s, p95 {v['p95']:.3f} s",
                flush=True,
            )
    (HERE / "yardstick.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
