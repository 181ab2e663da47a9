"""The command line and everything at the edge of smibjax: `python -m smibjax
{simulate,reproduce,montecarlo,cct,compare,modes} ...`, run folders, files and plots.

Layout: `process` (what an entry point sets up: devices, float64, equinox's error
mode, the compilation cache), `options` (the shared parser and options, also the
tuner's), `files` (reading TOML/JSON and gains files, atomic writes), one module per
command (`simulate`, `montecarlo`, `cct`, `compare`, `reproduce`, `modes`), `runs`
(Monte Carlo run folders and resume), `cluster` (Dask), `plotting` and `report`.

Bad input ends with one line on stderr (`smibjax: error: ...`) and exit status 2; no
traceback. Importing this package loads neither JAX nor equinox: `main` configures
the process first (`smibjax.configure`).
"""

from __future__ import annotations

import sys

__all__ = ["main", "run"]


def _parser():
    from .. import __version__
    from . import cct, compare, modes, montecarlo, reproduce, simulate
    from .options import Parser

    top = Parser(
        prog="python -m smibjax",
        description=(
            "Differentiable SMIB + SVC simulator under adaptive finite-time synergetic "
            "control."
        ),
    )
    top.add_argument("--version", action="version", version=f"smibjax {__version__}")
    sub = top.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in (simulate, reproduce, montecarlo, cct, compare, modes):
        command.add_parser(sub)
    return top


def run() -> None:
    """Console entry point (`smibjax`, `python -m smibjax`): `main`, then exit.

    Everything is written and closed by then; `gc.freeze()` spares the interpreter's
    final garbage collection over JAX's traced objects, which took ~0.3 s of every
    exit (measured after one `simulate`: exit 0.34 -> 0.07 s)."""
    import gc

    code = main()
    gc.freeze()
    sys.exit(code)


def precheck(args) -> None:
    """The checks that need no JAX, run before the process is configured: a --case
    or --dyr file that does not exist or is foreign (`grid.precheck_case`), and the
    command's own (`args.precheck`, e.g. `simulate --out`'s format); CLIError."""
    from .grid import precheck_case

    precheck_case(args)
    own = getattr(args, "precheck", None)
    if own is not None:
        own(args)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status. The command line is parsed first (no
    JAX: `--help` and usage errors answer at once), then the process is configured
    (`smibjax.configure`), then the command runs."""
    from .._commandline import CLIError, one_line

    args = None
    try:
        args = _parser().parse_args(argv)
        args.argv = list(sys.argv[1:] if argv is None else argv)  # for `given`
    except CLIError as e:
        print(f"smibjax: error: {e}", file=sys.stderr)
        return 2
    try:  # bad files and flags refused before JAX starts (it takes seconds)
        precheck(args)
    except CLIError as e:
        print(f"smibjax: error: {e}", file=sys.stderr)
        return 2
    from .._process import configure

    try:
        configure()
    except ValueError as e:  # a bad SMIBJAX_CACHE_MIN_COMPILE_S
        print(f"smibjax: error: {e}", file=sys.stderr)
        return 2
    from .._commandline import xla_alarms_explained
    from .._parameters import ParameterError

    try:
        with xla_alarms_explained():
            return args.func(args)
    except CLIError as e:
        print(f"smibjax: error: {e}", file=sys.stderr)
        return 2
    except ParameterError as e:
        flags = getattr(args, "flags", set())
        print(f"smibjax: error: {one_line(e, flags)}", file=sys.stderr)
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
