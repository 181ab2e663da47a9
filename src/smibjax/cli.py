"""Command line: `python -m smibjax {simulate,reproduce} ...`.

Bad input ends with one line on stderr (`smibjax: error: ...`) and exit status 2;
no traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

__all__ = ["main", "build_parameters"]


class CLIError(Exception):
    """A user error to report on one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        raise CLIError(f"{message} (see `python -m smibjax {self._sub} --help`)")

    _sub = ""


def _setup_jax() -> None:
    """64-bit mode and the persistent compilation cache (SMIBJAX_CACHE_DIR)."""
    import jax

    cache = os.environ.get(
        "SMIBJAX_CACHE_DIR", str(Path.home() / ".cache" / "smibjax" / "jax")
    )
    if cache:
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--controller",
        choices=["aftsc", "asc"],
        default="aftsc",
        help="AFTSC (alpha = 5/7) or ASC (alpha = 1); default aftsc",
    )
    p.add_argument(
        "--preset",
        choices=["paper", "realistic"],
        default="paper",
        help="plant input limits: paper (none) or realistic; default paper",
    )
    p.add_argument("--gains", metavar="FILE", help="flat JSON or TOML table of gains")
    p.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a gain, plant or operating-point value (repeatable)",
    )
    p.add_argument(
        "--adaptation",
        choices=["oracle", "realizable"],
        default="oracle",
        help="oracle (paper, uses the true theta) or realizable (k1=k2=0)",
    )


def _parse_sets(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise CLIError(f"--set {item!r} is not allowed: expected NAME=VALUE")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise CLIError(
                f"--set {item!r} is not allowed: VALUE must be a number"
            ) from None
    return out


def build_parameters(controller="aftsc", preset="paper", gains_file=None, sets=None):
    """(Gains, Plant, OperatingPoint, InitialEstimates) from the CLI's options: the
    paper's gains for `controller`, then the gains file, then `--set` values."""
    from .io import read_gains
    from .parameters import (
        GAIN_NAMES,
        PLANT_NAMES,
        Gains,
        InitialEstimates,
        OperatingPoint,
        Plant,
    )

    sets = dict(sets or {})
    gain_values = read_gains(gains_file) if gains_file else {}
    groups = {"gains": {}, "plant": {}, "op": {}, "init": {}}
    owners = {
        **{n: "gains" for n in GAIN_NAMES},
        **{n: "plant" for n in PLANT_NAMES},
        "delta_e": "op",
        "Pm_ref": "op",
        "th1": "init",
        "th2": "init",
    }
    for name, value in sets.items():
        if name not in owners:
            raise CLIError(
                f"--set {name}: unknown name; allowed are {', '.join(owners)}"
            )
        groups[owners[name]][name] = value
    gains = Gains.paper(controller, **{**gain_values, **groups["gains"]})
    plant = Plant.preset(preset, **groups["plant"])
    return (
        gains,
        plant,
        OperatingPoint(**groups["op"]),
        InitialEstimates(**groups["init"]),
    )


def _cmd_simulate(args) -> int:
    from .io import write_npz
    from .metrics import metrics
    from .parameters import Fault
    from .plotting import plot_trajectory, trajectory_arrays
    from .report import format_summary, metrics_dict
    from .simulate import simulate

    gains, plant, op, init = build_parameters(
        args.controller, args.preset, args.gains, _parse_sets(args.set)
    )
    fault = Fault(
        t_fault=args.fault_time,
        t_clear=args.clear_time,
        t_reclose=args.reclose_time,
        lam=args.fault_location,
        Xf=args.fault_reactance,
    )
    traj = simulate(
        gains,
        fault,
        plant,
        op=op,
        init=init,
        adaptation=args.adaptation,
        t_end=args.t_end,
        dt_save=args.dt_save,
    )
    m = metrics(traj)
    print(format_summary(gains, fault, plant, traj, m, args))
    arrays = trajectory_arrays(traj)
    if args.out:
        meta = {
            "gains": {k: float(getattr(gains, k)) for k in gains.__dataclass_fields__},
            "fault": {k: float(getattr(fault, k)) for k in fault.__dataclass_fields__},
            "plant": {k: float(getattr(plant, k)) for k in plant.__dataclass_fields__},
            "adaptation": args.adaptation,
            "metrics": metrics_dict(m),
        }
        arrays["meta"] = np.array(json.dumps(meta, allow_nan=True))
        out = Path(args.out)
        if out.suffix != ".npz":
            out = out.with_name(out.name + ".npz")
        write_npz(out, arrays)
        print(f"wrote {out}")
    if args.plot:
        plot_trajectory(
            arrays,
            args.plot,
            _title(gains, fault, args),
            (-float(plant.D), float(plant.Pm)),
        )
        print(f"wrote {args.plot}")
    return 0


def _title(gains, fault, args) -> str:
    c = "AFTSC" if float(gains.alpha) < 1 else "ASC"
    return (
        f"{c}: beta = ({float(gains.beta1):g}, {float(gains.beta2):g}), "
        f"alpha = {float(gains.alpha):.3g}; fault {float(fault.t_fault):g} -> "
        f"{float(fault.t_clear):g} s, reclose {float(fault.t_reclose):g} s, "
        f"lam {float(fault.lam):g}, Xf {float(fault.Xf):g}; {args.preset} plant"
    )


def _cmd_reproduce(args) -> int:
    from .reproduce import reproduce

    reproduce(Path(args.out), preset=args.preset, t_end=args.t_end)
    return 0


def _parser() -> argparse.ArgumentParser:
    top = _Parser(
        prog="python -m smibjax",
        description=(
            "Differentiable SMIB + SVC simulator under adaptive finite-time synergetic "
            "control."
        ),
    )
    sub = top.add_subparsers(dest="command", required=True, parser_class=_Parser)
    s = sub.add_parser("simulate", help="one closed-loop run: summary, npz, plot")
    s._sub = "simulate"
    _add_common(s)
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
    s.add_argument("--t-end", type=float, default=10.0, help="horizon (s)")
    s.add_argument(
        "--dt-save",
        type=float,
        default=0.01,
        help="sampling interval of the output (s), default 0.01",
    )
    s.add_argument("--out", metavar="FILE.npz", help="write the trajectory")
    s.add_argument("--plot", metavar="FILE.png", help="plot every signal")
    s.set_defaults(func=_cmd_simulate)
    r = sub.add_parser("reproduce", help="the paper's section 4 case, figures + table")
    r._sub = "reproduce"
    r.add_argument("--out", default="results/reproduce", help="output folder")
    r.add_argument("--preset", choices=["paper", "realistic"], default="paper")
    r.add_argument("--t-end", type=float, default=10.0, help="horizon (s)")
    r.set_defaults(func=_cmd_reproduce)
    return top


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    from .parameters import ParameterError

    try:
        args = _parser().parse_args(argv)
        _setup_jax()
        return args.func(args)
    except (CLIError, ParameterError) as e:
        print(f"smibjax: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(
            f"smibjax: error: {e.strerror or e}: {e.filename or ''}".rstrip(": "),
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt:
        print("smibjax: interrupted", file=sys.stderr)
        return 130
