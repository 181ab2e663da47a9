"""The lockstep cost model on finished Monte Carlo rows (issue 15): for each
scenarios.csv given, the efficiency (sum of steps) / (sum over device slices of the
slice's width x its slowest lane's steps) of the chunks as run (index order, chunk 256
on 2 devices: slices of 128) and with the rows ordered by their own steps (a perfect
cost predictor), by t_reclose and by the reclosing delay t_reclose - t_clear; and the
Spearman rank correlation of the steps with each scenario input. Writes
studies/lockstep_rows/lockstep_rows.json.

    python benchmarks/cli_rate.py --keep DIR   # keeps DIR/VARIANT.csv (8,192 rows)
    python studies/lockstep_rows/lockstep_rows.py DIR/*.csv [--width 128]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from smibjax._files import write_text
from smibjax.cli.runs import read_rows

INPUTS = ("t_fault", "t_reclose", "clear_duration", "fault_location", "fault_reactance")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", nargs="+")
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument(
        "--out", default=str(Path(__file__).resolve().parent / "lockstep_rows.json")
    )
    args = ap.parse_args()
    out = {}
    for path in args.csv:
        r = read_rows(path)
        s = r["num_steps"].astype(float)
        delay = r["t_reclose"] - r["t_clear"]

        def eff(order, s=s):
            x = s[order]
            w = args.width
            cost = sum(
                x[i : i + w].size * x[i : i + w].max() for i in range(0, x.size, w)
            )
            return float(s.sum() / cost)

        res = {
            "n": int(s.size),
            "steps_mean": float(s.mean()),
            "steps_max": int(s.max()),
            "efficiency": {
                "as_run": eff(np.arange(s.size)),
                "by_steps": eff(np.argsort(s)),
                "by_t_reclose": eff(np.argsort(r["t_reclose"])),
                "by_reclose_delay": eff(np.argsort(delay)),
            },
            "spearman": {c: float(spearmanr(r[c], s).statistic) for c in INPUTS},
        }
        res["spearman"]["reclose_delay"] = float(spearmanr(delay, s).statistic)
        out[Path(path).stem] = res
        e = res["efficiency"]
        print(
            f"{Path(path).stem:16} as run {e['as_run']:.3f}  by steps "
            f"{e['by_steps']:.3f}  by t_reclose {e['by_t_reclose']:.3f}  by delay "
            f"{e['by_reclose_delay']:.3f}"
        )
    write_text(args.out, json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
