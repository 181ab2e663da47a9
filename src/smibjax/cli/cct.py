"""`python -m smibjax cct`: critical clearing times of one or more controllers, a
table on stdout and (with --out) a JSON file and its plot."""

from __future__ import annotations

import sys
import warnings
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
    positive,
    solver_options,
)

__all__ = ["add_parser", "run", "add_cct_options", "check_args", "run_grouped"]


def add_cct_options(p, with_reactance=True) -> None:
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
    p.add_argument("--tol", type=positive, default=1e-3, help="bisection tolerance (s)")
    p.add_argument(
        "--scan-step",
        type=float,
        default=0.05,
        help="spacing (s) of the scan of clearing durations that precedes the "
        "bisection and finds non-monotone stability (default 0.05)",
    )


def add_parser(sub) -> None:
    c = sub.add_parser(
        "cct", help="critical clearing times: vmapped scan, then bisection"
    )
    add_common(c, several_controllers=True)
    add_cct_options(c)
    add_tolerances(c)
    c.add_argument(
        "--t-end",
        type=positive,
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
    c.add_argument(
        "--out",
        metavar="FILE.json",
        nargs="?",
        const=UNNAMED,
        help="write the CCTs (+ a .png plot); --out alone: a new file "
        "runs/cct-<time>.json (default: nothing written)",
    )
    add_force(c)
    add_case_options(c, events=False)
    c.add_argument(
        "--fault-buses",
        default="all",
        help="with --case: the fault buses, e.g. 7,8,9 (default all)",
    )
    c.add_argument(
        "--cct-max",
        type=positive,
        default=1.0,
        help="with --case: the longest fault duration tried (s, default 1)",
    )
    c.set_defaults(func=run, flags=c.flags, precheck=precheck)


def check_args(args) -> None:
    """The CCT options, checked by the library before any work."""
    from .._cct import check_options

    check_options(
        args.fault_location,
        args.fault_time,
        args.reclose_time,
        getattr(args, "fault_reactance", 0.0),
        args.tol,
        args.scan_step,
        args.t_end,
        getattr(args, "criterion", "settled"),
    )


def _sets(args):
    """{label: controller} for the CCT lanes: one per --controller (default: the
    gains file's controller, else aftsc); each set's context is kept in
    `args.contexts`."""
    controllers = args.controller or [None]  # None: the gains file's, else aftsc
    out, common = {}, None
    args.contexts = {}
    for c in dict.fromkeys(controllers):
        params, plant, op, init = build_from_args(args, complete=True, controller=c)
        out[args.context.controller] = controller_of(
            params, args.adaptation, args.context
        )
        args.contexts[args.context.controller] = args.context.describe()
        common = (plant, op, init)
    return out, common


def run_grouped(args, sets, plant, op, init, progress=None) -> dict:
    """`critical_clearing_times` with the CCT options of `args`, once per kind of
    controller (`smibjax._cct.lane_kind`), merged in the order of `sets`; `progress`:
    a factory of one progress callback per call (e.g. `progress_bar`)."""
    from .. import _cct  # (looked up at call time: tests replace the engine)
    from .compare import merge_cct

    critical_clearing_times, lane_kind = _cct.critical_clearing_times, _cct.lane_kind

    groups: dict[tuple, dict] = {}
    for name, ctrl in sets.items():
        groups.setdefault(lane_kind(ctrl), {})[name] = ctrl
    results = [
        critical_clearing_times(
            g,
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
            solver=solver_options(args),
            progress=progress() if progress else None,
        ).to_dict()
        for g in groups.values()
    ]
    return results[0] if len(results) == 1 else merge_cct(results, list(sets))


def progress_bar(desc: str = "cct scan + bisection", make=None):
    """A `progress(done, total)` callback drawing a tqdm bar (closed at done ==
    total); `make`: the bar factory of `progress_bars()` (which closes the bar when
    the command ends, also on an error), else tqdm itself."""
    if make is None:
        from tqdm.auto import tqdm as make

    state: dict = {}

    def update(done: int, total: int) -> None:
        if state.get("closed"):
            return
        bar = state.get("bar")
        if bar is None:
            bar = state["bar"] = make(total=total, desc=desc)
        bar.update(done - bar.n)
        if done >= total:
            close()

    def close() -> None:
        """Close the bar (also when the work stopped early, on an error): an error
        line then starts on a line of its own."""
        if state.get("bar") is not None and not state.get("closed"):
            state["bar"].close()
        state["closed"] = True

    update.close = close
    return update


def output(args):
    """The --out file: as named (`json_name`: .json appended without a suffix), a
    new one under `OUTPUT_ROOT` for `--out` alone (runs/cct-<time>.json), else
    None."""
    out = out_path(args.out, "cct", ".json", default=False)
    return None if out is None else json_name(out)


def json_name(path) -> Path:
    """`path` with `.json` appended when it has no suffix; any suffix but .json is a
    one-line CLIError (the CCTs are JSON, the plot goes beside them as .png)."""
    p = Path(path)
    if not p.suffix:
        return p.with_name(p.name + ".json")
    if p.suffix.lower() != ".json":
        raise CLIError(
            f"--out = {str(p)!r} is not allowed: must end in .json (the CCTs are "
            "written as JSON, their plot beside them as .png)"
        )
    return p


def precheck(args) -> None:
    """Before JAX starts: --out names a .json file (or has no suffix)."""
    if args.out:
        json_name(args.out)


def run(args) -> int:
    from .._files import check_new_file, write_json
    from .plotting import plot_cct

    args.out = output(args)
    if args.case:
        from .grid import run_cct

        return run_cct(args)
    check_args(args)
    out = png = None
    if args.out:
        out = check_new_file(args.out, args.force, "--out")
        png = check_new_file(out.with_suffix(".png"), args.force, "--out (its plot)")
        if png == out:
            raise CLIError(
                f"--out = {str(out)!r} is not allowed: must not end in .png (the plot "
                "is written beside it as .png)"
            )
    sets, (plant, op, init) = _sets(args)
    from .._cct import BudgetWarning
    from .._commandline import announce_compile, progress_bars
    from .._parameters import PLANT_NAMES

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", BudgetWarning)
        # every bar this command draws is closed before any line is printed
        with (
            progress_bars() as make,
            announce_compile("the CCT scan and bisection", "jit_run"),
        ):
            res = run_grouped(
                args, sets, plant, op, init, lambda: progress_bar(make=make)
            )
    res["context"] = args.contexts
    # what the CCTs were computed for: each set's gains, the plant and the
    # operating point (with every --set / gains-file override applied)
    res["gains"] = {n: c.parameters() for n, c in sets.items()}
    res["plant"] = {k: float(getattr(plant, k)) for k in PLANT_NAMES}
    res["op"] = {"delta_e": float(op.delta_e), "Pm_ref": float(op.Pm_ref)}
    res["init"] = {"th1": float(init.th1), "th2": float(init.th2)}
    res["sets_given"] = list(args.set)
    for w in caught:
        if issubclass(w.category, BudgetWarning):
            print(f"smibjax: warning: {w.message}", file=sys.stderr)
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    print_cct(res)
    if out is not None:
        write_json(out, res)
        plot_cct(res, png)
        print(f"wrote {out} and {png}")
    return 0


def _cell(res: dict, r: dict, j: int) -> str:
    """One printed CCT cell: the number, '*' when not monotone, or what it is not."""
    st = r["status"][j]
    if st == "exceeds_window":
        return f"> {res['window']:g} (window)"
    if st == "unstable_at_min":
        return "none (unstable)" + ("*" if r["islands"][j] else "")
    return f"{r['cct'][j]:.4f}" + ("*" if st == "non_monotone" else "")


def print_cct(res: dict) -> None:
    """The CCT table on stdout: criterion and times, each set's context, one row per
    location, then notes on windows and non-monotone locations."""
    from .compare import context_text, islands_text

    locs = res["fault_location"]
    crit = res.get("criterion", "settled")
    print(
        f"critical clearing time (s), criterion {crit}, fault at "
        f"{res['fault_time']:g} s, reclose {res['reclose_time']:g} s, t_end "
        f"{res.get('t_end', 10.0):g} s, tol {res['tol']:g} s:"
    )
    limits = ""
    if isinstance(res.get("plant"), dict):  # the plant the CCTs were computed on
        from .report import plant_text

        limits = " " + plant_text(res["plant"]).removeprefix("plant ")
    for name, ctx in res.get("context", {}).items():
        c, a, p = context_text(ctx)
        print(f"  {name}: controller {c}, adaptation {a}, plant {p}{limits}")
    print(f"{'location':>10} " + " ".join(f"{n:>16}" for n in res["sets"]))
    for j, lam in enumerate(locs):
        cells = [_cell(res, r, j) for r in res["sets"].values()]
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
                    f"clearing durations {islands_text(r['islands'][j])} (scan "
                    "durations): the CCT is where stability first ends"
                )
