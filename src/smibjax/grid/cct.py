"""Critical clearing times of bus faults on a multi-machine case.

For each fault bus, the longest duration of a bolted three-phase fault (applied at
`t_fault`, removed without tripping anything) after which the system keeps
synchronism over the horizon (`simulate` criterion: no angle more than pi from the
centre of inertia). The search is the engine's, as for the SMIB (`smibjax._cct`):
a scan of every bus at durations `tol`, then every `scan_step` up to `t_max`, then
bisection to `tol` (s) inside each bus's first stable-to-unstable bracket; a bus that
is stable again at a longer scanned duration is reported `non_monotone` with its
stable islands (a plain bisection would silently pick one of the brackets). Each
stage is one batch over all buses (two batch shapes: two compiles).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from .._cct import _bisect, _scan, _statuses, scan_durations
from .._errors import ParameterError
from .events import BusFault
from .loop import Case, Operating
from .simulate import simulate_batch

__all__ = ["critical_clearing_times_grid"]


def critical_clearing_times_grid(
    case: Case,
    op: Operating,
    buses,
    *,
    t_fault: float = 0.5,
    t_max: float = 1.0,
    tol: float = 0.005,
    t_end: float = 5.0,
    rtol: float = 1e-6,
    atol: float = 1e-8,
    scan_step: float = 0.05,
) -> dict:
    """The CCT (s) of a bolted fault at each of `buses` (PSS/E numbers).

    **Returns:** {"cct": {bus number: CCT in s, None if stable at every duration up to
    t_max, 0 if unstable at the shortest duration tried (`tol`)}, "status": {bus:
    "ok", "exceeds_window" (None), "unstable_at_min" (0), or "non_monotone" (stable
    again at a longer scanned duration: the CCT is the end of the first stable
    stretch)}, "islands": {bus: the [first, last] stable scanned durations after the
    first unstable one}, "first_unstable": {bus: the unstable end of the bracket (s)},
    "tol", "scan_step", "t_fault", "t_max", "exhausted": buses where a run spent its
    step budget (counted as unstable)}."""
    if not (
        tol > 0
        and t_max > tol
        and t_fault >= 0
        and t_end > t_fault + t_max
        and scan_step > 0
    ):
        raise ParameterError(
            f"cct: need tol > 0 ({tol}), t_max > tol ({t_max}), t_fault >= 0 "
            f"({t_fault}), t_end > t_fault + t_max ({t_end}) and scan_step > 0 "
            f"({scan_step})"
        )
    pos = np.array([case.system.bus_index(b) for b in buses], dtype=np.int64)
    n = len(pos)
    kw = dict(t_end=t_end, dt_save=0.05, rtol=rtol, atol=atol)
    spent = np.zeros(n, dtype=bool)

    def stable_at(durations: np.ndarray, lanes: np.ndarray) -> np.ndarray:
        m = len(lanes)
        ev = (
            BusFault(
                bus=jnp.asarray(pos[lanes]),
                t_on=jnp.full(m, t_fault),
                t_off=t_fault + jnp.asarray(durations, dtype=jnp.float64),
            ),
        )
        tr = simulate_batch(case, op, ev, **kw)
        np.logical_or.at(spent, lanes, np.asarray(tr.exhausted))
        return np.asarray(tr.stable)

    scan = scan_durations(t_max, tol, scan_step)
    steps = max(
        1, math.ceil(math.log2(max(np.max(np.diff(scan), initial=tol), tol) / tol))
    )
    all_stable, active, lo, hi, islands = _scan(stable_at, scan, n)
    lo, hi = _bisect(stable_at, active, lo, hi, tol, steps, lambda done, total: None)
    status = _statuses(all_stable, active, islands)
    nums = [int(b) for b in buses]
    cct, first_bad = {}, {}
    for i, b in enumerate(nums):
        st = str(status[i])
        cct[b] = (
            None
            if st == "exceeds_window"
            else 0.0
            if st == "unstable_at_min"
            else float(lo[i])
        )
        first_bad[b] = float(hi[i]) if st in ("ok", "non_monotone") else None
    return {
        "cct": cct,
        "status": {b: str(status[i]) for i, b in enumerate(nums)},
        "islands": {b: islands[i] for i, b in enumerate(nums)},
        "first_unstable": first_bad,
        "tol": tol,
        "scan_step": scan_step,
        "t_fault": t_fault,
        "t_max": t_max,
        "exhausted": [nums[i] for i in np.flatnonzero(spent)],
    }
