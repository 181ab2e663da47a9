"""Command line: `python -m smibjax {simulate,reproduce,montecarlo,cct,compare} ...`.

Bad input ends with one line on stderr (`smibjax: error: ...`) and exit status 2;
no traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

__all__ = ["main", "build_parameters"]


class CLIError(Exception):
    """A user error to report on one line."""


class _Parser(argparse.ArgumentParser):
    _sub = ""

    def error(self, message):  # one line, no usage dump
        where = f"python -m smibjax {self._sub} --help".replace("  ", " ")
        raise CLIError(f"{message} (see `{where}`)")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but arguments left over are reported with the help of the
        subcommand they were given to (argparse reports them at the top level)."""
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            sub = getattr(ns, "command", None) or ""
            where = f"python -m smibjax {sub} --help".replace("  ", " ")
            raise CLIError(
                f"unrecognized arguments: {' '.join(extras)} (see `{where}`)"
            )
        return ns


def _add_common(p: argparse.ArgumentParser) -> None:
    from .controllers import CONTROLLERS

    p.add_argument(
        "--controller",
        choices=list(CONTROLLERS),
        default=None,
        help="aftsc (alpha = 5/7), asc (alpha = 1), none (E_fd0 held, u_r = 0) or "
        "avr-pss (exciter + PSS + SVC regulator); default: the gains file's, else "
        "aftsc",
    )
    p.add_argument(
        "--preset",
        choices=["paper", "realistic"],
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
    _add_max_steps(p)


def _add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--force",
        action="store_true",
        help="replace existing output files (without it an existing file is refused "
        "before any work)",
    )


def _add_max_steps(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-steps",
        type=int,
        default=50_000,
        help="adaptive solver step budget per run (default 50000); a run that spends "
        "it is reported as such, not as stable",
    )


def _tolerance(text: str) -> float:
    """A solver tolerance (or a horizon, a sampling interval): a finite number > 0
    (checked while parsing, before any work starts)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid float value: {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text} is not allowed: must be > 0")
    return v


def _add_tolerances(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--rtol",
        type=_tolerance,
        default=1e-6,
        help="adaptive solver relative tolerance (default 1e-6)",
    )
    p.add_argument(
        "--atol",
        type=_tolerance,
        default=1e-8,
        help="adaptive solver absolute tolerance (default 1e-8; 1e-6 takes ~1.75x "
        "fewer AFTSC steps, delta within ~6e-6 rad: benchmarks/README.md)",
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
    from .controllers import CONTROLLERS, Synergetic, make_controller
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
    if gain_values is None:
        gain_values = read_gains(gains_file, complete=complete) if gains_file else {}
    groups = {"gains": {}, "plant": {}, "op": {}, "init": {}}
    synergetic = CONTROLLERS[controller] is Synergetic
    names = (
        GAIN_NAMES if synergetic else tuple(CONTROLLERS[controller].parameter_kinds())
    )
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
    if synergetic:
        gains = Gains.paper(controller, **values)
    else:
        gains = make_controller(controller, values)
    plant = Plant.preset(preset, **{**(plant_values or {}), **groups["plant"]})
    return (
        gains,
        plant,
        OperatingPoint(**groups["op"]),
        InitialEstimates(**groups["init"]),
    )


def _controller_of(args, params):
    """The controller that runs: `params` itself (none, avr-pss) or the paper's law
    with `params` as gains, the adaptation and the options (projection, phi_layer)
    of the resolved context."""
    from .controllers import Synergetic
    from .parameters import Gains

    if not isinstance(params, Gains):
        return params
    ctx = getattr(args, "context", None)
    return Synergetic.from_options(
        params, args.adaptation, ctx.options if ctx is not None else {}
    )


def _gains_context(path, controller=None, adaptation=None, preset=None, complete=False):
    """(Context, gain values) of the gains file at `path` (None: no file) under the
    flags given (None: not given): flag, else file, else the paper's default. The
    warnings (a flag contradicting the file) and notes (a flat file) go to stderr,
    one line each."""
    from .gainsfile import read, resolve

    gf = read(path, complete=complete) if path else None
    ctx, values, messages = resolve(
        gf, controller, adaptation, preset, source=f"--gains {path}"
    )
    for m in messages:
        print(f"smibjax: {m}", file=sys.stderr)
    return ctx, values


def _warn_plant_sets(ctx, sets: dict) -> None:
    """A warning for each `--set` of a plant value that contradicts the file's."""
    for name, value in sets.items():
        if name in ctx.plant and ctx.plant[name] != value:
            print(
                f"smibjax: warning: --set {name}={value:g} overrides {name} = "
                f"{ctx.plant[name]:g} of the gains file",
                file=sys.stderr,
            )


