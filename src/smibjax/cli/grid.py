"""The commands on a multi-machine case (`--case NAME` or `--case FILE.raw --dyr
FILE.dyr`): `simulate`, `montecarlo` and `cct` hand over here when `--case` is given.

Events from the command line (times in s, buses and branches by PSS/E numbers):
`--fault-bus B` (a three-phase fault at bus B from --fault-time to --clear-time,
through --fault-reactance; with `--open-line A-B[:CKT]` it is cleared by opening that
line at --clear-time), `--fault-line A-B[:CKT]` (a fault at --fault-location along the
line, cleared by opening it at --clear-time; `--reclose` recloses it at
--reclose-time), `--trip-line A-B[:CKT]` and `--trip-gen BUS[:ID]` (at --fault-time;
no clearing time). A flag whose event is absent (`--open-line` without `--fault-bus`,
`--clear-time` without a fault) is refused in one line.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

from .options import CLIError

__all__ = [
    "add_case_options",
    "precheck_case",
    "run_simulate",
    "run_montecarlo",
    "run_cct",
    "load",
]

# the largest Monte Carlo chunk of a --case run: a chunk keeps every scenario's saved
# states (IEEE 39 at 1,001 samples: 1 MB each); the CPU time per scenario does not
# fall beyond a few dozen (benchmarks/grid_montecarlo.py)
GRID_CHUNK = 128


def load_case_reporting(name_or_raw, dyr=None, skip_unsupported=False):
    """`load_case` with the reader's warnings (a skipped dyr model, a remote
    regulated bus) printed as one "smibjax: warning: ..." line each on stderr."""
    import warnings

    from ..grid.case import load_case

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        case = load_case(name_or_raw, dyr, skip_unsupported=skip_unsupported)
    for w in caught:
        print(f"smibjax: warning: {w.message}", file=sys.stderr)
    return case


_SNIFF_BYTES = 1 << 16


def _text_head(path: Path, flag: str, kind: str) -> list[str]:
    """The first lines of a file that must exist and be text (no NUL byte in its
    first 64 KiB); CLIError (one line) otherwise."""
    if not path.exists():
        raise CLIError(f"{flag} {str(path)!r}: no such file")
    if not path.is_file():
        raise CLIError(
            f"{flag} {str(path)!r} is not allowed: must be a {kind} (a file)"
        )
    with open(path, "rb") as fh:
        head = fh.read(_SNIFF_BYTES)
    if b"\x00" in head:
        raise CLIError(
            f"{flag} {str(path)!r} is not allowed: must be a {kind} (this is a binary "
            "file)"
        )
    return head.decode("utf-8", errors="replace").splitlines()


def _looks_like_raw(lines: list[str]) -> bool:
    """The first line is a PSS/E case identification: IC (0 or 1), SBASE (a number)
    and REV (an integer), comma- or blank-separated, before any '/' comment."""
    if not lines:
        return False
    fields = [f for f in re.split(r"[,\s]+", lines[0].split("/")[0].strip()) if f]
    try:
        ic, rev = int(fields[0]), int(fields[2])
        float(fields[1])
    except (IndexError, ValueError):
        return False
    return ic in (0, 1) and rev > 0


_DYR_RECORD = re.compile(r"^\s*\d+\s*[,\s]\s*'[^']+'")


def precheck_case(args) -> None:
    """Refuse a --case or --dyr file that does not exist or is not what it should
    be (a PSS/E raw file, a dyr file) in one line, before JAX is imported (the full
    reader, with every record checked, runs after). A --case that is not a file
    name (no .raw suffix, no such path) is left to the case loader (built-in
    names)."""
    case, dyr = getattr(args, "case", None), getattr(args, "dyr", None)
    if not case:
        from .._commandline import given

        for flag in ("--load-model", "--step", "--load-step", "--trip-load"):
            if given(args, flag):  # issue 47's options of a case
                raise CLIError(
                    f"{flag} is not allowed without --case: the paper's SMIB has no "
                    "PSS/E loads, exciter or governor references"
                )
        return
    p = Path(case)
    if not dyr and (p.suffix.lower() == ".raw" or p.is_file()):
        raise CLIError(f"{case}: a raw file needs its dyr file (--dyr)")  # as load_case
    if p.suffix.lower() == ".raw" or p.exists() or dyr:
        if not _looks_like_raw(_text_head(p, "--case", "PSS/E raw file")):
            raise CLIError(
                f"--case {str(p)!r} is not allowed: not a PSS/E raw file (its first "
                "line is not a case identification IC, SBASE, REV, ...)"
            )
    if dyr:
        lines = _text_head(Path(dyr), "--dyr", "PSS/E dyr file")
        if not any(_DYR_RECORD.match(line) for line in lines[:400]):
            raise CLIError(
                f"--dyr {str(dyr)!r} is not allowed: not a PSS/E dyr file (no record "
                "BUS 'MODEL' ... in its first lines)"
            )


_EVENT_FLAGS = ("fault_bus", "fault_line", "trip_line", "trip_gen")
_EVENT_FLAGS += ("step", "load_step", "trip_load")


def require_an_event(args) -> None:
    """`simulate --case` needs at least one event; CLIError (one line) otherwise.
    Needs no JAX: `precheck` runs it before JAX starts."""
    if any(getattr(args, a, None) not in (None, [], (), "") for a in _EVENT_FLAGS):
        return
    raise CLIError(
        "a --case run needs an event: --fault-bus, --fault-line, --trip-line, "
        "--trip-gen, --step, --load-step or --trip-load"
    )


def add_case_options(p, events: bool = True) -> None:
    """The options that choose a multi-machine case (and, for `events`, the events
    of one run)."""
    g = p.add_argument_group("multi-machine case (smibjax.grid)")
    g.add_argument(
        "--case",
        metavar="NAME|FILE.raw",
        help="a built-in case (kundur, kundur-gencls, kundur-nopss, kundur-synex, ieee39, "
        "ieee39-pss, ieee39-gencls, smib, smib-gencls, ieee14, wecc179, npcc, nordic44) "
        "or a PSS/E v32-v35 raw file (with --dyr); without it the command runs the "
        "paper's SMIB",
    )
    g.add_argument(
        "--dyr", metavar="FILE.dyr", help="the dyr file of a --case raw file"
    )
    g.add_argument(
        "--skip-unsupported",
        action="store_true",
        help="skip the dyr records of models smibjax does not have (one warning per "
        "model; an exciter or governor skipped leaves its machine's field voltage "
        "or mechanical power constant) instead of refusing the file",
    )
    g.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="MODEL.PARAM=VALUE",
        help="set a device parameter (e.g. IEEEST.KS=20, SEXS[1:1].K=150); repeatable",
    )
    g.add_argument(
        "--load-factor",
        type=float,
        default=1.0,
        help="scale every load (P and Q) and the non-slack generation (default 1)",
    )
    # issue 47: loads as PSS/E models them
    g.add_argument(
        "--load-model",
        metavar="SPEC",
        help="the loads in dynamics: 'p=P,I,Z q=P,I,Z [pqbrak=0.7] [ibrak=0.5]', the "
        "shares of each load's constant power kept as constant power, converted to "
        "constant current and to constant impedance (PSS/E's CONL), or impedance, "
        "current, power; default: every load a constant impedance "
        "(docs/loads-events.md)",
    )
    if events:
        g.add_argument("--fault-bus", type=int, metavar="BUS", help="bus fault at BUS")
        g.add_argument(
            "--fault-line", metavar="A-B[:CKT]", help="fault on a line, opened to clear"
        )
        g.add_argument(
            "--reclose",
            action="store_true",
            help="reclose --fault-line at --reclose-time",
        )
        g.add_argument(
            "--open-line",
            metavar="A-B[:CKT]",
            help="with --fault-bus: clear the fault by opening this line at "
            "--clear-time (the fault is removed and the line stays open)",
        )
        g.add_argument(
            "--trip-line", metavar="A-B[:CKT]", help="open a line at --fault-time"
        )
        g.add_argument("--trip-gen", metavar="BUS[:ID]", help="trip a generator")
        # issue 47, part 3: reference steps, load steps and trips
        g.add_argument(
            "--step",
            action="append",
            default=[],
            metavar="BUS[:ID]:SIGNAL=DELTA@T",
            help="step a controller reference of a generator at T s: SIGNAL Vref "
            "(the exciter's voltage reference, pu) or Pref (the governor's reference, "
            "in its model's units), e.g. 3:1:Vref=+0.05@1.0; repeatable",
        )
        g.add_argument(
            "--load-step",
            action="append",
            default=[],
            metavar="BUS[:ID]=DELTA@T",
            help="change a load by DELTA of its power at T s (every part alike), "
            "e.g. 7:1=+10%%@1.0 or 7=-0.2@2; repeatable",
        )
        g.add_argument(
            "--trip-load",
            action="append",
            default=[],
            metavar="BUS[:ID][@T]",
            help="trip a load at T s (default --fault-time); repeatable",
        )


def _branch_spec(text: str, flag: str):
    a, sep, rest = text.partition("-")
    b, _, ckt = rest.partition(":")
    try:
        spec = (int(a), int(b)) + ((ckt.strip(),) if ckt.strip() else ())
    except ValueError:
        raise CLIError(
            f"{flag} {text!r} is not allowed: expected FROM-TO[:CKT]"
        ) from None
    if not sep:
        raise CLIError(f"{flag} {text!r} is not allowed: expected FROM-TO[:CKT]")
    return spec


def _params(items) -> dict:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not math.isfinite(out.get(name.strip(), math.nan)):
            raise CLIError(
                f"--param {item!r} is not allowed: expected MODEL.PARAM=VALUE with a "
                "finite number"
            )
    return out


_SMIB_FLAGS = (
    "--set",
    "--gains",
    "--controller",
    "--preset",
    "--adaptation",
    "--max-steps",
    "--phi-layer",
)
SMIB_ONLY = {
    "simulate": _SMIB_FLAGS,
    "montecarlo": (*_SMIB_FLAGS, "--dist"),
    "cct": (
        *_SMIB_FLAGS,
        "--fault-location",
        "--fault-reactance",
        "--reclose-time",
        "--scan-step",
        "--criterion",
    ),
    "compare": (
        *_SMIB_FLAGS,
        "--resume",
        "--dist",
        "--scheduler",
        "--workers",
        "--fault-location",
        "--reclose-time",
        "--scan-step",
    ),
}
"""Per command, the flags of the paper's SMIB that a --case run has no use for: each
is refused when given (at any value), never ignored."""


def refuse_smib_flags(args) -> None:
    """CLIError (one line) for a flag of `SMIB_ONLY` given with --case, or a flag
    given without the flag it qualifies (`simulate --reclose` without
    --fault-line, --reclose-time without --reclose, --fault-location without
    --fault-line)."""
    from .._commandline import given

    for flag in SMIB_ONLY.get(getattr(args, "command", ""), _SMIB_FLAGS):
        if given(args, flag):
            hint = (
                "a case's parameters take --param MODEL.PARAM=VALUE"
                if flag in ("--set", "--gains", "--preset", "--adaptation")
                else "a case's devices come from its dyr file"
                if flag in ("--controller", "--phi-layer")
                else "it has no meaning for a case"
            )
            raise CLIError(
                f"{flag} is not allowed with --case: it is an option of the paper's "
                f"SMIB; {hint}"
            )
    if getattr(args, "command", "") == "simulate":
        needs = (
            ("--reclose", "--fault-line", bool(args.fault_line)),
            ("--reclose-time", "--reclose", bool(args.reclose)),
            ("--fault-location", "--fault-line", bool(args.fault_line)),
            ("--open-line", "--fault-bus", args.fault_bus is not None),
            (
                "--clear-time",
                "a fault (--fault-bus or --fault-line)",
                args.fault_bus is not None or bool(args.fault_line),
            ),
        )
        for flag, needed, have in needs:
            if given(args, flag) and not have:
                raise CLIError(f"{flag} is not allowed without {needed} on a case")


def load(args, initialize: bool = True):
    """(case, operating point, power flow) from the arguments; CLIError on bad
    input (one line). Without `initialize`, the operating point is None and the
    case is the one the power flow solved (loads scaled by --load-factor)."""
    from ..grid.case import CaseError
    from ..grid.operating import operating_point, scaled_power_flow
    from ..grid.params import ParamError, set_params
    from ..grid.powerflow import PowerFlowError
    from ..grid.psse import PsseError

    refuse_smib_flags(args)
    if (
        args.dyr
        and not str(args.case).endswith(".raw")
        and not Path(args.case).exists()
    ):
        raise CLIError(f"--case {args.case!r}: with --dyr, --case must be a raw file")
    if not (args.load_factor > 0 and math.isfinite(args.load_factor)):
        raise CLIError(f"--load-factor {args.load_factor} is not allowed: must be > 0")
    try:
        case = load_case_reporting(args.case, args.dyr, args.skip_unsupported)
        params = _params(args.param)
        if params:
            case = set_params(case, params)
        case = _with_load_model(case, args)
        if initialize:
            op, pf = operating_point(case, args.load_factor, args.load_factor)
        else:
            op = None
            case, pf = scaled_power_flow(case, args.load_factor, args.load_factor)
    except (CaseError, PsseError, ParamError, PowerFlowError) as e:
        raise CLIError(str(e)) from None
    except FileNotFoundError as e:
        raise CLIError(f"{e.filename}: no such file") from None
    except ValueError as e:  # parameter checks of the device models
        raise CLIError(str(e).splitlines()[0]) from None
    return case, op, pf


def _with_load_model(case, args):
    """`case` with --load-model's loads (the case itself without the flag)."""
    spec = getattr(args, "load_model", None)
    if spec is None:
        return case
    from ..grid.loads import parse_load_model, with_load_model

    return with_load_model(case, parse_load_model(spec))


