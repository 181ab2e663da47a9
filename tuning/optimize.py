"""`python -m tuning.optimize`: tune the controller gains with optax over batches of
fault scenarios; checkpoints, resume, report.

    python -m tuning.optimize [--config FILE.toml] [--init paper|FILE] [--steps N]
        [--batch B] [--seed S] [--out DIR] [--resume] [--preset paper|realistic]
        [--controller aftsc|asc|avr-pss] [--adaptation oracle|realizable] [--quiet]

A config with a `[case]` table tunes device parameters of a multi-machine case
instead (`tuning.grid_run`, docs/tuning-grid.md).

This module is the command line only: it configures the process (host devices,
float64, equinox's error mode, the compilation cache; `smibjax.configure`) before
JAX loads, then builds the problem (`tuning.problem`), runs the loop
(`tuning.loop`) and writes the outputs (`tuning.outputs`).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

from smibjax._commandline import CLIError, Parser, out_path

__all__ = ["main", "parse_args"]

_CONTROLLERS = ("aftsc", "asc", "avr-pss")  # the tunable ones (none has no parameters)


def _defaults() -> dict:
    """configs/default.toml, read without the library (for --help: no JAX)."""
    import tomllib

    path = Path(__file__).parent / "configs" / "default.toml"
    return tomllib.loads(path.read_text(encoding="utf-8"))


def parse_args(argv):
    d = _defaults()

    def dflt(key):
        return f" (default: {d[key]}, from tuning/configs/default.toml)"

    p = Parser(
        prog="python -m tuning.optimize",
        description="Tune the controller gains with optax over batches of fault "
        "scenarios; checkpoints, resume, report. Flags override --config, which "
        "overrides tuning/configs/default.toml; the defaults of one controller "
        "family (the paper's law's continuation, frozen gains and bounds) apply "
        "to it only.",
    )
    p.add_argument("--config", help="TOML file overriding configs/default.toml")
    p.add_argument("--init", help="'paper' or a gains file (JSON/TOML)" + dflt("init"))
    p.add_argument("--steps", type=int, help="optimizer steps" + dflt("steps"))
    p.add_argument(
        "--batch", type=int, help="training scenarios per step" + dflt("batch")
    )
    p.add_argument(
        "--seed", type=int, help="seed of the training batches" + dflt("seed")
    )
    p.add_argument(
        "--out", help="output folder (default: a new folder runs/tune-<time>)"
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its last checkpoint",
    )
    p.add_argument(
        "--preset",
        choices=["paper", "realistic"],
        help="plant input limits" + dflt("preset"),
    )
    p.add_argument("--controller", choices=_CONTROLLERS, help="" + dflt("controller"))
    p.add_argument(
        "--adaptation",
        choices=["oracle", "realizable"],
        help="the paper's law only (aftsc, asc)" + dflt("adaptation"),
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p.parse_args(argv)


def resolve_config(args) -> dict:
    """The default configuration, then --config, then the flags; validated."""
    from .config import check_config, load_config

    keys = ("init", "steps", "batch", "seed", "preset", "controller", "adaptation")
    cfg = load_config(args.config, flags={k: getattr(args, k) for k in keys})
    check_config(cfg)
    return cfg


def output(args) -> Path:
    """The run folder: --out, else a new folder runs/tune-<time> (the output root
    of every command, `smibjax._commandline.OUTPUT_ROOT`)."""
    return out_path(args.out, "tune")


def main(argv=None) -> int:
    try:  # parsed before JAX loads: --help and usage errors answer at once
        args = parse_args(argv)
    except CLIError as e:
        print(f"tuning.optimize: error: {e}", file=sys.stderr)
        return 2
    from smibjax import configure

    configure()  # before anything imports equinox or JAX
    from smibjax._commandline import xla_alarms_explained

    with xla_alarms_explained():  # XLA's slow-compile alarm as a line of ours
        return _main(args)


def _main(args) -> int:
    """`main` after the parse and the process set-up."""
    from smibjax import ParameterError
    from smibjax._files import check_out_folder, write_json

    from .loop import CHECKPOINT, run
    from .outputs import finish
    from .problem import UsageError, build
    from .resume import SessionClock, start_mode

    try:
        from .grid_config import is_grid_config

        if is_grid_config(args.config):  # a [case] table: a multi-machine case
            from .grid_run import main as grid_main

            return grid_main(args)
        cfg = resolve_config(args)
        if args.resume and not args.out:
            raise UsageError("--resume needs --out DIR (the run to continue)")
        out = output(args)
        check_out_folder(out)  # writable, before any work
        resume = start_mode(out, cfg, args.resume, CHECKPOINT)  # tuning/resume.py
        build(cfg)  # validate gains, bounds, scenarios before any work
        out.mkdir(parents=True, exist_ok=True)
        if not resume:
            write_json(out / "config.json", cfg)
        clock, t0 = SessionClock(out, args.resume), time.perf_counter()
        state = run(cfg, out, resume=resume, quiet=args.quiet)
        total, sessions = clock.finish(time.perf_counter() - t0)
        # the wall time of all sessions of the run
        state = dataclasses.replace(state, wall_seconds=total, wall_sessions=sessions)
        if not args.quiet:
            print(
                "writing the report: the best gains on the validation set and the "
                "representative faults, the plots ...",
                file=sys.stderr,
                flush=True,
            )
        finish(cfg, out, state)
        print(
            f"wrote {out}/gains.json, report.md, history.csv and plots "
            f"({state.wall_seconds:.0f} s)"
        )
        return 0
    except (CLIError, UsageError, ParameterError) as e:
        print(f"tuning.optimize: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"tuning.optimize: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\ntuning.optimize: interrupted; continue with --resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