def _build_from_args(args, complete=False, controller=None):
    """`build_parameters` for a command with --gains/--controller/--preset/
    --adaptation: the context resolved (`_gains_context`) and written back into
    `args` (controller, preset, adaptation), so the rest of the command uses it.
    Returns (Gains, Plant, OperatingPoint, InitialEstimates)."""
    sets = _parse_sets(args.set)
    ctx, values = _gains_context(
        args.gains,
        controller if controller is not None else args.controller,
        args.adaptation,
        args.preset,
        complete,
    )
    _warn_plant_sets(ctx, sets)
    args.preset, args.adaptation = ctx.preset, ctx.adaptation
    args.context = ctx
    if controller is None:
        args.controller = ctx.controller
    return build_parameters(
        ctx.controller,
        ctx.preset,
        None,
        sets,
        complete,
        gain_values=values,
        plant_values=ctx.plant,
    )


def _cmd_simulate(args) -> int:
    from .io import write_npz
    from .metrics import metrics
    from .parameters import Fault
    from .plotting import plot_trajectory, trajectory_arrays
    from .report import format_summary, metrics_dict
    from .simulate import simulate

    out, plot = _simulate_outputs(args)
    gains, plant, op, init = _build_from_args(args)
    fault = Fault(
        t_fault=args.fault_time,
        t_clear=args.clear_time,
        t_reclose=args.reclose_time,
        lam=args.fault_location,
        Xf=args.fault_reactance,
    )
    traj = simulate(
        _controller_of(args, gains),
        fault,
        plant,
        op=op,
        init=init,
        t_end=args.t_end,
        dt_save=args.dt_save,
        rtol=args.rtol,
        atol=args.atol,
        max_steps=args.max_steps,
    )
    _warn_dt_save(args)
    m = metrics(traj)
    print(format_summary(gains, fault, plant, traj, m, args))
    arrays = trajectory_arrays(traj)
    if args.out:
        meta = {
            "gains": _parameter_values(gains),
            "fault": {k: float(getattr(fault, k)) for k in fault.__dataclass_fields__},
            "plant": {k: float(getattr(plant, k)) for k in plant.__dataclass_fields__},
            "adaptation": args.adaptation,
            "context": args.context.describe(),
            "metrics": {  # NaN (not reached) as null
                k: None if isinstance(v, float) and math.isnan(v) else v
                for k, v in metrics_dict(m).items()
            },
        }
        arrays["meta"] = np.array(json.dumps(meta, allow_nan=True))
        write_npz(out, arrays)
        print(f"wrote {out}")
    if plot:
        plot_trajectory(
            arrays,
            plot,
            _title(gains, fault, args),
            (-float(plant.D), float(plant.Pm)),
        )
        print(f"wrote {plot}")
    return 0


def _simulate_outputs(args) -> tuple[Path | None, Path | None]:
    """simulate's --out (.npz appended when missing) and --plot paths, refused before
    the run when they exist (without --force), name a folder, the same file, or (for
    --plot) a format that cannot be written."""
    from .io import check_new_file
    from .plotting import check_plot_path

    out = plot = None
    if args.out:
        out = Path(args.out)
        if out.suffix != ".npz":
            out = out.with_name(out.name + ".npz")
        out = check_new_file(out, args.force, "--out")
    if args.plot:
        plot = check_new_file(check_plot_path(args.plot), args.force, "--plot")
        if out is not None and plot.resolve() == out.resolve():
            raise CLIError(
                f"--plot = {str(plot)!r} is not allowed: must differ from --out"
            )
    return out, plot


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
    c = "AFTSC" if float(gains.alpha) < 1 else "ASC"
    return (
        f"{c}: beta = ({float(gains.beta1):g}, {float(gains.beta2):g}), "
        f"alpha = {float(gains.alpha):.3g}; fault {float(fault.t_fault):g} -> "
        f"{float(fault.t_clear):g} s, reclose {float(fault.t_reclose):g} s, "
        f"lam {float(fault.lam):g}, Xf {float(fault.Xf):g}; {args.preset} plant, "
        f"{args.adaptation} adaptation"
    )