def events_from_args(case, args) -> tuple:
    """The events of one run from the command line (positions resolved, checked)."""
    from ..grid.events import BranchClose, BranchTrip, BusFault, GenTrip, LineFault
    from ..grid.operating import check_islanding
    from ..grid.scenarios import branch_positions

    sys_ = case.system
    t_on, t_off = args.fault_time, args.clear_time
    faulted = args.fault_bus is not None or bool(args.fault_line)
    if faulted and not (0 <= t_on < t_off < args.t_end):
        raise CLIError(
            f"--fault-time {t_on} and --clear-time {t_off} must satisfy 0 <= fault < "
            f"clear < --t-end {args.t_end}"
        )
    if not (0 <= t_on < args.t_end):  # a trip alone: no clearing time
        raise CLIError(
            f"--fault-time {t_on} must satisfy 0 <= time < --t-end {args.t_end}"
        )
    if not 0 <= args.fault_reactance < math.inf:
        raise CLIError(
            f"--fault-reactance {args.fault_reactance} is not allowed: must be finite "
            "and >= 0 (pu)"
        )
    ev = []
    try:
        if args.fault_bus is not None:
            ev.append(
                BusFault(
                    bus=sys_.bus_index(args.fault_bus),
                    t_on=t_on,
                    t_off=t_off,
                    x=args.fault_reactance,
                )
            )
        if args.open_line:  # the bus fault cleared by opening a line
            k = int(
                branch_positions(sys_, [_branch_spec(args.open_line, "--open-line")])[0]
            )
            ev.append(BranchTrip(branch=k, t=t_off))
        if args.fault_line:
            k = int(
                branch_positions(sys_, [_branch_spec(args.fault_line, "--fault-line")])[
                    0
                ]
            )
            lam = args.fault_location
            if not 0 < lam < 1:
                raise CLIError(f"--fault-location {lam} must lie in (0, 1)")
            ev += [
                LineFault(
                    branch=k, frac=lam, t_on=t_on, t_off=t_off, x=args.fault_reactance
                ),
                BranchTrip(branch=k, t=t_off),
            ]
            if args.reclose:
                if not t_off < args.reclose_time < args.t_end:
                    raise CLIError(
                        f"--reclose-time {args.reclose_time} must lie between "
                        f"--clear-time and --t-end"
                    )
                ev.append(BranchClose(branch=k, t=args.reclose_time))
        if args.trip_line:
            k = int(
                branch_positions(sys_, [_branch_spec(args.trip_line, "--trip-line")])[0]
            )
            ev.append(BranchTrip(branch=k, t=t_on))
        if args.trip_gen:
            ev.append(GenTrip(gen=_gen_position(case, args.trip_gen), t=t_on))
        ev += _step_events(case, args)
        ev.sort(key=lambda e: float(e.switches()[0]))
        check_islanding(case, ev)
        from ..grid.events import check_order, check_steps

        check_order(ev)
        check_steps(case, ev)
    except ValueError as e:
        raise CLIError(str(e).splitlines()[0]) from None
    if not ev:
        require_an_event(args)
    return tuple(ev)


