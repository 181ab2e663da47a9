"""Settling against chatter: the default tuning run for several weights of the loss's
`chatter` term (issue 13, "No bang-bang by accident"), and the cross-entropy search on
the same problem for reference; every result on the same validation set.

    python studies/chatter_tradeoff/chatter_tradeoff.py [--weights 0 0.3 1] [--n-val 64]
    python studies/chatter_tradeoff/chatter_tradeoff.py --from-runs w=0:DIR w=0.3:DIR search:DIR

Each run is `python -m tuning.optimize` on the default config with `[loss] chatter`
set (and `[validation] n`); `--from-runs` reads finished run folders instead (their
`gains.json`). Every set is scored on the default config's validation set. Writes
studies/chatter_tradeoff/chatter_tradeoff.json and docs/figures/chatter_tradeoff.png.
"""

from __future__ import annotations

from smibjax import configure

# an entry point: float64, equinox's checks as NaNs, before JAX loads
configure(cache=False)

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from smibjax._files import write_text

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT))  # the tuning package


def _best(run: Path, n_val: int) -> dict:
    """The exact validation summary of `run/gains.json` on the default config's
    validation set of `n_val` scenarios (the same set for every run)."""
    import jax
    import numpy as np

    from smibjax._files import read_gains_file
    from tuning.config import load_config
    from tuning.problem import build
    from tuning.train import draw_scenarios, make_validate, summarize

    cfg = load_config()
    cfg["validation"]["n"] = n_val
    _, _, setup, dist, _ = build(cfg)
    val = draw_scenarios(
        jax.random.PRNGKey(int(cfg["validation"]["seed"])), n_val, dist, setup.plant
    )
    gf = read_gains_file(run / "gains.json")
    params = setup.space.make(**{**setup.space.frozen, **gf.gains})
    m = make_validate(setup)(params, val)
    return summarize(jax.tree_util.tree_map(np.asarray, m))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", type=float, nargs="+", default=[0.0, 0.3, 1.0])
    ap.add_argument("--n-val", type=int, default=256)
    ap.add_argument("--from-runs", nargs="+", metavar="LABEL:DIR")
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args(argv)
    rows = {}
    if args.from_runs:
        for item in args.from_runs:
            label, _, path = item.partition(":")
            rows[label] = _best(Path(path), args.n_val)
    else:
        for w in args.weights:
            with tempfile.TemporaryDirectory() as tmp:
                cfg = Path(tmp) / "c.toml"
                cfg.write_text(
                    f"[loss]\nchatter = {w}\n[validation]\nn = {args.n_val}\n"
                )
                run = Path(tmp) / "run"
                subprocess.run(
                    [
                        sys.executable,
                        "-m",
                        "tuning.optimize",
                        "--config",
                        str(cfg),
                        "--out",
                        str(run),
                        "--quiet",
                    ],
                    check=True,
                    cwd=ROOT,
                )
                rows[f"w={w:g}"] = _best(run, args.n_val)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "chatter_tradeoff.json", json.dumps(rows, indent=1))
    print(
        f"{'run':10} {'stable':>7} {'mean ts':>8} {'p95 ts':>7} {'TV u_f':>8} "
        f"{'TV u_r':>7}"
    )
    for k, v in rows.items():
        print(
            f"{k:10} {v['stable_fraction']:7.3f} {v['settling_delta_mean']:8.3f} "
            f"{v['settling_delta_p95']:7.3f} {v['tv_uf_mean']:8.1f} "
            f"{v['tv_ur_mean']:7.1f}"
        )
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from smibjax.cli.plotting import save_figure

    fig, ax = plt.subplots(figsize=(6, 4))
    for k, v in rows.items():
        marker = "s" if k.startswith("search") else "o"
        ax.plot(v["tv_uf_mean"], v["settling_delta_mean"], marker, ms=8)
        ax.errorbar(
            v["tv_uf_mean"],
            v["settling_delta_mean"],
            yerr=[[0], [v["settling_delta_p95"] - v["settling_delta_mean"]]],
            color="grey",
            capsize=3,
        )
        ax.annotate(
            k,
            (v["tv_uf_mean"], v["settling_delta_mean"]),
            textcoords="offset points",
            xytext=(6, 4),
        )
    ax.set_xlabel("mean total variation of the applied u_f (pu): chatter")
    ax.set_ylabel("mean delta settling (s); bar to p95")
    ax.set_title("Realistic limits, realizable adaptation, D drawn", fontsize=9)
    ax.grid(alpha=0.3)
    ax.margins(x=0.35, y=0.15)
    fig.tight_layout()
    save_figure(fig, ROOT / "docs" / "figures" / "chatter_tradeoff.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