def _read_dist(path):
    """A scenario distribution from a flat TOML/JSON table of name = [lo, hi]."""
    from .io import read_utf8, tomllib
    from .parameters import ParameterError
    from .scenarios import ScenarioDistribution

    if path is None:
        return ScenarioDistribution()
    p = Path(path)
    if not p.is_file():
        raise ParameterError(f"--dist file {str(p)!r} does not exist or is not a file")
    text = read_utf8(p)
    try:
        data = tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
    except ValueError as e:  # TOMLDecodeError and JSONDecodeError are ValueErrors
        raise ParameterError(f"--dist file {str(p)!r} is not valid: {e}") from e
    if not isinstance(data, dict):
        raise ParameterError(f"--dist file {str(p)!r} must hold a table")
    return ScenarioDistribution.from_dict(data)


def _fresh_out(kind: str) -> Path:
    import datetime

    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{kind}-{stamp}"


def _parameter_values(params) -> dict[str, float]:
    """A parameter set's tunable values (the paper's nine gains plus c1, c2, or a
    controller's own), as plain floats."""
    from .parameters import GAIN_NAMES, Gains

    if isinstance(params, Gains):
        return {k: float(getattr(params, k)) for k in GAIN_NAMES}
    return params.parameters()


def _spec_from_args(args, gains, plant, op, init, dist):
    from .montecarlo import MonteCarloSpec
    from .parameters import PLANT_NAMES

    if args.n < 1:
        raise CLIError(f"--n {args.n} is not allowed: must be >= 1")
    if args.chunk < 1:
        raise CLIError(f"--chunk {args.chunk} is not allowed: must be >= 1")
    return MonteCarloSpec(
        n=args.n,
        seed=args.seed,
        chunk=min(args.chunk, args.n),
        gains=_parameter_values(gains),
        plant={k: float(getattr(plant, k)) for k in PLANT_NAMES},
        op={"delta_e": float(op.delta_e), "Pm_ref": float(op.Pm_ref)},
        init={"th1": float(init.th1), "th2": float(init.th2)},
        dist=dist.to_dict(),
        adaptation=args.adaptation,
        controller=args.controller or "",
        options=dict(getattr(getattr(args, "context", None), "options", {}) or {}),
        t_end=args.t_end,
        rtol=args.rtol,
        atol=args.atol,
        max_steps=args.max_steps,
    )


def _runner(args):
    """The chunk runner: in this process, or on Dask (`--scheduler`, `--workers`)."""
    import contextlib

    if (
        getattr(args, "scheduler", None) is None
        and getattr(args, "workers", None) is None
    ):
        return contextlib.nullcontext(None)
    if args.scheduler is not None and args.workers is not None:
        raise CLIError("give --scheduler or --workers, not both")
    if args.workers is not None and args.workers < 1:
        raise CLIError(f"--workers {args.workers} is not allowed: must be >= 1")
    from .cluster import dask_runner

    return dask_runner(scheduler=args.scheduler, workers=args.workers)


def _run_mc(spec, out: Path, resume: bool, runner, title: str):
    """`run_montecarlo`, with a cluster failure (e.g. a chunk that keeps killing its
    workers) turned into one line that says how to finish the run."""
    from .montecarlo import run_montecarlo
    from .parameters import ParameterError

    try:
        return run_montecarlo(spec, out, resume=resume, runner=runner, title=title)
    except Exception as e:
        if runner is None or isinstance(e, (CLIError, ParameterError, OSError)):
            raise
        raise CLIError(
            f"the cluster failed ({type(e).__name__}: {e}); the chunks already "
            f"written are kept: finish with --resume --out {out}"
        ) from None


