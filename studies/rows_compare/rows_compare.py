"""The Monte Carlo rows of the current code against those of git revision REV: the
same command, `python -m smibjax montecarlo --n N --controller C --set beta1=-1 --set
beta2=-1 [EXTRA]`, run once with each code (REV in a temporary worktree on
PYTHONPATH), and every column compared: verdicts changed (stable, lost_sync,
budget_exhausted), the largest settling-time difference (s), the largest relative
difference of every other column, and the mean step counts. For a change that should
move results by rounding only (issue 15's criterion: every verdict unchanged, settling
within 5 ms). Writes studies/rows_compare/rows_compare[_TAG].json.

    python studies/rows_compare/rows_compare.py REV [--n 4096] [--controllers aftsc asc]
        [--extra ARG ...] [--tag NAME]
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
sys.path.insert(0, str(HERE.parents[1] / "benchmarks"))  # cli_rate, _common, _results

import argparse
import tempfile

import numpy as np
from cli_rate import ROOT, cli, worktree_add, worktree_remove

VERDICTS = ("stable", "lost_sync", "budget_exhausted")
SETTLING = ("settling_time", "settling_Vt", "settling_omega")


def compare(a: dict, b: dict) -> dict:
    """Differences of the rows `b` from the rows `a` (dicts of columns)."""
    out = {
        "rows": int(a["index"].size),
        "verdicts_changed": {
            c: int(np.sum(a[c].astype(int) != b[c].astype(int))) for c in VERDICTS
        },
        "num_steps_mean": [float(a["num_steps"].mean()), float(b["num_steps"].mean())],
    }
    for c in SETTLING:
        fin = np.isfinite(a[c]) & np.isfinite(b[c])
        out[f"{c}_inf_changed"] = int(np.sum(np.isfinite(a[c]) != np.isfinite(b[c])))
        out[f"{c}_max_abs_diff_s"] = float(np.max(np.abs(a[c][fin] - b[c][fin])))
    rel = {}
    for c in a:
        if c in (*VERDICTS, *SETTLING, "index", "num_steps"):
            continue
        x, y = a[c].astype(float), b[c].astype(float)
        fin = np.isfinite(x) & np.isfinite(y)
        scale = np.maximum(np.abs(x[fin]), 1e-12)
        rel[c] = float(np.max(np.abs(x[fin] - y[fin]) / scale)) if fin.any() else 0.0
    out["max_relative_diff"] = rel
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev")
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--controllers", nargs="+", default=["aftsc", "asc"])
    ap.add_argument("--extra", nargs="*", default=[], help="more command options")
    ap.add_argument("--out", default=str(HERE))
    ap.add_argument("--tag", default="")
    args = ap.parse_args()
    from _common import result_name
    from _results import write_results

    from smibjax.cli.runs import read_rows

    tmp = Path(tempfile.mkdtemp(prefix="smibjax-rows-"))
    base = worktree_add(args.rev, tmp / "baseline")
    results = {}
    try:
        for c in args.controllers:
            rows = {}
            for name, root in (("rev", base), ("now", ROOT)):
                keep = tmp / f"{c}_{name}.csv"
                cli(args.n, c, args.extra, tmp / "run", keep, root)
                rows[name] = read_rows(keep)
            results[c] = compare(rows["rev"], rows["now"])
            r = results[c]
            print(
                f"{c}: verdicts changed {r['verdicts_changed']}, settling max diff "
                f"{r['settling_time_max_abs_diff_s']:.2e} s, steps "
                f"{r['num_steps_mean'][0]:.1f} -> {r['num_steps_mean'][1]:.1f}, "
                f"largest relative diff "
                f"{max(r['max_relative_diff'].values()):.1e}",
                flush=True,
            )
    finally:
        worktree_remove(base)
    write_results(
        args.out,
        result_name("rows_compare", args.tag),
        {
            "rev": args.rev,
            "n": args.n,
            "command": "python -m smibjax montecarlo --n N --controller C --set "
            "beta1=-1 --set beta2=-1 " + " ".join(args.extra),
        },
        results,
    )


if __name__ == "__main__":
    main()
