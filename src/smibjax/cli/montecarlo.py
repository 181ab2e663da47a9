"""`python -m smibjax montecarlo`: a batch Monte Carlo over fault scenarios into a
resumable run folder (`smibjax.cli.runs`), in this process or on Dask."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .._montecarlo import MonteCarloSpec

import contextlib
import sys
from pathlib import Path

from .._commandline import out_path
from .grid import add_case_options, add_montecarlo_options
from .options import (
    CLIError,
    add_common,
    add_tolerances,
    build_from_args,
    parameter_values,
    positive,
    read_dist,
    solver_options,
)

__all__ = ["add_parser", "run", "add_mc_options", "spec_from_args", "runner_of"]


def add_mc_options(p, n_default: int) -> None:
    """--n, --seed, --dist, --chunk, --t-end, --resume, --scheduler, --workers."""
    p.add_argument("--n", type=int, default=n_default, help="number of scenarios")
    p.add_argument("--seed", type=int, default=0, help="scenario seed (default 0)")
    p.add_argument(
        "--dist",
        metavar="FILE.toml",
        help="scenario ranges name = [lo, hi] (t_fault, clear_duration, "
        "reclose_delay, fault_location, fault_reactance, D, Pm)",
    )
    p.add_argument(
        "--chunk",
        type=int,
        default=1024,
        help="scenarios per batch (default 1024; the rows do not depend on it)",
    )
    p.add_argument("--t-end", type=positive, default=10.0, help="horizon (s)")
    p.add_argument(
        "--resume", action="store_true", help="finish the run in --out after a stop"
    )
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run chunks on this Dask scheduler"
    )
    p.add_argument(
        "--workers", type=int, help="run chunks on a local Dask cluster of N processes"
    )


def add_parser(sub) -> None:
    m = sub.add_parser(
        "montecarlo", help="batch Monte Carlo over fault scenarios (resumable)"
    )
    add_common(m)
    add_tolerances(m)
    add_mc_options(m, 1000)
    m.add_argument(
        "--out",
        metavar="DIR",
        help="output folder (default: a new folder runs/montecarlo-<time>)",
    )
    add_case_options(m, events=False)
    add_montecarlo_options(m)
    m.set_defaults(func=run, flags=m.flags)


def spec_from_args(args, params, plant, op, init, dist) -> MonteCarloSpec:
    """The `MonteCarloSpec` of the command's options (validated by the spec)."""
    from .._montecarlo import MonteCarloSpec
    from .._parameters import PLANT_NAMES

    return MonteCarloSpec(
        n=args.n,
        seed=args.seed,
        chunk=min(args.chunk, args.n) if args.n >= 1 else args.chunk,
        gains=parameter_values(params),
        plant={k: float(getattr(plant, k)) for k in PLANT_NAMES},
        op={"delta_e": float(op.delta_e), "Pm_ref": float(op.Pm_ref)},
        init={"th1": float(init.th1), "th2": float(init.th2)},
        dist=dist.to_dict(),
        adaptation=args.adaptation,
        controller=args.controller or "",
        options=dict(getattr(getattr(args, "context", None), "options", {}) or {}),
        t_end=args.t_end,
        solver=solver_options(args),
    )


def runner_of(args):
    """A context manager of the chunk runner: None (this process) or Dask
    (`--scheduler`, `--workers`; validated by `dask_runner`)."""
    if args.scheduler is None and args.workers is None:
        return contextlib.nullcontext(None)
    from .cluster import dask_runner

    return dask_runner(scheduler=args.scheduler, workers=args.workers)


def run_folder(spec, out: Path, resume: bool, runner, title: str):
    """`run_montecarlo`, with a cluster failure (e.g. a chunk that keeps killing its
    workers) turned into one line that says how to finish the run."""
    from .._parameters import ParameterError
    from .runs import run_montecarlo

    try:
        return run_montecarlo(spec, out, resume=resume, runner=runner, title=title)
    except Exception as e:
        if runner is None or isinstance(e, (CLIError, ParameterError, OSError)):
            raise
        raise CLIError(
            f"the cluster failed ({type(e).__name__}: {e}); the chunks already "
            f"written are kept: finish with --resume --out {out}"
        ) from None


def output(args) -> Path:
    """The run folder: --out, else a new folder runs/montecarlo-<time>
    (`OUTPUT_ROOT`)."""
    return out_path(args.out, "montecarlo")


def run(args) -> int:
    from ..controllers import describe
    from .report import plant_text

    if args.case:
        from .grid import run_montecarlo as run_case

        return run_case(args)
    params, plant, op, init = build_from_args(args, complete=True)
    spec = spec_from_args(args, params, plant, op, init, read_dist(args.dist))
    if args.resume and not args.out:
        raise CLIError("--resume needs --out DIR (the folder of the run to finish)")
    out = output(args)
    from .._files import check_out_folder

    check_out_folder(out)  # before any work
    title = (
        f"{describe(params)}; {args.n} scenarios, seed {args.seed}, "
        + plant_text(plant, args.preset)
        + (
            f", {args.adaptation} adaptation"
            if "adaptation" in args.context.describe()
            else ""
        )
    )
    with runner_of(args) as runner:
        _, summary = run_folder(spec, out, args.resume, runner, title)
    print(title)
    print_summary(summary, out)
    return 0


def print_summary(summary: dict, out: Path) -> None:
    lo, hi = summary["stable_fraction_ci95"]
    st = summary["settling_time"]
    print(
        f"stable: {summary['stable']} of {summary['n']} "
        f"({100 * summary['stable_fraction']:.2f}%, 95% CI {100 * lo:.2f}-"
        f"{100 * hi:.2f}%)"
    )
    if st["count"]:
        print(
            f"delta settling time (stable): mean {st['mean']:.3f} s, p50 "
            f"{st['p50']:.3f} s, p95 {st['p95']:.3f} s, max {st['max']:.3f} s"
        )
    if summary.get("budget_exhausted"):
        print(
            f"warning: {summary['budget_exhausted']} run(s) spent the solver's step "
            "budget before t_end and are counted as not stable: raise --max-steps",
            file=sys.stderr,
        )
    print(f"wrote {out}/scenarios.csv, summary.json, summary.md, montecarlo.png")