def _cmd_montecarlo(args) -> int:
    gains, plant, op, init = _build_from_args(args, complete=True)
    spec = _spec_from_args(args, gains, plant, op, init, _read_dist(args.dist))
    out = Path(args.out) if args.out else _fresh_out("montecarlo")
    if args.resume and not args.out:
        raise CLIError("--resume needs --out DIR (the folder of the run to finish)")
    title = _title_mc(gains, args)
    with _runner(args) as runner:
        _, summary = _run_mc(spec, out, args.resume, runner, title)
    _print_mc(summary, out)
    return 0


def _title_mc(gains, args) -> str:
    c = "AFTSC" if float(gains.alpha) < 1 else "ASC"
    return (
        f"{c}: beta = ({float(gains.beta1):g}, {float(gains.beta2):g}), "
        f"alpha = {float(gains.alpha):.3g}; {args.n} scenarios, seed {args.seed}, "
        f"{args.preset} plant, {args.adaptation} adaptation"
    )


def _print_mc(summary: dict, out: Path) -> None:
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


def _cct_sets(args):
    """{label: Gains} for the CCT lanes: one per --controller (default: the gains
    file's controller, else aftsc); each set's context is kept in `args.contexts`."""
    controllers = args.controller or [None]  # None: the gains file's, else aftsc
    out, common = {}, None
    for c in dict.fromkeys(controllers):
        gains, plant, op, init = _build_from_args(args, complete=True, controller=c)
        out[args.context.controller] = _controller_of(args, gains)
        args.contexts = {
            **getattr(args, "contexts", {}),
            **{args.context.controller: args.context.describe()},
        }
        common = (plant, op, init)
    return out, common


def _check_cct_args(args) -> None:
    if args.fault_time < 0:
        raise CLIError(f"--fault-time {args.fault_time:g} is not allowed: must be >= 0")
    if not math.isfinite(args.reclose_time):
        raise CLIError(
            f"--reclose-time {args.reclose_time:g} is not allowed: must be finite"
        )
    if args.reclose_time <= args.fault_time:
        raise CLIError(
            f"--reclose-time {args.reclose_time:g} is not allowed: must be after "
            f"--fault-time {args.fault_time:g}"
        )
    from .cct import MIN_TOL
    from .parameters import Fault

    window = args.reclose_time - args.fault_time
    if not MIN_TOL <= args.tol < window:
        raise CLIError(
            f"--tol {args.tol:g} is not allowed: must be within [{MIN_TOL:g}, "
            f"{window:g}) s"
        )
    if not (math.isfinite(args.t_end) and args.t_end > args.reclose_time):
        raise CLIError(
            f"--t-end {args.t_end:g} is not allowed: must be after --reclose-time "
            f"{args.reclose_time:g} (the fault time plus the clearing window)"
        )
    for lam in args.fault_location:  # every lane's fault, before any work
        if not 0 < lam < 1:
            raise CLIError(
                f"--fault-location {lam:g} is not allowed: must be within (0, 1)"
            )
        Fault(
            args.fault_time,
            args.fault_time + args.tol,
            args.reclose_time,
            lam,
            getattr(args, "fault_reactance", 0.0),
        )
    if not args.scan_step > 0:
        raise CLIError(f"--scan-step {args.scan_step:g} is not allowed: must be > 0")


def _cct_cell(res: dict, r: dict, j: int) -> str:
    """One printed CCT cell: the number, '*' when not monotone, or what it is not."""
    st = r["status"][j]
    if st == "exceeds_window":
        return f"> {res['window']:g} (window)"
    if st == "unstable_at_min":
        return "none (unstable)" + ("*" if r["islands"][j] else "")
    return f"{r['cct'][j]:.4f}" + ("*" if st == "non_monotone" else "")


def _islands_text(islands: list) -> str:
    """Stable islands as '[0.4, 0.45] s, [0.6, 0.6] s'."""
    return ", ".join(f"[{lo:g}, {hi:g}] s" for lo, hi in islands)