def _at_time(text: str, flag: str, t_end: float, default=None) -> tuple[str, float]:
    """('what', t) from 'what@t' (t in [0, t_end)); `default` when there is no @."""
    what, at, t = text.rpartition("@") if "@" in text else (text, "", "")
    if not at:
        if default is None:
            raise ValueError(f"{flag} {text!r} is not allowed: give the time as @T (s)")
        return text, float(default)
    try:
        tv = float(t)
    except ValueError:
        raise ValueError(
            f"{flag} {text!r} is not allowed: {t!r} is not a time (s)"
        ) from None
    if not (0 <= tv < t_end):
        raise ValueError(
            f"{flag} {text!r} is not allowed: the time {tv:g} s must lie in [0, "
            f"--t-end {t_end:g})"
        )
    return what, tv


def _delta(text: str, flag: str, spec: str) -> float:
    """A signed change: '+0.05', '-0.1', '+10%' (a percentage of the load)."""
    pct = text.endswith("%")
    try:
        v = float(text[:-1] if pct else text)
    except ValueError:
        raise ValueError(
            f"{flag} {spec!r} is not allowed: {text!r} is not a number (or N%)"
        ) from None
    if not math.isfinite(v):
        raise ValueError(f"{flag} {spec!r} is not allowed: the change must be finite")
    return v / 100 if pct else v


def _load_position(case, spec: str, flag: str) -> int:
    """The position of load BUS[:ID] (ID 1 when omitted) in `System.loads`."""
    ld = case.system.loads
    nums = np.asarray(case.system.buses.number)[np.asarray(ld.bus, dtype=int)]
    ids = ld.ident or ("1",) * len(nums)
    names = [f"{int(b)}:{str(i).strip()}" for b, i in zip(nums, ids, strict=True)]
    name = spec.strip() if ":" in spec else f"{spec.strip()}:1"
    if name not in names:
        raise ValueError(
            f"{flag} {spec}: no load {name} (have {', '.join(names[:12])}"
            f"{' ...' if len(names) > 12 else ''})"
        )
    return names.index(name)


def _step_events(case, args) -> list:
    """The --step, --load-step and --trip-load events."""
    from ..grid.events import REF_SIGNALS, LoadStep, RefStep

    out = []
    for spec in args.step:
        body, t = _at_time(spec, "--step", args.t_end)
        target, eq, d = body.partition("=")
        gen, _, signal = target.rpartition(":")
        if not eq or not gen or signal not in REF_SIGNALS:
            raise ValueError(
                f"--step {spec!r} is not allowed: write BUS[:ID]:SIGNAL=DELTA@T with "
                f"SIGNAL one of {', '.join(REF_SIGNALS)} (e.g. 3:1:Vref=+0.05@1.0)"
            )
        out.append(
            RefStep(
                gen=_gen_position(case, gen, "--step"),
                delta=_delta(d, "--step", spec),
                t=t,
                signal=signal,
            )
        )
    for spec in args.load_step:
        body, t = _at_time(spec, "--load-step", args.t_end)
        where, eq, d = body.partition("=")
        if not eq:
            raise ValueError(
                f"--load-step {spec!r} is not allowed: write BUS[:ID]=DELTA@T (e.g. "
                "7:1=+10%@1.0)"
            )
        delta = _delta(d, "--load-step", spec)
        if delta < -1:
            raise ValueError(
                f"--load-step {spec!r} is not allowed: a load cannot fall by more "
                "than 100 % (-100 % trips it)"
            )
        out.append(
            LoadStep(load=_load_position(case, where, "--load-step"), delta=delta, t=t)
        )
    for spec in args.trip_load:
        where, t = _at_time(spec, "--trip-load", args.t_end, default=args.fault_time)
        out.append(
            LoadStep(load=_load_position(case, where, "--trip-load"), delta=-1.0, t=t)
        )
    return out


def _gen_position(case, spec: str, flag: str = "--trip-gen") -> int:
    from ..grid.loop import gen_names

    name = spec if ":" in spec else f"{spec}:1"
    names = gen_names(case)
    if name not in names:
        raise ValueError(
            f"{flag} {spec}: no generator {name} (have {', '.join(names)})"
        )
    return names.index(name)


def _size(case) -> str:
    """ "npcc (48 machines, 140 buses)"."""
    return f"{case.name} ({case.n_gen} machines, {case.system.n_bus} buses)"


COMPILE_S = (20.0, 0.5)
"""A first compile of a case's simulation takes about a + b * machines seconds on a
2-core CPU (measured: Kundur's 4 machines 21 CPU-s, NPCC's 48 machines 31 CPU-s,
`simulate --case` at load 3, 2026-12-03)."""


def compile_s(case, factor: float = 1.0) -> float:
    """The expected first compile time (s) of a program over `case` (`COMPILE_S`),
    times `factor` for a larger program (a batch with its metrics)."""
    a, b = COMPILE_S
    return factor * (a + b * case.n_gen)


def say_phase(what: str, program: str, seconds: float) -> None:
    """The line before a compile: 'compiling WHAT: about N s the first time, a few s
    once cached' (or, without a compilation cache, 'about N s')."""
    from .._process import cache_state

    if cache_state(program) == "off":
        text = f"about {seconds:.0f} s (no compilation cache)"
    else:
        text = f"about {seconds:.0f} s the first time, a few s once cached"
    print(f"compiling {what}: {text}", file=sys.stderr, flush=True)


def _solver_kw(args) -> dict:
    """The horizon, sampling and tolerances of a run, from the command line."""
    return dict(t_end=args.t_end, dt_save=args.dt_save, rtol=args.rtol, atol=args.atol)


