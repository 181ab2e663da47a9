"""The command line's shared options: one parser class (also the tuner's), the
options every command shares, and the parameter sets they build.

Values are validated once, by the library (`ParameterError`); `Parser` only types
them, and `one_line` turns a library error into the one line the user reads, naming
the command-line flag of the value where there is one.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from typing import TYPE_CHECKING

from .._commandline import CLIError, Parser, fresh_out, one_line
from .._names import CONTROLLER_NAMES, PRESETS

if TYPE_CHECKING:  # (the library loads in the functions: --help imports no JAX)
    from .._gainsfile import Context
    from .._options import SolverOptions
    from .._scenarios import ScenarioDistribution

__all__ = [
    "CLIError",
    "Parser",
    "one_line",
    "positive",
    "add_common",
    "add_force",
    "add_max_steps",
    "add_phi_layer",
    "with_phi_layer",
    "add_tolerances",
    "solver_options",
    "parse_sets",
    "build_parameters",
    "build_from_args",
    "controller_of",
    "parameter_values",
    "read_dist",
    "fresh_out",
    "warn_plant_sets",
]


def positive(text: str) -> float:
    """An argparse type: a finite number > 0 (a tolerance, a horizon, a sampling
    interval), checked while parsing, before any work starts."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text[:40]!r} is not allowed: must be a number"
        ) from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text} is not allowed: must be > 0")
    return v


def tolerance(text: str) -> float:
    """An argparse type: an adaptive solver tolerance in (0, 1e-2]
    (`smibjax._validate.MAX_TOLERANCE`: looser, the step-size controller rather than
    the plant decides the verdict)."""
    from .._validate import MAX_TOLERANCE

    v = positive(text)
    if v > MAX_TOLERANCE:
        raise argparse.ArgumentTypeError(
            f"{text} is not allowed: must be in (0, {MAX_TOLERANCE:g}] (a looser "
            "tolerance lets the solver, not the plant, decide the verdict)"
        )
    return v


def add_common(p: Parser, several_controllers: bool = False) -> None:
    """--controller (one, or `several_controllers`), --preset, --gains, --set,
    --adaptation, --max-steps, --phi-layer."""
    p.add_argument(
        "--controller",
        choices=list(CONTROLLER_NAMES),
        nargs="+" if several_controllers else None,
        default=None,
        help=(
            "one or more of " + ", ".join(CONTROLLER_NAMES) + " (default: the gains "
            "file's, else aftsc)"
            if several_controllers
            else "aftsc (alpha = 5/7), asc (alpha = 1), none (E_fd0 held, u_r = 0) "
            "or avr-pss (exciter + PSS + SVC regulator); default: the gains file's, "
            "else aftsc"
        ),
    )
    p.add_argument(
        "--preset",
        choices=list(PRESETS),
        default=None,
        help="plant input limits: paper (none) or realistic; default: the gains "
        "file's, else paper",
    )
    p.add_argument(
        "--gains",
        metavar="FILE",
        help="gains file (JSON/TOML): with context (schema smibjax.gains/1, as the "
        "tuner writes) or a flat table of gains",
    )
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
        default=None,
        help="oracle (paper, uses the true theta) or realizable (k1=k2=0); default: "
        "the gains file's, else oracle",
    )
    add_max_steps(p)
    add_phi_layer(p)


def add_phi_layer(p: Parser) -> None:
    p.add_argument(
        "--phi-layer",
        type=float,
        default=None,
        metavar="W",
        help="boundary layer of the evolution law (units of phi; 0: the exact "
        "finite-time law; aftsc/asc only; overrides the gains file's phi_layer "
        "option): fewer solver steps in the settled tail (benchmarks/README.md, "
        "'The settled tail')",
    )


def with_phi_layer(ctx: Context, layer: float | None) -> Context:
    """`ctx` with its `phi_layer` option replaced by `layer` (None: unchanged),
    validated by the controller's `check_options`; a controller without the
    option (none, avr-pss) refuses it with one line."""
    from .._parameters import ParameterError
    from ..controllers import CONTROLLERS

    if layer is None:
        return ctx
    cls = CONTROLLERS[ctx.controller]
    if "phi_layer" not in cls.option_names:
        raise ParameterError(
            f"phi_layer = {layer!r} is not allowed for controller "
            f"{ctx.controller!r}: only the paper's law (aftsc, asc) has a boundary "
            "layer"
        )
    options = cls.check_options(ctx.controller, {**ctx.options, "phi_layer": layer})
    return dataclasses.replace(ctx, options=options)