def _print_cct(res: dict) -> None:
    """The CCT table on stdout: criterion and times, each set's context, one row per
    location, then notes on windows and non-monotone locations."""
    from .compare import context_text

    locs = res["fault_location"]
    crit = res.get("criterion", "settled")
    print(
        f"critical clearing time (s), criterion {crit}, fault at "
        f"{res['fault_time']:g} s, reclose {res['reclose_time']:g} s, t_end "
        f"{res.get('t_end', 10.0):g} s, tol {res['tol']:g} s:"
    )
    for name, ctx in res.get("context", {}).items():
        c, a, p = context_text(ctx)
        print(f"  {name}: controller {c}, adaptation {a}, plant {p}")
    print(f"{'location':>10} " + " ".join(f"{n:>16}" for n in res["sets"]))
    for j, lam in enumerate(locs):
        cells = [_cct_cell(res, r, j) for r in res["sets"].values()]
        print(f"{lam:10g} " + " ".join(f"{c:>16}" for c in cells))
    if any("exceeds_window" in r["status"] for r in res["sets"].values()):
        print(
            f"note: '> {res['window']:g}' = still stable when cleared at reclosure: the "
            "CCT lies beyond the window (no number is given)"
        )
    for name, r in res["sets"].items():
        for j, lam in enumerate(locs):
            if r["islands"][j]:
                print(
                    f"* non-monotone: {name} at location {lam:g} is stable again for "
                    f"clearing durations {_islands_text(r['islands'][j])} (scan "
                    "durations): the CCT is where stability first ends"
                )


def _lane_kind(ctrl) -> tuple:
    """Controllers that can share one batch of CCT lanes (the same pytree shape)."""
    from .controllers import Synergetic

    if isinstance(ctrl, Synergetic):
        return ("Synergetic", ctrl.oracle, ctrl.phi_layer, ctrl.projection is None)
    return (type(ctrl).__name__,)


def _run_cct_grouped(args, sets, plant, op, init) -> dict:
    """`_run_cct` once per kind of controller (`_lane_kind`), merged in the order of
    `sets`."""
    from .compare import merge_cct

    groups: dict[tuple, dict] = {}
    for name, ctrl in sets.items():
        groups.setdefault(_lane_kind(ctrl), {})[name] = ctrl
    results = [_run_cct(args, g, plant, op, init) for g in groups.values()]
    return results[0] if len(results) == 1 else merge_cct(results, list(sets))


def _run_cct(args, sets, plant, op, init) -> dict:
    """`critical_clearing_times` with the CCT options of `args`."""
    from .cct import critical_clearing_times

    return critical_clearing_times(
        sets,
        plant,
        op=op,
        init=init,
        fault_locations=args.fault_location,
        fault_time=args.fault_time,
        reclose_time=args.reclose_time,
        fault_reactance=getattr(args, "fault_reactance", 0.0),
        tol=args.tol,
        scan_step=args.scan_step,
        criterion=getattr(args, "criterion", "settled"),
        adaptation=args.adaptation,
        t_end=args.t_end,
        max_steps=args.max_steps,
        rtol=args.rtol,
        atol=args.atol,
        progress=True,
    )


def _cmd_cct(args) -> int:
    from .io import check_new_file, write_json
    from .plotting import plot_cct

    _check_cct_args(args)
    out = png = None
    if args.out:
        out = check_new_file(args.out, args.force, "--out")
        png = check_new_file(out.with_suffix(".png"), args.force, "--out (its plot)")
        if png == out:
            raise CLIError(
                f"--out = {str(out)!r} is not allowed: must not end in .png (the plot "
                "is written beside it as .png)"
            )
    sets, (plant, op, init) = _cct_sets(args)
    res = _run_cct_grouped(args, sets, plant, op, init)
    res["context"] = args.contexts
    _print_cct(res)
    if out is not None:
        write_json(out, res)
        plot_cct(res, png)
        print(f"wrote {out} and {png}")
    return 0