def _describe(case, pf) -> str:
    counts = {}
    for g in (*case.machines, *case.controllers, *case.svcs, *case.injectors):
        counts[type(g).__name__] = counts.get(type(g).__name__, 0) + len(
            np.atleast_1d(getattr(g, "gen", getattr(g, "bus", [])))
        )
    devices = ", ".join(f"{n} {k}" for k, n in counts.items())
    return (
        f"case {case.name}: {case.system.n_bus} buses, {len(case.system.branches.fr)} "
        f"branches, {devices}; power flow in {int(pf.iterations)} iterations"
    )


def _event_text(case, ev) -> str:
    from ..grid.events import BranchClose, BranchTrip, BusFault, GenTrip, LineFault
    from ..grid.loop import gen_names

    num = np.asarray(case.system.buses.number)
    br = case.system.branches

    def line(k):
        return f"{num[br.fr[k]]}-{num[br.to[k]]}"

    out = []
    for e in ev:
        if isinstance(e, BusFault):
            out.append(
                f"fault at bus {num[int(e.bus)]} {float(e.t_on):g}-{float(e.t_off):g} s"
            )
        elif isinstance(e, LineFault):
            out.append(
                f"fault on {line(int(e.branch))} at {float(e.frac):g} "
                f"{float(e.t_on):g}-{float(e.t_off):g} s"
            )
        elif isinstance(e, BranchTrip):
            out.append(f"open {line(int(e.branch))} at {float(e.t):g} s")
        elif isinstance(e, BranchClose):
            out.append(f"close {line(int(e.branch))} at {float(e.t):g} s")
        elif isinstance(e, GenTrip):
            out.append(
                f"trip generator {gen_names(case)[int(e.gen)]} at {float(e.t):g} s"
            )
        else:
            out.append(f"{_step_text(case, e)} at {float(e.t):g} s")
    return "; ".join(out)


def _step_text(case, e) -> str:
    """A load step or trip, or a reference step, in words (PSS/E numbers)."""
    from ..grid.events import LoadStep
    from ..grid.loop import gen_names

    if isinstance(e, LoadStep):
        ld = case.system.loads
        k = int(e.load)
        bus = int(np.asarray(case.system.buses.number)[int(ld.bus[k])])
        name = f"{bus}:{str(ld.ident[k]).strip() if ld.ident else '1'}"
        d = float(e.delta)
        return f"trip load {name}" if d == -1 else f"load {name} {100 * d:+g} %"
    return f"{e.signal} of {gen_names(case)[int(e.gen)]} {float(e.delta):+g}"


# ---- the memory plan of grid runs (issue 46) ----


def _plan(case, events, args):
    from ..grid.events import LineFault
    from ..grid.memory import run_size

    samples = args.t_end / args.dt_save + 1
    n_lf = sum(isinstance(e, LineFault) for e in events)
    return run_size(case, samples, len(events), n_lf), samples


def _require_run_fits(case, events, args) -> None:
    """CLIError (one line) unless one run fits the memory available."""
    from .._validate import ParameterError
    from ..grid.memory import require_fit

    size, samples = _plan(case, events, args)
    try:
        require_fit(
            f"--t-end {args.t_end:g} with --dt-save {args.dt_save:g} ({samples:.4g} "
            f"samples of {case.system.n_bus} buses)",
            size,
            1,
            "shorten --t-end or raise --dt-save",
        )
    except ParameterError as e:
        raise CLIError(str(e)) from None


def _chunk_that_fits(case, events, args, chunk: int) -> int:
    """`chunk`, lowered to the largest batch that fits the memory available;
    CLIError (one line) if not even one run fits."""
    from ..grid.memory import chunk_that_fits

    size, _ = _plan(case, events, args)
    fit = chunk_that_fits(size, chunk)
    if fit < 1:
        _require_run_fits(case, events, args)
    return fit


def coi_record(case, tr) -> np.ndarray:
    """The recorded angles referred to the centre of inertia of the machines in
    service at each sample (rad, (T, n_gen)); a machine tripped during the run is NaN
    from its trip on (its frozen angle has no meaning against the others)."""
    from ..grid.trajectory import coi_angles

    on = np.asarray(tr.gen_on)
    rel = np.asarray(coi_angles(case, tr.delta, tr.gen_on))
    tripped = (on[:1] > 0) & (on <= 0)
    return np.where(tripped, np.nan, rel)


def warn_not_at_rest(case, dy0, most: int = 8) -> None:
    """One warning line per device that does not start at rest (its data put the
    operating point beyond its own limits: PSS/E's suspect initial conditions), the
    largest first, at most `most` and a count of the rest."""
    from ..grid.operating import not_at_rest

    rows = not_at_rest(case, dy0)
    for model, where, state, v in rows[:most]:
        print(
            f"smibjax: warning: {model} at {where} does not start at rest "
            f"(d{state}/dt = {v:.3g} at t = 0): its data or its controls' limits "
            "put the operating point beyond a limit; the run starts from there",
            file=sys.stderr,
        )
    if len(rows) > most:
        print(
            f"smibjax: warning: and {len(rows) - most} more devices not at rest",
            file=sys.stderr,
        )


def run_simulate(args) -> int:
    """`simulate --case`: one run; summary, the trajectory (per-generator and per-bus
    arrays with their PSS/E ids) in the format of the --out suffix, the plot."""

    from .._export import grid_columns, write_trajectory
    from .._files import check_new_file
    from ..grid.loop import gen_names
    from ._exported import run_grid
    from .simulate import check_out

    out = check_out(args.out, args.force) if args.out else None
    plot = None
    if args.plot:
        from .._figures import check_plot_path

        plot = check_new_file(check_plot_path(args.plot), args.force, "--plot")
    case, _, pf = load(args, initialize=False)
    ev = events_from_args(case, args)
    _require_run_fits(case, ev, args)
    print(_describe(case, pf), file=sys.stderr)
    print(f"events: {_event_text(case, ev)}", file=sys.stderr)
    t0 = time.perf_counter()
    t_first = min(float(e.switches()[0]) for e in ev)
    # a second run of this structure calls the stored program: no trace, no diffrax
    tr, m, dy0 = run_grid(
        case,
        pf,
        ev,
        t_first,
        before_trace=lambda: say_phase(
            f"the simulation of {_size(case)}", "jit__program", compile_s(case)
        ),
        **_solver_kw(args),
    )
    wall = time.perf_counter() - t0
    warn_not_at_rest(case, dy0)
    verdict = (
        "stable"
        if bool(tr.stable)
        else (
            "step budget exhausted"
            if bool(tr.exhausted)
            else ("VOLTAGE COLLAPSE" if bool(tr.collapsed) else "UNSTABLE")
        )
    )
    names = gen_names(case)
    print(f"{verdict} ({wall:.1f} s)")
    if bool(tr.collapsed):
        print(
            f"  the network has no solution from t = {float(tr.t_collapse):.3f} s "
            "(voltage collapse: constant power or current loads past the nose point)"
        )
    elif not bool(tr.stable) and not bool(tr.exhausted):
        print(
            f"  synchronism lost at t = {float(tr.t_unstable):.3f} s (|angle - COI| > pi)"
        )
    print(
        f"  settling (COI angles within 0.01 rad): {float(m.settling_angle):.2f} s; "
        f"speeds within 1e-4 pu: {float(m.settling_speed):.2f} s"
    )
    print(
        f"  overshoot {float(m.overshoot):.3f} rad; largest |angle - COI| "
        f"{float(m.max_spread):.3f} rad; bus voltages {float(m.v_min):.3f}-"
        f"{float(m.v_max):.3f} pu; peak Efd {float(m.efd_max):.3f} pu"
    )
    rel = coi_record(case, tr)
    arrays = {
        "t": np.asarray(tr.ts),
        "gen": np.array(names),
        "bus": np.asarray(case.system.buses.number),
        "delta": np.asarray(tr.delta),
        "delta_coi": rel,
        "omega": np.asarray(tr.omega),
        "efd": np.asarray(tr.efd),
        "pm": np.asarray(tr.pm),
        "pe": np.asarray(tr.pe),
        "vt": np.asarray(tr.vt),
        "vs": np.asarray(tr.vs),
        "v_bus": np.asarray(tr.v_bus),
        "meta": np.array(
            json.dumps(
                {
                    "case": case.name,
                    "events": _event_text(case, ev),
                    "stable": bool(tr.stable),
                    "t_unstable": float(tr.t_unstable),
                    "exhausted": bool(tr.exhausted),
                    "collapsed": bool(tr.collapsed),
                    "t_collapse": float(tr.t_collapse),
                    "load_model": getattr(args, "load_model", None),
                    "rtol": args.rtol,
                    "atol": args.atol,
                    "params": _params(args.param),
                    "load_factor": args.load_factor,
                    "units": "angles rad (synchronous frame; delta_coi: from the centre "
                    "of inertia), omega pu speed deviation, efd/vt/v_bus pu, pm/pe pu "
                    "machine base",
                }
            )
        ),
    }
    arrays |= ibr_arrays(case, tr)  # issue 47: the renewables' signals
    if out:
        written = write_trajectory(
            out,
            arrays,
            grid_columns(arrays),
            station=case.name,
            frequency=float(case.system.f_base),
            trigger=t_first,
        )
        print(f"wrote {', '.join(str(w) for w in written)}")
    if plot:
        plot_case(arrays, ev, case, plot)
        print(f"wrote {plot}")
    return 0


