"""The command line's Monte Carlo marginal throughput (issue 15): `python -m smibjax
montecarlo --set beta1=-1 --set beta2=-1 ...` at n = --small and --large (default
512 and 8192), the rate (large - small) / (t_large - t_small), which leaves out the
process start and the compilation; for AFTSC and ASC, with the exact law and with each
--phi-layer W (AFTSC only: alpha = 1 is unaffected by the layer), and each of these
again with --chunk C for each --chunks C (--small must be at least the largest C, so
that both n run the same program), all in one run, the
variants alternated (each n, each variant in turn, --repeat rounds) so that contention
on the machine affects them alike. Beside it, the SciPy loop of benchmarks/vs_scipy.py
(LSODA, one scenario after another, tests/reference.py's model) on the first --n-scipy
scenarios of the same Monte Carlo, in the same run. With --baseline REV the two
exact-law commands (AFTSC, ASC; default chunk) run a second time with the code of git
revision REV (a temporary worktree on PYTHONPATH), alternated with the others, and the
table gives each variant's rate over its controller's exact-law command at REV
("x base": the command as it was). Writes benchmarks/results/cli_rate.json.

    python benchmarks/cli_rate.py [--small 512] [--large 8192] [--widths 0.01]
        [--chunks C ...] [--order] [--baseline REV] [--repeat 1] [--n-scipy 4]
        [--keep DIR] [--tag NAME]
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import argparse
import os
import shutil
import subprocess
import tempfile
import time

import numpy as np

ROOT = HERE.parent


def cli(
    n: int, controller: str, extra: list[str], out: Path, keep=None, root=ROOT
) -> float:
    """Seconds of one `python -m smibjax montecarlo` process (spawn to exit), with
    the code of the checkout at `root`."""
    argv = [sys.executable, "-m", "smibjax", "montecarlo", "--n", str(n)]
    argv += ["--controller", controller, "--set", "beta1=-1", "--set", "beta2=-1"]
    argv += [*extra, "--out", str(out)]
    env = dict(os.environ, PYTHONPATH=str(Path(root) / "src"))
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, cwd=root, capture_output=True, env=env)
    seconds = time.perf_counter() - t0
    if keep is not None:
        keep.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(out / "scenarios.csv", keep)
    shutil.rmtree(out)
    return seconds


def worktree_add(rev: str, path: Path) -> Path:
    """A detached git worktree of revision `rev` at `path` (its code runs with
    PYTHONPATH=path/src, see `cli`)."""
    subprocess.run(
        ["git", "worktree", "add", "--detach", str(path), rev],
        check=True,
        cwd=ROOT,
        capture_output=True,
    )
    return path


def worktree_remove(path: Path) -> None:
    subprocess.run(
        ["git", "worktree", "remove", "--force", str(path)],
        cwd=ROOT,
        capture_output=True,
    )


def scipy_rate(controller: str, n: int) -> float:
    """Scenarios/s of vs_scipy's LSODA loop on Monte Carlo scenarios 0..n-1 (seed 0)."""
    import vs_scipy  # configures the process (float64, devices) on import

    import smibjax as sj
    from smibjax._scenarios import ScenarioDistribution, sample_scenarios

    g = sj.Gains.paper(controller, beta1=-1.0, beta2=-1.0)
    gd = {k: float(getattr(g, k)) for k in sj.GAIN_NAMES}
    plant = {k: float(getattr(sj.Plant(), k)) for k in sj.PLANT_NAMES}
    faults, _, _ = sample_scenarios(0, 0, n, ScenarioDistribution(), sj.Plant())
    total = 0.0
    for i in range(n):
        fl = {k: float(getattr(faults, k)[i]) for k in sj.FAULT_NAMES}
        t0 = time.perf_counter()
        vs_scipy.scipy_scenario(gd, plant, fl, "LSODA", 10.0, (1e-6, 1e-8))
        total += time.perf_counter() - t0
    return n / total


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", type=int, default=512)
    ap.add_argument("--large", type=int, default=8192)
    ap.add_argument("--widths", type=float, nargs="*", default=[0.01])
    ap.add_argument(
        "--chunks", type=int, nargs="*", default=[], help="ASC at these --chunk sizes"
    )
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument(
        "--order",
        action="store_true",
        help="also each with --order reclose-delay (the CLI of commit 09054a1 only: "
        "the option was measured and removed, benchmarks/README.md)",
    )
    ap.add_argument(
        "--baseline",
        metavar="REV",
        help="also run every variant with the code of this git revision",
    )
    ap.add_argument("--n-scipy", type=int, default=4)
    ap.add_argument("--out", default=str(HERE / "results"))
    ap.add_argument("--tag", default="")
    ap.add_argument("--keep", metavar="DIR", help="keep each variant's large-n rows")
    args = ap.parse_args()
    variants = {"aftsc exact": ("aftsc", []), "asc exact": ("asc", [])}
    for w in args.widths:
        variants[f"aftsc W={w:g}"] = ("aftsc", ["--phi-layer", str(w)])
    if args.chunks and max(args.chunks) > args.small:
        ap.error(f"--small {args.small} is below --chunks {max(args.chunks)}")
    for c in args.chunks:  # every variant above again at this chunk size
        for v, (ctrl, extra) in list(variants.items()):
            if "chunk=" not in v:
                variants[f"{v} chunk={c}"] = (ctrl, [*extra, "--chunk", str(c)])
    if args.order:  # each variant again with --order reclose-delay
        for v, (c, extra) in list(variants.items()):
            variants[f"{v} ordered"] = (c, [*extra, "--order", "reclose-delay"])
    tmp = Path(tempfile.mkdtemp(prefix="smibjax-cli-rate-"))
    roots = {v: ROOT for v in variants}
    if args.baseline:
        base_root = worktree_add(args.baseline, tmp / "baseline")
        for v in ("aftsc exact", "asc exact"):  # the command as it was at REV
            variants[f"{v} @{args.baseline}"] = variants[v]
            roots[f"{v} @{args.baseline}"] = base_root
    times = {v: {args.small: [], args.large: []} for v in variants}
    try:
        for v, (c, extra) in variants.items():  # warm the compilation cache
            cli(args.small, c, extra, tmp / "warm", root=roots[v])
        for r in range(args.repeat):
            for n in (args.small, args.large):
                order = list(variants)
                for v in order[r % len(order) :] + order[: r % len(order)]:
                    c, extra = variants[v]
                    keep = None
                    if args.keep and n == args.large:
                        name = v.replace(" ", "_").replace("=", "")
                        keep = Path(args.keep) / f"{name}.csv"
                    s = cli(n, c, extra, tmp / "run", keep, roots[v])
                    times[v][n].append(s)
                    print(f"  {v} n={n}: {s:.1f} s", flush=True)
    finally:
        if args.baseline:
            worktree_remove(tmp / "baseline")
        shutil.rmtree(tmp, ignore_errors=True)
    scipy = {}
    for c in ("aftsc", "asc"):
        t0 = time.perf_counter()
        scipy[c] = scipy_rate(c, args.n_scipy)
        print(
            f"  scipy LSODA {c}: {scipy[c]:.3f} /s ({time.perf_counter() - t0:.0f} s)"
        )
    rates = {}
    for v, (c, _) in variants.items():
        ts, tl = np.median(times[v][args.small]), np.median(times[v][args.large])
        rate = (args.large - args.small) / (tl - ts)
        rates[v] = {
            "controller": c,
            "seconds_small": float(ts),
            "seconds_large": float(tl),
            "marginal_scenarios_per_s": float(rate),
            "over_scipy_lsoda": float(rate / scipy[c]),
        }
    at = f" @{args.baseline}" if args.baseline else ""
    for v, r in rates.items():
        exact = f"{r['controller']} exact" + (at if v.endswith(at) and at else "")
        r["over_exact"] = (
            r["marginal_scenarios_per_s"] / (rates[exact]["marginal_scenarios_per_s"])
        )
        if args.baseline and not v.endswith(at):  # over the command at REV
            base = rates[f"{r['controller']} exact{at}"]["marginal_scenarios_per_s"]
            r["over_baseline"] = r["marginal_scenarios_per_s"] / base
    print(
        f"\n{'variant':32} {'t_small':>8} {'t_large':>8} {'rate/s':>8} "
        f"{'x exact':>8} {'x scipy':>8} {'x base':>7}"
    )
    for v, r in rates.items():
        base = f"{r['over_baseline']:7.2f}" if "over_baseline" in r else ""
        print(
            f"{v:32} {r['seconds_small']:8.1f} {r['seconds_large']:8.1f} "
            f"{r['marginal_scenarios_per_s']:8.0f} {r['over_exact']:8.2f} "
            f"{r['over_scipy_lsoda']:8.0f} {base:>7}"
        )
    from _common import result_name
    from _results import write_results

    write_results(
        args.out,
        result_name("cli_rate", args.tag),
        {
            "command": "python -m smibjax montecarlo --n N --controller C --set "
            "beta1=-1 --set beta2=-1 [--phi-layer W] (defaults otherwise: seed 0, "
            "the command's own --chunk (1024 since 2026-12-01, 256 before), rtol 1e-6, "
            "atol 1e-8, paper plant, oracle)",
            "baseline": args.baseline,
            "small": args.small,
            "large": args.large,
            "repeat": args.repeat,
            "rate": "(large - small) / (t_large - t_small), medians of the repeats",
            "scipy": f"vs_scipy.scipy_scenario LSODA, Monte Carlo scenarios 0..{args.n_scipy - 1}",
            "cores": os.cpu_count(),
        },
        {
            "rows": rates,
            "times": {v: {str(k): t for k, t in d.items()} for v, d in times.items()},
            "scipy_lsoda_scenarios_per_s": scipy,
        },
    )


if __name__ == "__main__":
    main()