def _cmd_compare(args) -> int:
    from .compare import merge_cct, resolve_gain_set_context, write_compare

    _check_cct_args(args)
    sets = _parse_sets(args.set)
    specs = args.gains or ["paper", "paper-asc", "stable"]
    gain_sets, contexts = {}, {}
    for spec in specs:
        label, g, ctx, messages = resolve_gain_set_context(
            spec, sets, args.adaptation, args.preset
        )
        for m in messages:
            print(f"smibjax: {m}", file=sys.stderr)
        _warn_plant_sets(ctx, sets)
        base, i = label, 2
        while label in gain_sets:
            label, i = f"{base}-{i}", i + 1
        gain_sets[label], contexts[label] = g, ctx
    # each set under its own plant and adaptation: (plant, op, init) per set
    parts = {
        label: build_parameters(
            ctx.controller, ctx.preset, None, sets, plant_values=ctx.plant
        )[1:]
        for label, ctx in contexts.items()
    }
    dist = _read_dist(args.dist)
    out = Path(args.out) if args.out else _fresh_out("compare")
    if out.exists() and any(out.iterdir()) and not args.resume:
        raise CLIError(
            f"--out {str(out)!r} exists and is not empty: choose a new folder or add "
            "--resume"
        )
    summaries, rows = {}, {}
    with _runner(args) as runner:
        for label, g in gain_sets.items():
            print(f"== {label}")
            plant, op, init = parts[label]
            args_set = argparse.Namespace(
                **{
                    **vars(args),
                    "adaptation": contexts[label].adaptation,
                    "controller": contexts[label].controller,
                    "context": contexts[label],
                }
            )
            spec = _spec_from_args(args_set, g, plant, op, init, dist)
            sub = out / label
            resume = args.resume and (sub / "run.json").is_file()
            r, s = _run_mc(spec, sub, resume, runner, label)
            summaries[label], rows[label] = s, r
    # one CCT sweep per (adaptation, plant) group of sets
    groups: dict[tuple, list[str]] = {}
    for label, ctx in contexts.items():
        key = (ctx.adaptation, ctx.preset, tuple(sorted(ctx.plant.items())))
        groups.setdefault(key, []).append(label)
    results = []
    for (adaptation, *_), labels in groups.items():
        plant, op, init = parts[labels[0]]
        lanes = {}
        for n in labels:
            ns = argparse.Namespace(adaptation=adaptation, context=contexts[n])
            lanes[n] = _controller_of(ns, gain_sets[n])
        args_group = argparse.Namespace(**{**vars(args), "adaptation": adaptation})
        results.append(_run_cct_grouped(args_group, lanes, plant, op, init))
    res = merge_cct(results, list(gain_sets))
    write_compare(
        out,
        summaries,
        rows,
        res,
        {label: ctx.describe() for label, ctx in contexts.items()},
    )
    print((out / "compare.md").read_text())
    print(f"wrote {out}/compare.md, compare.json, compare.png")
    return 0


def _add_mc_options(p, n_default: int) -> None:
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
        default=256,
        help="scenarios per batch (default 256: measured fastest on 2 cores)",
    )
    p.add_argument("--t-end", type=_tolerance, default=10.0, help="horizon (s)")
    p.add_argument(
        "--resume", action="store_true", help="finish the run in --out after a stop"
    )
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run chunks on this Dask scheduler"
    )
    p.add_argument(
        "--workers", type=int, help="run chunks on a local Dask cluster of N processes"
    )


def _add_cct_options(p, with_reactance=True) -> None:
    p.add_argument(
        "--fault-location",
        type=float,
        nargs="+",
        default=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9],
        metavar="L",
        help="fault locations in (0, 1) (default 0.1 ... 0.9)",
    )
    p.add_argument("--fault-time", type=float, default=0.5, help="t_fault (s)")
    p.add_argument("--reclose-time", type=float, default=2.0, help="t_reclose (s)")
    if with_reactance:
        p.add_argument("--fault-reactance", type=float, default=0.0, help="Xf (pu)")
    p.add_argument(
        "--tol", type=_tolerance, default=1e-3, help="bisection tolerance (s)"
    )
    p.add_argument(
        "--scan-step",
        type=float,
        default=0.05,
        help="spacing (s) of the scan of clearing durations that precedes the "
        "bisection and finds non-monotone stability (default 0.05)",
    )


def _cmd_reproduce(args) -> int:
    from .reproduce import reproduce

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CLIError(f"--out = {str(out)!r} is not allowed: must be a folder")
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise CLIError(
            f"--out = {str(out)!r} is not allowed: must be a new or empty folder (it "
            "holds files; add --force to replace the ones reproduce writes)"
        )
    reproduce(out, preset=args.preset, t_end=args.t_end)
    return 0