# issue 47: inverter-based resources
def ibr_arrays(case, tr) -> dict:
    """The renewables' signals of a run (`GridTrajectory.ibr`) as arrays of
    `simulate --case`: "ibr_gen" (the plants' bus:id) and "ibr_<signal>" (samples x
    plants) for Ip, Iq, Ipcmd, Iqcmd, LVPL, Ipmax, Iqmax, Qe, Pref, Qext (pu machine
    base) and Va (rad); none without renewables."""
    from ..grid.loop import gen_names

    if not tr.ibr:
        return {}
    names = gen_names(case)
    g = sorted(int(i) for d in case.injectors if hasattr(d, "signals") for i in d.gen)
    out = {"ibr_gen": np.array([names[i] for i in g])}
    for k, v in tr.ibr.items():
        out[f"ibr_{k}"] = np.asarray(v)[:, g]
    return out


def event_marks(case, ev) -> list[tuple[float, str]]:
    """The switchings of `ev` as (t (s), text) for a figure, buses and lines by
    their PSS/E numbers, generators by bus:id; switchings at one instant share one
    entry (a line fault cleared by opening its line: "clear: open 7-8 at 1.1 s")."""
    from ..grid.events import BranchClose, BranchTrip, BusFault, GenTrip, LineFault
    from ..grid.loop import gen_names

    num = np.asarray(case.system.buses.number)
    br = case.system.branches

    def line(k):
        return f"{num[br.fr[int(k)]]}-{num[br.to[int(k)]]}"

    marks: list[tuple[float, str]] = []
    for e in ev:
        if isinstance(e, BusFault):
            marks += [
                (float(e.t_on), f"fault at bus {num[int(e.bus)]}"),
                (float(e.t_off), f"clear: fault at bus {num[int(e.bus)]} removed"),
            ]
        elif isinstance(e, LineFault):
            marks += [
                (float(e.t_on), f"fault on {line(e.branch)} at {float(e.frac):g}"),
                (float(e.t_off), "clear: fault removed"),
            ]
        elif isinstance(e, BranchTrip):
            marks.append((float(e.t), f"open {line(e.branch)}"))
        elif isinstance(e, BranchClose):
            marks.append((float(e.t), f"reclose {line(e.branch)}"))
        elif isinstance(e, GenTrip):
            marks.append((float(e.t), f"trip G {gen_names(case)[int(e.gen)]}"))
        else:
            marks.append((float(e.t), _step_text(case, e)))
    merged: dict[float, list[str]] = {}
    for t, text in sorted(marks, key=lambda m: m[0]):
        merged.setdefault(round(t, 9), []).append(text)
    out = []
    for t, texts in merged.items():
        if texts[0] == "clear: fault removed" and len(texts) > 1:
            texts = ["clear: " + texts[1], *texts[2:]]
        out.append((t, "; ".join(texts) + f" at {t:g} s"))
    return out


def plot_case(a: dict, ev, case, path) -> None:
    """`plotting.plot_grid_run` of a `simulate --case` run: the machines with the
    largest swings named, the others a band, the events labelled, the buses of the
    voltage panel named by PSS/E number and name."""
    from .plotting import plot_grid_run

    plot_grid_run(
        a,
        path,
        f"{case.name}: {_event_text(case, ev)}",
        events=event_marks(case, ev),
        bus_names=list(case.system.buses.name) or None,
    )


def _grid_distribution(case, args):
    """(FaultDistribution, n, chunk) of the Monte Carlo options; one-line CLIError."""
    from ..grid.scenarios import FaultDistribution, sample_events

    try:
        dist = FaultDistribution(
            kind=args.fault_kind,
            buses=tuple(_int_list(args.fault_buses)),
            branches=tuple(
                _branch_spec(s, "--fault-lines") for s in _str_list(args.fault_lines)
            ),
            t_fault=_range(args.fault_times, "--fault-times"),
            clear_after=_range(args.clear_after, "--clear-after"),
            reclose=_range(args.reclose_after, "--reclose-after")
            if args.reclose_after
            else None,
        )
        if dist.t_last() >= args.t_end:
            raise CLIError(
                f"--t-end {args.t_end} must exceed the latest event time {dist.t_last():g} s"
            )
        n, chunk = int(args.n), int(min(args.chunk, args.n, GRID_CHUNK))
        if n < 1 or chunk < 1:
            raise CLIError(f"--n {args.n} and --chunk {args.chunk} must be >= 1")
        one = sample_events(case.system, dist, 1, args.seed)  # checks buses, lines
    except ValueError as e:
        raise CLIError(str(e)) from None
    return dist, n, _chunk_that_fits(case, one, args, chunk)


def _grid_spec(dist, n, chunk, args):
    """The `GridMonteCarloSpec` of the Monte Carlo options."""
    from ..grid.montecarlo import GridMonteCarloSpec, json_ready

    return GridMonteCarloSpec(
        n=n,
        seed=int(args.seed),
        chunk=chunk,
        t_end=float(args.t_end),
        dt_save=float(args.dt_save),
        rtol=float(args.rtol),
        atol=float(args.atol),
        distribution=json_ready(dataclasses.asdict(dist)),
    )


def grid_rows(case, op, dist, n, chunk, args, desc="scenarios"):
    """The rows (column -> array: scenario columns and `GridMetrics`) of `n`
    scenarios drawn from `dist` with seed `args.seed`, all drawn at once (the rows
    do not depend on --chunk; the same scenarios for every parameter set of the
    same case), run in chunks through one compiled program
    (`grid.montecarlo.chunk_runner`), in memory (compare --case)."""
    from .._commandline import progress_bars, say_compiling
    from ..grid.montecarlo import chunk_runner

    spec = _grid_spec(dist, n, chunk, args)
    compute = chunk_runner(case, op, spec)
    say_compiling("the batched case simulator", "jit_grid_batch_metrics")
    parts = []
    with progress_bars() as make:  # closed also when a chunk fails
        bar = make(total=n, desc=desc, unit="sc")
        for k in range(spec.n_chunks):
            parts.append(compute(k))
            bar.update(len(parts[-1]["index"]))
    rows = {c: np.concatenate([p[c] for p in parts]) for c in parts[0]}
    return rows, spec