def add_force(p: Parser) -> None:
    p.add_argument(
        "--force",
        action="store_true",
        help="replace existing output files (without it an existing file is refused "
        "before any work)",
    )


def add_max_steps(p: Parser) -> None:
    p.add_argument(
        "--max-steps",
        type=int,
        default=50_000,
        help="adaptive solver step budget per run (default 50000); a run that spends "
        "it is reported as such, not as stable",
    )


def solver_options(args) -> SolverOptions:
    """The adaptive solver's options of a command with `add_tolerances` and
    `add_max_steps` (--rtol, --atol, --max-steps)."""
    from .._options import SolverOptions

    return SolverOptions(rtol=args.rtol, atol=args.atol, max_steps=args.max_steps)


def add_tolerances(p: Parser) -> None:
    p.add_argument(
        "--rtol",
        type=tolerance,
        default=1e-6,
        help="adaptive solver relative tolerance (default 1e-6)",
    )
    p.add_argument(
        "--atol",
        type=tolerance,
        default=1e-8,
        help="adaptive solver absolute tolerance (default 1e-8; 1e-6 takes ~1.75x "
        "fewer AFTSC steps, delta within ~6e-6 rad: benchmarks/README.md)",
    )


def parse_sets(items: list[str]) -> dict[str, float]:
    """`--set NAME=VALUE` items as a table."""
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


