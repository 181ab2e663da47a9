"""Is the training gradient at this point a derivative at all? The default training
step's automatic gradient against central and one-sided differences over a range of
difference steps h, and the one-sided slope of each loss term per scenario (issue 18).

Where the loss is smooth, the central differences converge as h falls (until rounding
takes over near 1e-6) and both one-sided differences agree with them. Where a term has
a kink at this point (a |u(t_k+1) - u(t_k)| of the chatter term through zero, a
settling time that jumps), they do not converge, the two sides differ, and the
automatic gradient is one side's derivative. tests/test_tuning.py's gradient check
under limits sits at the 4 s horizon because of this script's 3 s result.

The setup is that test's: the tiny default config (realistic limits, realizable
adaptation, projection, boundary layer, D drawn, adaptive Tsit5 at rtol 1e-8), the
buildable start (beta1 = beta2 = -1, T1 = 0.02, T2 = 0.5, gamma = 0.5, k = 0), k1, k2,
c1, c2 frozen, --batch faults from PRNGKey(--key). Prints a table and writes
studies/fd_steps/fd_steps[_TAG].json.

    python studies/fd_steps/fd_steps.py [--t-end 3] [--key 7] [--batch 2] [--param NAME]
"""

from __future__ import annotations

import sys
from pathlib import Path

from smibjax import configure

configure(host_devices=False)  # one device: the tests' training step
HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results
sys.path.insert(0, str(ROOT))  # the tuning package

import argparse
import dataclasses

import jax
import numpy as np
from _common import result_name
from _results import write_results

import smibjax as sj
from tuning.config import load_config
from tuning.params import GainSpace, gains_to_dict
from tuning.problem import build
from tuning.train import draw_scenarios, make_train_step

STEPS = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6)
BUILDABLE_START = dict(
    beta1=-1.0, beta2=-1.0, T1=0.02, T2=0.5, gamma1=0.5, gamma2=0.5, k1=0.0, k2=0.0
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=3.0, help="training horizon (s)")
    ap.add_argument("--key", type=int, default=7, help="PRNGKey of the batch")
    ap.add_argument("--batch", type=int, default=2)
    ap.add_argument("--param", help="raw parameter (default: the largest gradient)")
    ap.add_argument("--out", default=str(HERE))
    ap.add_argument("--tag", default="")
    args = ap.parse_args()

    cfg = load_config(None)
    cfg.update(batch=args.batch)
    cfg["train"].update(t_end=args.t_end)
    _, _, setup, dist, _ = build(cfg)
    init = {**gains_to_dict(sj.Gains()), **BUILDABLE_START}
    space = GainSpace.build(init, freeze=["k1", "k2", "c1", "c2"])
    step = make_train_step(dataclasses.replace(setup, space=space))
    faults = draw_scenarios(jax.random.PRNGKey(args.key), args.batch, dist, setup.plant)
    raw = space.to_raw(init)
    loss0, _, terms0, _, grad, _ = step(raw, faults)
    loss0 = float(loss0)
    g = {k: float(v) for k, v in grad.items()}
    name = args.param or max(g, key=lambda k: abs(g[k]))
    if name not in raw:
        ap.error(f"--param {name!r} is not a trainable raw parameter: {sorted(raw)}")

    def at(h):
        out = step({**raw, name: raw[name] + h}, faults)
        return float(out[0]), {k: np.asarray(v) for k, v in out[2].items()}

    rows = []
    print(f"d loss / d raw {name}: automatic {g[name]:.6g} (t_end {args.t_end} s)")
    print(f"{'h':>8} {'central':>12} {'from above':>12} {'from below':>12}")
    for h in STEPS:
        (lp, _), (lm, _) = at(h), at(-h)
        row = {
            "h": h,
            "central": (lp - lm) / (2 * h),
            "from_above": (lp - loss0) / h,
            "from_below": (loss0 - lm) / h,
        }
        rows.append(row)
        print(
            f"{h:8.0e} {row['central']:12.5g} {row['from_above']:12.5g} "
            f"{row['from_below']:12.5g}"
        )
    h = 1e-4
    (_, tp), (_, tm) = at(h), at(-h)
    terms = {
        k: {
            "from_above": ((tp[k] - np.asarray(v)) / h).tolist(),
            "from_below": ((np.asarray(v) - tm[k]) / h).tolist(),
        }
        for k, v in terms0.items()
    }
    print(f"\none-sided slopes of each term at h = {h:g}, per scenario (above / below)")
    for k, d in terms.items():
        above = " ".join(f"{x:9.3g}" for x in d["from_above"])
        below = " ".join(f"{x:9.3g}" for x in d["from_below"])
        print(f"  {k:16} {above}   / {below}")
    write_results(
        args.out,
        result_name("fd_steps", args.tag),
        {
            "t_end": args.t_end,
            "key": args.key,
            "batch": args.batch,
            "param": name,
            "setup": "tiny default config, buildable start, k1 k2 c1 c2 frozen",
        },
        {
            "loss": loss0,
            "autodiff": g[name],
            "gradient": g,
            "steps": rows,
            "terms_at_1e-4": terms,
        },
    )


if __name__ == "__main__":
    main()