def run_montecarlo(args) -> int:
    """`montecarlo --case`: fault scenarios drawn over buses or lines
    (`smibjax.grid.montecarlo`), run in chunks into the run folder --out (default:
    a new folder runs/montecarlo-<time>, as the SMIB's montecarlo): run.json (what
    the run computes and its context), chunks/NNNNNN.npz (each the moment it is
    computed), then scenarios.csv, summary.json, summary.md and montecarlo.png (as
    the SMIB's Monte Carlo). `--resume` finishes
    a run from the chunks on disk: the files are those of an uninterrupted run."""
    from .._commandline import out_path, progress_bars, say_compiling
    from .._files import check_out_folder
    from ..grid.montecarlo import chunk_runner

    refuse_smib_flags(args)
    if args.resume and not args.out:
        raise CLIError("--resume needs --out DIR (the folder of the run to finish)")
    out = out_path(args.out, "montecarlo")
    check_out_folder(out)  # before any work
    if not args.resume and out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise CLIError(
            f"--out {str(out)!r} exists and is not empty: choose a new folder or add "
            "--resume to finish the run in it"
        )
    case, op, pf = load(args)
    dist, n, chunk = _grid_distribution(case, args)
    spec = _grid_spec(dist, n, chunk, args)
    context = {
        "case": case.name,
        "case_files": [str(args.case), str(args.dyr) if args.dyr else None],
        "skip_unsupported": bool(args.skip_unsupported),
        "params": _params(args.param),
        "load_factor": float(args.load_factor),
    }
    manifest = {"spec": spec.to_dict(), "context": context, "complete": False}
    if args.resume:
        _check_grid_resume(out, manifest)
    else:
        _write_new(out / "run.json", json.dumps(manifest, indent=2) + "\n")
    print(_describe(case, pf), file=sys.stderr)
    todo = [k for k in range(spec.n_chunks) if not _grid_chunk_ok(out, spec, k)]
    t0 = time.perf_counter()
    if todo:
        done = spec.n - sum(
            spec.chunk_range(k)[1] - spec.chunk_range(k)[0] for k in todo
        )
        with contextlib.ExitStack() as stack:
            if args.workers is not None or args.scheduler is not None:
                # chunks on Dask: each worker rebuilds the case from the run's
                # context once and computes the chunks it is given
                from ..grid.montecarlo import GridChunkJob
                from .cluster import dask_runner, run_grid_chunk

                runner = stack.enter_context(
                    dask_runner(args.scheduler, args.workers, task=run_grid_chunk)
                )
                print(
                    "compiling the batched case simulator in each Dask worker",
                    file=sys.stderr,
                    flush=True,
                )
                files = [
                    str(Path(f).resolve()) if f and Path(f).exists() else f
                    for f in context["case_files"]
                ]
                job = GridChunkJob(context | {"case_files": files}, spec)
                chunks = runner(job, todo)
            else:
                compute = chunk_runner(case, op, spec)
                say_compiling("the batched case simulator", "jit_grid_batch_metrics")
                chunks = ((k, compute(k)) for k in todo)
            make = stack.enter_context(progress_bars())  # closed also on a failure
            bar = make(total=n, initial=done, desc="scenarios", unit="sc")
            for k, rows in chunks:
                _write_chunk(_grid_chunk_path(out, k), rows)
                bar.update(len(rows["index"]))
    wall = time.perf_counter() - t0
    rows, summary = _grid_finish(out, spec, context, manifest)
    print(
        f"{n} scenarios ({len(todo)} of {spec.n_chunks} chunks computed now, "
        f"{wall:.1f} s): stable {summary['stable_fraction']}, settling mean "
        f"{summary['settling_angle_s']['mean']} s"
    )
    print(f"wrote {out}/scenarios.csv, summary.json, summary.md, montecarlo.png")
    return 0


def _write_chunk(path: Path, rows: dict) -> None:
    """A computed chunk, atomically (a kill leaves it whole or absent)."""
    from .._files import write_npz

    write_npz(path, rows)


def _grid_chunk_path(out: Path, k: int) -> Path:
    return out / "chunks" / f"{k:06d}.npz"


def _grid_chunk_ok(out: Path, spec, k: int) -> bool:
    """Chunk k is on disk and whole (`runs.chunk_is_whole`); one that is not is
    recomputed."""
    from ..grid.montecarlo import METRIC_COLUMNS
    from .runs import chunk_is_whole

    start, stop = spec.chunk_range(k)
    must = ("index", "t_fault", "t_clear", *METRIC_COLUMNS)
    return chunk_is_whole(_grid_chunk_path(out, k), start, stop, must)


def _check_grid_resume(out: Path, manifest: dict) -> None:
    """CLIError (one line) unless `out` holds an unfinished run of the same spec and
    context."""
    path = out / "run.json"
    try:
        saved = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(saved, dict) or "spec" not in saved:
            raise ValueError("not a grid Monte Carlo run")
    except FileNotFoundError:
        raise CLIError(
            f"--resume: {str(out)!r} holds no Monte Carlo run (no run.json)"
        ) from None
    except (ValueError, UnicodeDecodeError) as e:
        reason = str(e).splitlines()[0][:80] if str(e) else type(e).__name__
        raise CLIError(
            f"--resume: {str(path)!r} is damaged ({reason}): start a new run in a "
            "new --out folder"
        ) from None
    if saved.get("complete"):
        raise CLIError(f"--resume: the run in {str(out)!r} is complete")
    old, new = _flat(saved), _flat(json.loads(json.dumps(manifest)))
    for key in new:
        if key != "complete" and old.get(key, "(absent)") != new[key]:
            raise CLIError(
                f"--resume: {key} = {new[key]!r} differs from the run in "
                f"{str(out)!r} ({key} = {old.get(key, '(absent)')!r}); repeat its "
                "options"
            )


def _flat(d: dict, head: str = "") -> dict:
    """A nested table as dotted keys."""
    out = {}
    for k, v in d.items():
        key = f"{head}.{k}" if head else str(k)
        if isinstance(v, dict):
            out.update(_flat(v, key))
        else:
            out[key] = v
    return out