def build_parameters(
    controller="aftsc",
    preset="paper",
    gains_file=None,
    sets=None,
    complete=False,
    *,
    gain_values=None,
    plant_values=None,
):
    """(parameters, Plant, OperatingPoint, InitialEstimates) from the CLI's options:
    the controller's defaults (the paper's `Gains` for aftsc/asc, else the controller
    itself), then the gains file's values (or `gain_values`, already read; with
    `complete`, all nine gains), then `--set` values; the plant `preset`, then
    `plant_values` (a gains file's plant context), then `--set`."""
    from .._files import read_gains
    from .._parameters import (
        PLANT_NAMES,
        InitialEstimates,
        OperatingPoint,
        Plant,
    )
    from ..controllers import CONTROLLERS, parameter_set

    sets = dict(sets or {})
    if gain_values is None:
        gain_values = read_gains(gains_file, complete=complete) if gains_file else {}
    groups = {"gains": {}, "plant": {}, "op": {}, "init": {}}
    names = tuple(CONTROLLERS[controller].parameter_kinds())
    owners = {
        **{n: "gains" for n in names},
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
    values = {**gain_values, **groups["gains"]}
    gains = parameter_set(controller, values)
    plant = Plant.preset(preset, **{**(plant_values or {}), **groups["plant"]})
    return (
        gains,
        plant,
        OperatingPoint(**groups["op"]),
        InitialEstimates(**groups["init"]),
    )


def controller_of(params, adaptation: str, context: Context | None = None):
    """The controller that runs: `params` itself (none, avr-pss) or the paper's law
    with `params` as gains, the adaptation and the options (projection, phi_layer)
    of the context."""
    from ..controllers import as_controller

    return as_controller(
        params, adaptation, context.options if context is not None else {}
    )


def gains_context(path, controller=None, adaptation=None, preset=None, complete=False):
    """(Context, gain values) of the gains file at `path` (None: no file) under the
    flags given (None: not given): flag, else file, else the paper's default. The
    warnings (a flag contradicting the file) and notes (a flat file) go to stderr,
    one line each."""
    from .._files import read_gains_file
    from .._gainsfile import resolve
    from .._parameters import ParameterError

    try:
        gf = read_gains_file(path, complete=complete) if path else None
        ctx, values, messages = resolve(
            gf, controller, adaptation, preset, source=f"--gains {path}"
        )
    except ParameterError as e:
        # the file's own key names the value, never a flag of the same name
        text = str(e)
        raise CLIError(
            text if str(path) in text else f"{text} (in --gains {path})"
        ) from None

    for m in messages:
        print(f"smibjax: {m}", file=sys.stderr)
    return ctx, values


def warn_plant_sets(ctx: Context, sets: dict) -> None:
    """A warning for each `--set` of a plant value that contradicts the file's."""
    for name, value in sets.items():
        if name in ctx.plant and ctx.plant[name] != value:
            print(
                f"smibjax: warning: --set {name}={value:g} overrides {name} = "
                f"{ctx.plant[name]:g} of the gains file",
                file=sys.stderr,
            )


def plant_note(controller: str, preset: str, plant) -> str | None:
    """The note for a conventional controller (`conventional`, e.g. avr-pss) run on
    a `Plant` without input limits (the paper preset with no --set limit): its
    field voltage and SVC command are then unbounded and its result unrealistic (Vt
    up to 1.89 pu for avr-pss); None otherwise. The default plant is not changed:
    the paper case's results stay as they are."""
    from ..controllers import CONTROLLERS

    cls = CONTROLLERS.get(controller)
    if cls is None or not cls.conventional:
        return None
    limits = ("uf_min", "uf_max", "ur_min", "ur_max")
    if any(math.isfinite(float(getattr(plant, k))) for k in limits):
        return None
    return (
        f"note: {controller} runs on the {preset} plant, which has no input limits "
        "(an unbounded field voltage and SVC command: the terminal voltage of a "
        "conventional controller reaches 1.89 pu); --preset realistic runs it "
        "within a real exciter's and SVC's limits"
    )


def build_from_args(args, complete=False, controller=None):
    """`build_parameters` for a command with --gains/--controller/--preset/
    --adaptation: the context resolved (`gains_context`) and written back into
    `args` (controller, preset, adaptation, context), so the rest of the command
    uses it. Returns (parameters, Plant, OperatingPoint, InitialEstimates)."""
    from ..controllers import CONTROLLERS

    sets = parse_sets(args.set)
    ctx, values = gains_context(
        args.gains,
        controller if controller is not None else args.controller,
        args.adaptation,
        args.preset,
        complete,
    )
    if args.adaptation is not None and not CONTROLLERS[ctx.controller].has_adaptation:
        raise CLIError(
            f"--adaptation {args.adaptation} does not apply to controller "
            f"{ctx.controller!r}: only the paper's law (aftsc, asc) adapts"
        )
    warn_plant_sets(ctx, sets)
    ctx = with_phi_layer(ctx, getattr(args, "phi_layer", None))
    args.preset, args.adaptation = ctx.preset, ctx.adaptation
    args.context = ctx
    if controller is None:
        args.controller = ctx.controller
    built = build_parameters(
        ctx.controller,
        ctx.preset,
        None,
        sets,
        complete,
        gain_values=values,
        plant_values=ctx.plant,
    )
    note = plant_note(ctx.controller, ctx.preset, built[1])
    if note:
        print(f"smibjax: {note}", file=sys.stderr)
    return built


def parameter_values(params) -> dict[str, float]:
    """A parameter set's tunable values (the paper's nine gains plus c1, c2, or a
    controller's own), as plain floats."""
    from ..controllers import as_controller

    return as_controller(params).parameters()


def read_dist(path) -> ScenarioDistribution:
    """A scenario distribution from a TOML/JSON table of name = [lo, hi], or from
    the `[scenarios]` table of a tuning config (`D = []` there: the plant's own
    damping); None: the default distribution."""
    from .._files import read_data
    from .._parameters import ParameterError
    from .._scenarios import ScenarioDistribution

    if path is None:
        return ScenarioDistribution()
    data = read_data(path)
    if not isinstance(data, dict):
        raise ParameterError(f"--dist file {str(path)!r} must hold a table")
    if isinstance(data.get("scenarios"), dict):  # a tuning config: its scenarios
        data = {
            k: v for k, v in data["scenarios"].items() if not (k == "D" and v == [])
        }
    return ScenarioDistribution.from_dict(data)