def _parser() -> argparse.ArgumentParser:
    top = _Parser(
        prog="python -m smibjax",
        description=(
            "Differentiable SMIB + SVC simulator under adaptive finite-time synergetic "
            "control."
        ),
    )
    from . import __version__

    top.add_argument("--version", action="version", version=f"smibjax {__version__}")
    sub = top.add_subparsers(dest="command", required=True, parser_class=_Parser)
    s = sub.add_parser("simulate", help="one closed-loop run: summary, npz, plot")
    s._sub = "simulate"
    _add_common(s)
    _add_tolerances(s)
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
    s.add_argument("--t-end", type=_tolerance, default=10.0, help="horizon (s)")
    s.add_argument(
        "--dt-save",
        type=_tolerance,
        default=0.01,
        help="sampling interval of the output (s), default 0.01",
    )
    s.add_argument("--out", metavar="FILE.npz", help="write the trajectory")
    s.add_argument(
        "--plot",
        metavar="FILE.png",
        help="plot every signal, in the format of the suffix (.png, .pdf, .svg, ...)",
    )
    _add_force(s)
    s.set_defaults(func=_cmd_simulate)
    r = sub.add_parser("reproduce", help="the paper's section 4 case, figures + table")
    r._sub = "reproduce"
    r.add_argument("--out", default="results/reproduce", help="output folder")
    r.add_argument("--preset", choices=["paper", "realistic"], default="paper")
    r.add_argument("--t-end", type=_tolerance, default=10.0, help="horizon (s)")
    _add_force(r)
    r.set_defaults(func=_cmd_reproduce)

    m = sub.add_parser(
        "montecarlo", help="batch Monte Carlo over fault scenarios (resumable)"
    )
    m._sub = "montecarlo"
    _add_common(m)
    _add_tolerances(m)
    _add_mc_options(m, 1000)
    m.add_argument("--out", metavar="DIR", help="output folder (default: runs/...)")
    m.set_defaults(func=_cmd_montecarlo)

    c = sub.add_parser(
        "cct", help="critical clearing times: vmapped scan, then bisection"
    )
    c._sub = "cct"
    _add_common(c)
    c.set_defaults(controller=None)
    for a in c._actions:
        if a.dest == "controller":
            a.nargs, a.default = "+", None
            a.help = "one or more of aftsc, asc (default aftsc)"
    _add_cct_options(c)
    _add_tolerances(c)
    c.add_argument(
        "--t-end",
        type=_tolerance,
        default=10.0,
        help="horizon of every run (s), after --reclose-time (default 10)",
    )
    c.add_argument(
        "--criterion",
        choices=["settled", "synchronism"],
        default="settled",
        help="settled: no loss of synchronism and delta back in its band by t_end "
        "(default); synchronism: no loss of synchronism up to t_end (the industry "
        "definition)",
    )
    c.add_argument("--out", metavar="FILE.json", help="write the CCTs (+ a .png plot)")
    _add_force(c)
    c.set_defaults(func=_cmd_cct)

    k = sub.add_parser(
        "compare", help="Monte Carlo and CCT of several gain sets side by side"
    )
    k._sub = "compare"
    k.add_argument(
        "--gains",
        action="append",
        metavar="FILE|NAME",
        help="a complete gains file or a built-in set (paper, paper-asc, stable, "
        "stable-asc); repeat for each set (default: paper, paper-asc, stable)",
    )
    k.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a gain (all sets), plant or operating-point value",
    )
    k.add_argument(
        "--preset",
        choices=["paper", "realistic"],
        default=None,
        help="plant of every set (default: each file's, else paper)",
    )
    k.add_argument(
        "--adaptation",
        choices=["oracle", "realizable"],
        default=None,
        help="adaptation of every set (default: each file's, else oracle)",
    )
    _add_max_steps(k)
    _add_tolerances(k)
    _add_mc_options(k, 1000)
    _add_cct_options(k, with_reactance=False)
    k.add_argument("--out", metavar="DIR", help="output folder (default: runs/...)")
    k.set_defaults(func=_cmd_compare)
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


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    from .parameters import ParameterError

    try:
        args = _parser().parse_args(argv)
        from . import enable_compilation_cache
        from .parallel import use_host_devices

        use_host_devices()  # before JAX starts its CPU backend
        enable_compilation_cache()
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