def _write_new(path: Path, text: str) -> None:
    """Write a new file atomically, put in place with a hard link: refused (one
    line) if `path` exists by then (another run on the same --out), never replaced."""
    from .._files import atomic_write

    def w(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    atomic_write(path, w, new=True)


def _csv_cell(v) -> str:
    if isinstance(v, str | np.str_):
        return str(v)
    if isinstance(v, bool | np.bool_):
        return str(int(v))
    if isinstance(v, int | np.integer):
        return str(int(v))
    return f"{float(v):.10g}"


def _grid_summary_md(summary: dict, spec, context: dict) -> str:
    lines = [
        f"# Monte Carlo: {context['case']}",
        "",
        f"{spec.n} scenarios (seed {spec.seed}), t_end {spec.t_end:g} s, dt_save "
        f"{spec.dt_save:g} s, rtol {spec.rtol:g}, atol {spec.atol:g}, load factor "
        f"{context['load_factor']:g}, parameters "
        + (
            ", ".join(f"{k} = {v:g}" for k, v in context["params"].items())
            or "the case's"
        )
        + ".",
        "",
        "| figure | value |",
        "|---|---|",
    ]
    for k, v in summary.items():
        if k in ("context", "spec"):
            continue
        if isinstance(v, dict):
            v = ", ".join(f"{q} {x}" for q, x in v.items())
        lines.append(f"| {k} | {v} |")
    return "\n".join(lines) + "\n"


def _grid_finish(out: Path, spec, context: dict, manifest: dict):
    """Assemble the chunks into scenarios.csv, summary.json and summary.md (new
    files, hard-linked), then mark run.json complete."""
    from .._files import write_json
    from ..grid.montecarlo import summarize

    parts = []
    for k in range(spec.n_chunks):
        with np.load(_grid_chunk_path(out, k)) as z:
            parts.append({c: np.asarray(z[c]) for c in z.files})
    cols = list(parts[0])
    rows = {c: np.concatenate([p[c] for p in parts]) for c in cols}
    lines = [",".join(cols)]
    lines += [
        ",".join(_csv_cell(rows[c][i]) for c in cols) for i in range(len(rows["index"]))
    ]
    summary = summarize(rows) | {"spec": spec.to_dict(), "context": context}
    _write_new(out / "scenarios.csv", "\n".join(lines) + "\n")
    _write_new(out / "summary.json", json.dumps(_clean(summary), indent=2) + "\n")
    _write_new(out / "summary.md", _grid_summary_md(summary, spec, context))
    from .plotting import plot_grid_montecarlo

    plot_grid_montecarlo(
        rows,
        out / "montecarlo.png",
        f"{context.get('case', '')}: {len(rows['index'])} fault scenarios",
    )
    write_json(out / "run.json", manifest | {"complete": True})
    return rows, summary


def _clean(o):
    """inf and NaN as strings (JSON has neither)."""
    if isinstance(o, float) and not math.isfinite(o):
        return str(o)
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_clean(v) for v in o]
    return o


def _int_list(text):
    if not text or text == "all":
        return []
    try:
        return [int(s) for s in str(text).split(",") if s.strip()]
    except ValueError:
        raise CLIError(
            f"{text!r} is not a comma-separated list of bus numbers"
        ) from None


def _str_list(text):
    return (
        []
        if not text or text == "all"
        else [s for s in str(text).split(",") if s.strip()]
    )


def _range(text, flag):
    try:
        lo, hi = (float(s) for s in str(text).split(":"))
    except ValueError:
        raise CLIError(f"{flag} {text!r} is not allowed: expected LO:HI") from None
    return (lo, hi)


def add_montecarlo_options(p) -> None:
    g = p.add_argument_group("multi-machine Monte Carlo (with --case)")
    g.add_argument(
        "--fault-kind",
        choices=("bus", "line"),
        default="bus",
        help="faults at buses or along lines",
    )
    g.add_argument(
        "--fault-buses", default="all", help="bus numbers, e.g. 7,8,9 (default all)"
    )
    g.add_argument(
        "--fault-lines", default="all", help="lines A-B[:CKT],... (default all)"
    )
    g.add_argument(
        "--fault-times", default="0.5:1.0", help="fault time range LO:HI (s)"
    )
    g.add_argument("--clear-after", default="0.05:0.1", help="clearing time range (s)")
    g.add_argument("--reclose-after", default=None, help="reclosure delay range (s)")
    g.add_argument("--dt-save", type=float, default=0.01, help="sampling interval (s)")


def run_cct(args) -> int:
    """`cct --case`: the critical clearing time of a bolted fault at each bus of
    --fault-buses (cleared without tripping), by the engine's scan and bisection to
    --tol, all buses in one batch per step; with --out the JSON (its context: case,
    --param values, load factor, horizon and tolerances; rows by PSS/E bus number and
    name) and its plot beside it (.png)."""
    from .._files import check_new_file, write_json
    from .plotting import plot_case_cct

    out = png = None
    if args.out:
        out = check_new_file(args.out, args.force, "--out")
        png = check_new_file(out.with_suffix(".png"), args.force, "--out (its plot)")
    case, op, pf = load(args)
    try:
        buses = _int_list(args.fault_buses) or [
            int(b) for b in np.asarray(case.system.buses.number)
        ]
    except ValueError as e:
        raise CLIError(str(e)) from None
    print(_describe(case, pf), file=sys.stderr)
    res = _bisect_cct(case, op, buses, args, args.cct_max)
    print(f"{'bus':>6}  CCT (s)")
    for b, c in res["cct"].items():
        print(f"{b:>6}  {_cct_text_of(c, args.cct_max)}")
    if out:
        rows = cct_rows(case, res)
        write_json(
            out,
            {
                "case": case.name,
                "params": _params(args.param),
                "load_factor": args.load_factor,
                "t_end": args.t_end,
                "rtol": args.rtol,
                "atol": args.atol,
                **res,
                "rows": rows,
            },
        )
        plot_case_cct(
            rows,
            res["t_max"],
            png,
            f"{case.name}: critical clearing time of a bolted bus fault at "
            f"{res['t_fault']:g} s, removed without tripping (scan, then bisection "
            f"to {res['tol']:g} s)",
        )
        print(f"wrote {out} and {png}")
    return 0


def _cct_text_of(c, t_max: float) -> str:
    """A printed CCT: the number (4 decimals), or what it is not."""
    if c == 0:
        return "none (unstable at the shortest)"
    return f"> {t_max:g}" if c is None else f"{c:.4f}"


def cct_rows(case, res: dict) -> list[dict]:
    """One row per fault bus of a CCT result: PSS/E bus number, its name, the CCT
    (s; None: stable at the longest duration tried) and its status ("found",
    "exceeds_max", "unstable_at_min")."""
    num = [int(b) for b in np.asarray(case.system.buses.number)]
    names = list(case.system.buses.name) or [""] * len(num)
    name_of = dict(zip(num, (str(n).strip() for n in names), strict=False))
    rows = []
    for b, c in res["cct"].items():
        status = (
            "exceeds_max" if c is None else ("unstable_at_min" if c == 0 else "found")
        )
        rows.append(
            {"bus": int(b), "name": name_of.get(int(b), ""), "cct": c, "status": status}
        )
    return rows


def _variant(text: str) -> tuple[str, list[str]]:
    """`--variant LABEL:MODEL.PARAM=V[,MODEL.PARAM=V...]` as (LABEL, [items])."""
    label, sep, rest = text.partition(":")
    items = [s.strip() for s in rest.split(",") if s.strip()]
    if not sep or not label.strip() or not items:
        raise CLIError(
            f"--variant {text!r} is not allowed: expected LABEL:MODEL.PARAM=VALUE"
            "[,MODEL.PARAM=VALUE...]"
        )
    _params(items)  # one line for a malformed item
    return label.strip(), items


def case_sets(args) -> dict[str, list[str]]:
    """The parameter sets of `compare --case`: the case's own ("case"), the
    --param values ("param", if any), then each --variant; label -> --param
    items."""
    sets = {"case": []}
    if args.param:
        sets["param"] = list(args.param)
    for text in args.variant or []:
        label, items = _variant(text)
        if label in sets:
            raise CLIError(f"--variant label {label!r} is given twice")
        sets[label] = items
    if len(sets) < 2:
        raise CLIError(
            "compare --case needs a set to compare with the case's own: --param "
            "MODEL.PARAM=VALUE or --variant LABEL:MODEL.PARAM=VALUE[,...]"
        )
    return sets


