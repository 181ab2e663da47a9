"""`python -m smibjax simulate`: one closed-loop run, its summary, npz and plot."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from .._commandline import UNNAMED, out_path
from .grid import add_case_options
from .options import (
    CLIError,
    add_common,
    add_force,
    add_tolerances,
    build_from_args,
    controller_of,
    parameter_values,
    positive,
    solver_options,
)

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    s = sub.add_parser("simulate", help="one closed-loop run: summary, npz, plot")
    add_common(s)
    add_tolerances(s)
    s.add_argument("--fault-time", type=float, default=0.5, help="t_fault (s)")
    s.add_argument("--clear-time", type=float, default=0.7, help="t_clear (s)")
    s.add_argument("--reclose-time", type=float, default=2.0, help="t_reclose (s)")
    s.add_argument(
        "--fault-location",
        type=float,
        default=0.5,
        help="lam in (0, 1), from the SVC bus",
    )
    s.add_argument("--fault-reactance", type=float, default=0.0, help="Xf >= 0 (pu)")
    s.add_argument("--t-end", type=positive, default=10.0, help="horizon (s)")
    s.add_argument(
        "--dt-save",
        type=positive,
        default=0.01,
        help="sampling interval of the output (s), default 0.01",
    )
    s.add_argument(
        "--out",
        metavar="FILE.npz|.csv|.mat|.cfg",
        nargs="?",
        const=UNNAMED,
        help="write the trajectory in the format of the suffix: .npz (NumPy), .csv "
        "(a wide table, one column per signal with its device and unit), .mat "
        "(MATLAB v5), .cfg (COMTRADE C37.111-1999 ASCII, with its .dat); --out "
        "alone: a new file runs/simulate-<time>.npz (default: nothing written)",
    )
    s.add_argument(
        "--plot",
        metavar="FILE.png",
        help="plot every signal, in the format of the suffix (.png, .pdf, .svg, ...)",
    )
    add_force(s)
    add_case_options(s)
    s.set_defaults(func=run, flags=s.flags, precheck=precheck)


def run(args) -> int:
    import numpy as np

    from .._export import smib_columns, write_trajectory
    from .._options import SaveOptions
    from .._parameters import Fault
    from . import _exported
    from .plotting import plot_trajectory
    from .report import format_summary, metrics_dict

    args.out = output(args)
    if args.case:
        from .grid import run_simulate

        return run_simulate(args)
    out, plot = _outputs(args)
    gains, plant, op, init = build_from_args(args)
    fault = Fault(
        t_fault=args.fault_time,
        t_clear=args.clear_time,
        t_reclose=args.reclose_time,
        lam=args.fault_location,
        Xf=args.fault_reactance,
    )
    from .._commandline import announce_compile

    with announce_compile("the simulation", *PROGRAMS):
        # a second identical run calls the stored programs: no trace, no diffrax
        traj, m, arrays = _exported.run(
            controller_of(gains, args.adaptation, args.context),
            fault,
            plant,
            op,
            init,
            solver_options(args),
            SaveOptions(args.t_end, args.dt_save),
        )
    _warn_dt_save(args)
    print(format_summary(gains, fault, plant, traj, m, args))
    if args.out:
        adaptive = "adaptation" in args.context.describe()
        meta = {
            "gains": parameter_values(gains),
            "fault": {k: float(getattr(fault, k)) for k in fault.__dataclass_fields__},
            "plant": {k: float(getattr(plant, k)) for k in plant.__dataclass_fields__},
            **({"adaptation": args.adaptation} if adaptive else {}),
            "context": args.context.describe(),
            "metrics": {  # NaN (not reached) as null
                k: None if isinstance(v, float) and math.isnan(v) else v
                for k, v in metrics_dict(m).items()
            },
        }
        arrays["meta"] = np.array(json.dumps(meta, allow_nan=True))
        written = write_trajectory(
            out,
            arrays,
            smib_columns(arrays),
            station="SMIB",
            frequency=float(plant.f),
            trigger=float(args.fault_time),
        )
        print(f"wrote {', '.join(str(w) for w in written)}")
    if plot:
        plot_trajectory(
            arrays,
            plot,
            _title(gains, fault, args),
            (-float(plant.D), float(plant.Pm)),
            events=(args.fault_time, args.clear_time, args.reclose_time),
            adaptive="adaptation" in args.context.describe(),
        )
        print(f"wrote {plot}")
    return 0


PROGRAMS = ("jit__simulate", "jit_call_exported")
"""The names JAX gives the simulation's compiled program in the persistent cache:
traced (`smibjax._simulate`) and stored (`smibjax.cli._exported`)."""


def output(args) -> Path | None:
    """The --out file: as named, a new one under `OUTPUT_ROOT` for `--out` alone
    (runs/simulate-<time>.npz), else None."""
    return out_path(args.out, "simulate", ".npz", default=False)


def _outputs(args) -> tuple[Path | None, Path | None]:
    """--out (.npz appended when there is no suffix; `check_out`) and --plot paths,
    refused before the run when they exist (without --force), name a folder, the
    same file, or a format that cannot be written."""
    from .._figures import check_plot_path
    from .._files import check_new_file

    out = plot = None
    if args.out:
        out = check_out(args.out, args.force)
    if args.plot:
        plot = check_new_file(check_plot_path(args.plot), args.force, "--plot")
        if out is not None and plot.resolve() == out.resolve():
            raise CLIError(
                f"--plot = {str(plot)!r} is not allowed: must differ from --out"
            )
    return out, plot


def precheck(args) -> None:
    """Before JAX starts: a --case run has an event; --out's suffix names a format
    (.npz, .csv, .mat, .cfg) and the file (with COMTRADE's .dat) is new or --force is
    given; CLIError."""

    if args.out:  # (None, or `--out` alone: a new name under runs/)
        _precheck_out(args)
    if getattr(args, "case", None):
        from .grid import require_an_event

        require_an_event(args)


def _precheck_out(args) -> None:
    from .._export import FormatError, check_trajectory_path, companion_files

    try:
        out = check_trajectory_path(args.out, "--out")
    except FormatError as e:
        raise CLIError(str(e)) from None
    for p in companion_files(out):
        if p.exists() and not args.force:
            raise CLIError(
                f"--out = {str(p)!r} is not allowed: must be a new file (it exists; "
                "add --force to replace it)"
            )


def check_out(path, force: bool) -> Path:
    """The --out trajectory file (`_export.check_trajectory_path`: .npz, .csv, .mat
    or .cfg; .npz appended without a suffix), and for COMTRADE its .dat, new (or
    --force): refused in one line before the run."""
    from .._export import FormatError, check_trajectory_path, companion_files
    from .._files import check_new_file

    try:
        out = check_trajectory_path(path, "--out")
    except FormatError as e:
        raise CLIError(str(e)) from None
    for p in companion_files(out):
        check_new_file(p, force, "--out")
    return out


def _warn_dt_save(args) -> None:
    """Say so when --dt-save does not divide --t-end: the run samples the nearest
    number of equal intervals instead (printed after the run succeeded, so that a
    refusal stays one line)."""
    ratio = args.t_end / args.dt_save
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
        n = max(int(round(ratio)), 1)
        print(
            f"smibjax: warning: --dt-save {args.dt_save:g} does not divide --t-end "
            f"{args.t_end:g}: sampling {n} equal intervals of "
            f"{args.t_end / n:.6g} s instead",
            file=sys.stderr,
        )


def _title(gains, fault, args) -> str:
    from ..controllers import describe

    return (
        f"{describe(gains)}; fault {float(fault.t_fault):g} -> "
        f"{float(fault.t_clear):g} s, reclose {float(fault.t_reclose):g} s, "
        f"lam {float(fault.lam):g}, Xf {float(fault.Xf):g}; {args.preset} plant"
        + (
            f", {args.adaptation} adaptation"
            if "adaptation" in args.context.describe()
            else ""
        )
    )
