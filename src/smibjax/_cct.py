"""Critical clearing time (docs/model.md section 4): the largest clearing duration
t_clear - t_fault (s) such that the run is stable for it and for every shorter
duration on the tolerance grid.

Stability of a run is judged by one of two criteria (`CRITERIA`): "settled" (docs/model.md
section 4: no loss of synchronism and delta back in its band at t_end) or
"synchronism" (the industry definition: no loss of synchronism up to t_end, and the
solver's step budget not spent).

Stability need not be monotone in the clearing duration: a controller under input
limits can recover from a 0.15 s and a 0.40 s fault but not settle by t_end after
0.2-0.35 s. Bisection on such a verdict finds *a* boundary, not the critical one, so
the computation has two stages, each batched over every lane (one lane per (gain set,
fault location) pair, split over the devices):

1. **Scan.** Every lane at K + 1 durations at once (one batched call of
   lanes x (K + 1) runs): the shortest duration `tol`, then k * window / K for
   k = 1..K, K = ceil(window / scan_step). The first unstable scan duration ends the
   stable stretch from zero.
2. **Bisection** inside that first unstable bracket (stable lower end, unstable upper
   end) down to `tol`: about log2(window / (K tol)) batched calls of one run per lane.

The window is (0, t_reclose - t_fault]: a clearing duration cannot run past
reclosure. Status per lane:

- "ok": the CCT is a number, and no scanned duration beyond it is stable;
- "non_monotone": the CCT is a number, but later scanned durations are stable again:
  the stable "islands" are listed as [lo, hi] intervals of scan durations (s);
- "exceeds_window": every scanned duration is stable: the CCT lies beyond the window
  (not a number);
- "unstable_at_min": unstable already at the shortest duration `tol` (not a number;
  stable islands further on, if any, are listed too).

Islands and unstable stretches narrower than the scan step can be missed; inside the
bracket the bisection returns a duration that is stable with one at most `tol` longer
that is not.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from ._batch import Engine, Scenarios
from ._options import SolverOptions, solver_or_legacy
from ._parameters import (
    Fault,
    InitialEstimates,
    OperatingPoint,
    ParameterError,
    Plant,
)
from ._validate import require_memory, require_positive, require_samples
from .controllers import as_controller

__all__ = [
    "critical_clearing_times",
    "CCTResult",
    "SetCCT",
    "scan_durations",
    "lane_kind",
    "CRITERIA",
    "STATUSES",
]

# Stability criteria of a CCT run (docs/model.md section 2, "Baselines", and section 4).
CRITERIA = ("settled", "synchronism")
STATUSES = ("ok", "non_monotone", "exceeds_window", "unstable_at_min")

MIN_TOL = 1e-9  # s: a finer bisection is below the solver's accuracy


def lane_kind(controller) -> tuple:
    """What gain sets of one call must share: the controller's type and structure
    (`AbstractController.structure`)."""
    return (type(controller).__name__, controller.structure())


def _lanes(gain_sets: dict, names: list, adaptation: str):
    """(template controller, tunable values per set) of the gain sets, which must
    share one `lane_kind` (they run as lanes of one program). The paper's law runs
    with `adaptation`."""
    ctrls = []
    for n in names:
        ctrls.append(as_controller(gain_sets[n]).with_adaptation(adaptation))
    if len({lane_kind(c) for c in ctrls}) > 1:
        raise ParameterError(
            "the gain sets of one CCT call must share one controller and its options "
            f"({', '.join(names)} do not): run them in separate calls"
        )
    return ctrls[0], [c.tunable() for c in ctrls]


class BudgetWarning(RuntimeWarning):
    """Runs of a CCT computation spent the solver's step budget (counted as not
    stable): its "none (unstable)" may say more about --max-steps than the plant."""


def _scan_count(window: float, tol: float, scan_step: float) -> int:
    """The number of scan durations `scan_durations` gives (without building them)."""
    return max(1, min(math.ceil(window / scan_step - 1e-9), int(window / tol + 1e-9)))


def scan_durations(window: float, tol: float, scan_step: float) -> np.ndarray:
    """The scan's clearing durations (s): `tol`, then k * window / K for k = 1..K with
    K = ceil(window / scan_step), capped so that the spacing is at least `tol`."""
    k = _scan_count(window, tol, scan_step)
    grid = window * np.arange(1, k + 1) / k
    return np.concatenate([[tol], grid[grid > tol]])


def _islands(stable: np.ndarray, durations: np.ndarray) -> list[list[float]]:
    """Maximal runs of stable scan durations, as [first, last] duration pairs (s)."""
    out, start = [], None
    for i, ok in enumerate(stable):
        if ok and start is None:
            start = i
        if start is not None and (not ok or i == len(stable) - 1):
            end = i if ok else i - 1
            out.append([float(durations[start]), float(durations[end])])
            start = None
    return out


def _check_window(fault_time, reclose_time, t_end, tol, scan_step) -> float:
    """The clearing window t_reclose - t_fault (s), after checking the times."""
    window = reclose_time - fault_time
    if not (math.isfinite(fault_time) and fault_time >= 0):
        raise ParameterError(
            f"fault_time = {fault_time:g} s is not allowed: must be >= 0"
        )
    if not math.isfinite(reclose_time):
        raise ParameterError(
            f"reclose_time = {reclose_time:g} s is not allowed: must be finite"
        )
    if not window > 0:
        raise ParameterError(
            f"reclose_time = {reclose_time:g} s is not allowed: must be after "
            f"fault_time = {fault_time:g} s"
        )
    if not (math.isfinite(t_end) and t_end > reclose_time):
        raise ParameterError(
            f"t_end = {t_end:g} s is not allowed: must be after reclose_time = "
            f"{reclose_time:g} s (the fault time plus the clearing window)"
        )
    if not MIN_TOL <= tol < window:
        raise ParameterError(
            f"tol = {tol:g} is not allowed: must be within [{MIN_TOL:g}, {window:g}) s"
        )
    require_positive("scan_step", scan_step)
    return window


def check_options(
    fault_locations,
    fault_time: float = 0.5,
    reclose_time: float = 2.0,
    fault_reactance: float = 0.0,
    tol: float = 1e-3,
    scan_step: float = 0.05,
    t_end: float = 10.0,
    criterion: str = "settled",
) -> tuple[list[float], float]:
    """Check the options of `critical_clearing_times` before any work (a
    `ParameterError` naming the first bad value). Returns (fault locations as floats,
    the clearing window t_reclose - t_fault (s))."""
    if criterion not in CRITERIA:
        raise ParameterError(
            f"criterion = {criterion!r} is not allowed: must be one of "
            f"{', '.join(CRITERIA)}"
        )
    locs = [float(x) for x in np.atleast_1d(fault_locations)]
    if not locs:
        raise ParameterError("fault_location: give at least one location")
    for lam in locs:
        if not 0 < lam < 1:
            raise ParameterError(
                f"fault_location = {lam:g} is not allowed: must be within (0, 1)"
            )
    window = _check_window(fault_time, reclose_time, t_end, tol, scan_step)
    require_samples(t_end, 0.01)  # simulate's default sampling, as the lanes run
    for lam in locs:  # every lane's extremes, before any work
        for duration in (tol, window):
            Fault(fault_time, fault_time + duration, reclose_time, lam, fault_reactance)
    return locs, window


@dataclasses.dataclass(frozen=True)
class SetCCT:
    """The CCT of one gain set at each fault location: `cct[j]` (s), the largest
    clearing duration with every shorter one stable, where `status[j]` is "ok" or
    "non_monotone", else None; `first_unstable[j]` (s) the unstable duration at most
    `tol` beyond it that ended the bisection; `islands[j]` the later stable [lo, hi]
    stretches of scan durations (s)."""

    cct: list[float | None]
    status: list[str]
    islands: list[list[list[float]]]
    first_unstable: list[float | None]


@dataclasses.dataclass(frozen=True)
class CCTResult:
    """What `critical_clearing_times` computed: the options it ran with (times in
    s), the scan durations (s) and a `SetCCT` per gain set (in the order given)."""

    fault_location: list[float]
    fault_time: float
    reclose_time: float
    fault_reactance: float
    criterion: str
    t_end: float
    window: float  # t_reclose - t_fault (s)
    tol: float
    scan: list[float]
    sets: dict[str, SetCCT]

    def to_dict(self) -> dict:
        """The JSON layout the command line writes: the fields, `sets` as name ->
        {"cct", "status", "islands", "first_unstable"}, and top-level "cct",
        "status" and "islands": those of the one gain set, or with several, tables
        name -> list."""
        out = {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if f.name != "sets"
        }
        out["fault_location"] = list(self.fault_location)
        out["scan"] = list(self.scan)
        sets = {n: dataclasses.asdict(v) for n, v in self.sets.items()}
        out["sets"] = sets
        names = list(sets)
        for key in ("cct", "status", "islands"):
            out[key] = (
                sets[names[0]][key]
                if len(names) == 1
                else {n: sets[n][key] for n in names}
            )
        return out


def _stacked_lanes(gain_sets: dict, locs: list, adaptation: str):
    """(names, template controller, stacked tunable values, fault location) of the
    lanes: one lane per (gain set, fault location) pair, sets outermost."""
    if not gain_sets:
        raise ParameterError("give at least one gain set")
    names = list(gain_sets)
    template, values = _lanes(gain_sets, names, adaptation)
    pairs = [(i, lam) for i in range(len(names)) for lam in locs]
    gains = jax.tree_util.tree_map(
        lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]),
        *[values[i] for i, _ in pairs],
    )
    return names, template, gains, np.asarray([p[1] for p in pairs])


def _verdicts(engine, template, gains, lam, fault_time, reclose_time, Xf, criterion):
    """stable_at(durations, lanes): the stable flags of lanes[i] cleared after
    durations[i] (s), in one batched call of the engine."""

    def stable_at(durations: np.ndarray, lanes: np.ndarray) -> np.ndarray:
        n = len(durations)
        tf = jnp.full(n, fault_time)
        fault = Fault(
            t_fault=tf,
            t_clear=tf + jnp.asarray(durations),
            t_reclose=jnp.full(n, reclose_time),
            lam=jnp.asarray(lam[lanes]),
            Xf=jnp.full(n, Xf),
        )
        g = jax.tree_util.tree_map(lambda a: a[jnp.asarray(lanes)], gains)
        out = engine.run(template, Scenarios(fault), lanes=g)
        stable_at.exhausted[0] += int(np.sum(np.asarray(out.budget_exhausted)))
        stable_at.exhausted[1] += n
        flags = out.synchronous if criterion == "synchronism" else out.metrics.stable
        return np.asarray(flags, dtype=bool)

    stable_at.exhausted = [0, 0]  # runs that spent the step budget, runs
    return stable_at


def _scan(stable_at, scan: np.ndarray, n_lanes: int):
    """Stage 1: every lane at every scan duration. Returns (all stable, active (a
    stable-to-unstable bracket to bisect), bracket lo (stable), hi (unstable), the
    stable islands after the first unstable duration) per lane."""
    n_scan = len(scan)
    lanes = np.repeat(np.arange(n_lanes), n_scan)
    grid = stable_at(np.tile(scan, n_lanes), lanes).reshape(n_lanes, n_scan)
    all_stable = grid.all(axis=1)
    first_bad = np.where(all_stable, n_scan, np.argmin(grid, axis=1))
    active = (first_bad > 0) & ~all_stable
    lo = np.where(active, scan[np.maximum(first_bad - 1, 0)], np.nan)  # stable
    hi = np.where(active, scan[np.minimum(first_bad, n_scan - 1)], np.nan)  # not
    islands = [
        _islands(grid[i, first_bad[i] :], scan[first_bad[i] :]) for i in range(n_lanes)
    ]
    return all_stable, active, lo, hi, islands


def _bisect(stable_at, active, lo, hi, tol, steps, report):
    """Stage 2: bisection of every active bracket [lo, hi] down to `tol`, all lanes
    in each batched call (one batch shape: one compile). Returns (lo, hi)."""
    everyone = np.arange(len(lo))
    for step in range(steps):
        todo = active & (hi - lo > tol * (1 + 1e-9))
        if not todo.any():
            break
        mid = np.where(todo, 0.5 * (lo + hi), tol)
        ok = stable_at(mid, everyone)
        lo = np.where(todo & ok, mid, lo)
        hi = np.where(todo & ~ok, mid, hi)
        report(step + 2, steps + 1)
    return lo, hi


def _statuses(all_stable, active, islands) -> np.ndarray:
    """The status of each lane (module docstring)."""
    return np.where(
        all_stable,
        "exceeds_window",
        np.where(
            ~active,
            "unstable_at_min",
            np.where([bool(x) for x in islands], "non_monotone", "ok"),
        ),
    )


def _set_results(names, n_locs, lo, hi, status, islands) -> dict[str, SetCCT]:
    """name -> `SetCCT` from the per-lane brackets, statuses and islands."""

    def numbers(v, st):
        ok = ("ok", "non_monotone")
        return [float(x) if s in ok else None for x, s in zip(v, st, strict=True)]

    out = {}
    for i, name in enumerate(names):
        sl = slice(i * n_locs, (i + 1) * n_locs)
        out[name] = SetCCT(
            cct=numbers(lo[sl], status[sl]),
            status=[str(s) for s in status[sl]],
            islands=islands[sl],
            first_unstable=numbers(hi[sl], status[sl]),
        )
    return out


def critical_clearing_times(
    gain_sets: dict,
    plant: Plant | None = None,
    *,
    op: OperatingPoint | None = None,
    init: InitialEstimates | None = None,
    fault_locations=(0.1, 0.3, 0.5, 0.7, 0.9),
    fault_time: float = 0.5,
    reclose_time: float = 2.0,
    fault_reactance: float = 0.0,
    tol: float = 1e-3,
    scan_step: float = 0.05,
    criterion: str = "settled",
    adaptation: str = "oracle",
    t_end: float = 10.0,
    solver: SolverOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    max_steps: int | None = None,
) -> CCTResult:
    """CCT (s) of every gain set at every fault location (module docstring: scan,
    then bisection in the first unstable bracket). `progress(done, total)`, if given,
    is called before the scan and after each batched call.

    `gain_sets`: name -> the paper's `Gains` (run with `adaptation`) or a controller
    (`smibjax.controllers`); all of one kind, since the lanes are stacked.

    `tol` (s): bisection tolerance and shortest duration tried; `scan_step` (s): the
    scan's spacing (at most; the window is split evenly); `criterion`: "settled" or
    "synchronism"; `t_end` (s): horizon of every run, after `reclose_time`;
    `solver`: a `SolverOptions` (default: adaptive Tsit5, rtol 1e-6, atol 1e-8,
    50,000 steps), passed whole to the batch engine. The keywords `rtol`, `atol`,
    `max_steps` of 0.1 still work, with a `DeprecationWarning`, for one release.

    **Returns:** a `CCTResult` (`.to_dict()`: the JSON layout).
    """
    plant = Plant() if plant is None else plant
    op = OperatingPoint() if op is None else op
    init = InitialEstimates() if init is None else init
    locs, window = check_options(
        fault_locations,
        fault_time,
        reclose_time,
        fault_reactance,
        tol,
        scan_step,
        t_end,
        criterion,
    )
    names, template, gains, lam = _stacked_lanes(gain_sets, locs, adaptation)
    legacy = {"rtol": rtol, "atol": atol, "max_steps": max_steps}
    solver = solver_or_legacy("critical_clearing_times", solver, legacy)
    engine = Engine(plant, op, init, t_end=t_end, solver=solver)
    stable_at = _verdicts(
        engine,
        template,
        gains,
        lam,
        fault_time,
        reclose_time,
        fault_reactance,
        criterion,
    )
    require_memory(
        f"tol = {tol:g} with scan_step = {scan_step:g}",
        len(lam) * _scan_count(window, tol, scan_step),
        round(t_end / engine.dt_save) + 1,
        "raise tol or scan_step, or give fewer fault locations",
    )
    scan = scan_durations(window, tol, scan_step)
    report_spent = stable_at.exhausted
    steps = max(1, math.ceil(math.log2(max(np.max(np.diff(scan)), tol) / tol)))
    report = progress or (lambda done, total: None)
    report(0, steps + 1)
    all_stable, active, lo, hi, islands = _scan(stable_at, scan, len(lam))
    report(1, steps + 1)
    lo, hi = _bisect(stable_at, active, lo, hi, tol, steps, report)
    report(steps + 1, steps + 1)
    status = _statuses(all_stable, active, islands)
    if report_spent[0]:
        warnings.warn(
            f"{report_spent[0]} of {report_spent[1]} CCT run(s) spent the solver's "
            f"step budget (max_steps = {max_steps}) before t_end and count as not "
            "stable: raise --max-steps",
            BudgetWarning,
            stacklevel=2,
        )
    return CCTResult(
        fault_location=locs,
        fault_time=fault_time,
        reclose_time=reclose_time,
        fault_reactance=fault_reactance,
        criterion=criterion,
        t_end=t_end,
        window=window,
        tol=tol,
        scan=[float(d) for d in scan],
        sets=_set_results(names, len(locs), lo, hi, status, islands),
    )