def case_summary(rows: dict) -> dict:
    """A `compare --case` row: stable fraction, settling of the COI angles (s;
    mean and p95 over the stable scenarios that settle), overshoot (rad; mean and
    p95 over the stable scenarios; a lost run has none), the
    largest field voltage (pu), the lowest bus voltage (pu), runs that spent the
    solver's step budget."""
    st = np.asarray(rows["stable"], dtype=bool)
    ts = np.asarray(rows["settling_angle"], dtype=float)[st]
    ts = ts[np.isfinite(ts)]
    ov = np.asarray(rows["overshoot"], dtype=float)[st]  # inf where lost

    def q(a, p):
        return float(np.percentile(a, p)) if a.size else None

    return {
        "n": int(st.size),
        "stable_fraction": float(st.mean()),
        "settling_mean": float(ts.mean()) if ts.size else None,
        "settling_p95": q(ts, 95),
        "overshoot_mean": float(ov.mean()) if ov.size else None,
        "overshoot_p95": q(ov, 95),
        "efd_peak": float(np.max(rows["efd_max"])),
        "v_min": float(np.min(rows["v_min"])),
        "exhausted": int(np.sum(rows["exhausted"])),
    }


CASE_CCT_MAX = 1.0
"""The longest fault duration (s) `compare --case` tries for a CCT."""


def case_cct(case, op, args) -> dict:
    """`compare --case`: the critical clearing time of a bolted fault at each bus of
    --fault-buses (all buses by default), applied at --fault-time and removed
    without tripping, by scan and bisection to --tol in [0, `CASE_CCT_MAX`] s over the
    --t-end horizon (`critical_clearing_times_grid`, as `cct --case`)."""
    buses = _int_list(args.fault_buses) or [
        int(b) for b in np.asarray(case.system.buses.number)
    ]
    return _bisect_cct(case, op, buses, args, CASE_CCT_MAX)


def _bisect_cct(case, op, buses, args, t_max: float) -> dict:
    """`critical_clearing_times_grid` of bolted faults at `buses` applied at
    --fault-time, scanned and bisected to --tol in [0, t_max] s over --t-end, at the command's
    --rtol/--atol; CLIError (one line) on bad input."""
    from .._commandline import announce_compile
    from ..grid.cct import critical_clearing_times_grid

    try:
        what = (
            f"the batched CCT bisection of {_size(case)}: about "
            f"{compile_s(case, 2.0):.0f} s the first time, a few s once cached"
        )
        with announce_compile(what):
            return critical_clearing_times_grid(
                case,
                op,
                buses,
                t_fault=args.fault_time,
                t_max=t_max,
                tol=args.tol,
                t_end=args.t_end,
                rtol=args.rtol,
                atol=args.atol,
            )
    except ValueError as e:
        raise CLIError(str(e)) from None


def _cct_text(args, dist) -> str:
    """What the CCT column of `compare --case` measures, or why it is empty
    ("none: ...")."""
    if dist.kind != "bus":
        return "none (the faults are on lines: --fault-kind bus has a CCT column)"
    if not args.t_end > args.fault_time + CASE_CCT_MAX:
        return (
            f"none (--t-end {args.t_end:g} s must exceed --fault-time "
            f"{args.fault_time:g} s + {CASE_CCT_MAX:g} s)"
        )
    return (
        f"a bolted fault at each fault bus at {args.fault_time:g} s, removed without "
        f"tripping; the longest duration in [0, {CASE_CCT_MAX:g}] s (a scan every "
        f"0.05 s, then bisection to {args.tol:g} s) after which no angle leaves the "
        f"centre of inertia by more than pi within {args.t_end:g} s; the table "
        "shows the shortest over the buses, compare.json every bus's"
    )


def shortest_cct(res: dict) -> dict:
    """The bus with the shortest CCT of a `case_cct` result: {"bus", "cct" (s; None:
    stable at the longest duration tried, 0: unstable at the shortest)}."""
    ccts = res["cct"]

    def key(b):
        c = ccts[b]
        return math.inf if c is None else c

    bus = min(ccts, key=key)
    return {"bus": int(bus), "cct": ccts[bus]}


def _cct_cell(s: dict) -> str:
    c = s.get("cct_shortest")
    if c is None:
        return "-"
    if c["cct"] is None:
        return f"> {CASE_CCT_MAX:g} (all buses)"
    return f"{c['cct']:.3f} (bus {c['bus']})"


def case_table(case_name: str, sets: dict, summaries: dict) -> str:
    """Markdown: one row per parameter set of a case (the shortest CCT over the
    fault buses where the faults are at buses)."""

    def f(x, spec=".3f"):
        return "-" if x is None else format(x, spec)

    lines = [
        f"| set ({case_name}) | parameters | stable % | mean settling (s) | "
        "p95 settling (s) | mean overshoot (rad) | p95 overshoot (rad) | "
        "peak Efd (pu) | lowest bus voltage (pu) | shortest CCT (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, s in summaries.items():
        params = ", ".join(sets[label]) or "the case's own"
        lines.append(
            f"| {label} | {params} | {100 * s['stable_fraction']:.1f} | "
            f"{f(s['settling_mean'], '.2f')} | {f(s['settling_p95'], '.2f')} | "
            f"{f(s['overshoot_mean'])} | {f(s['overshoot_p95'])} | "
            f"{f(s['efd_peak'])} | {f(s['v_min'])} | {_cct_cell(s)} |"
        )
    return "\n".join(lines) + "\n"


def run_compare(args) -> int:
    """`compare --case`: the case's own parameters against --param / --variant
    sets, each on the same fault scenarios (the Monte Carlo options, one seed):
    compare.md and compare.json in --out."""
    import argparse

    from .._files import write_json, write_text
    from .compare import output

    refuse_smib_flags(args)
    sets = case_sets(args)
    out = output(args)
    from .._files import check_out_folder

    check_out_folder(out)  # before any work
    if out.exists() and any(out.iterdir()):
        raise CLIError(
            f"--out {str(out)!r} exists and is not empty: choose a new folder"
        )
    loaded = {}  # every set loaded and checked before any run
    for label, items in sets.items():
        a = argparse.Namespace(**{**vars(args), "param": items})
        case, op, pf = load(a)
        loaded[label] = (a, case, op, pf, *_grid_distribution(case, a))
    a, case, op, pf, dist, n, chunk = loaded["case"]
    print(_describe(case, pf), file=sys.stderr)
    dist_text = (
        f"{n} faults ({dist.kind}), seed {args.seed}: fault at "
        f"{dist.t_fault[0]:g}-{dist.t_fault[1]:g} s, cleared after "
        f"{dist.clear_after[0]:g}-{dist.clear_after[1]:g} s"
    )
    cct_text = _cct_text(args, dist)
    if cct_text.startswith("none"):
        print(f"smibjax: note: CCT column: {cct_text}", file=sys.stderr)
    summaries, ccts, all_rows = {}, {}, {}
    for label, (a, case, op, _pf, dist, n, chunk) in loaded.items():
        rows, _ = grid_rows(case, op, dist, n, chunk, a, desc=label)
        all_rows[label] = rows
        summaries[label] = case_summary(rows)
        if not cct_text.startswith("none"):
            ccts[label] = case_cct(case, op, a)
            summaries[label]["cct_shortest"] = shortest_cct(ccts[label])
    table = case_table(case.name, sets, summaries)
    write_text(
        out / "compare.md",
        f"# Parameter sets compared on {case.name}\n\nScenarios: {dist_text} (the "
        f"same for every set).\n\nCCT: {cct_text}.\n\n" + table,
    )
    write_json(
        out / "compare.json",
        {
            "case": case.name,
            "scenarios": dist_text,
            "sets": sets,
            "summary": summaries,
            "cct": ccts,
        },
    )
    from .plotting import plot_case_compare

    plot_case_compare(
        all_rows,
        ccts,
        out / "compare.png",
        f"Parameter sets on {case.name}: {dist_text}",
    )
    print(f"{case.name}: {dist_text}")
    print(table)
    print(f"wrote {out}/compare.md, compare.json, compare.png")
    return 0
