"""Critical clearing times of bus faults on a multi-machine case.

For each fault bus, the longest duration of a bolted three-phase fault (applied at
`t_fault`, removed without tripping anything) after which the system keeps
synchronism over the horizon (`simulate` criterion: no angle more than pi from the
centre of inertia), found by bisection to `tol` (s) in [0, t_max]. Every bisection
step is one batch over all buses (one compile for the whole search).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

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
) -> dict:
    """{"cct": {bus number: CCT in s, None if stable at t_max, 0 if unstable at the
    shortest duration tried}, "tol", "t_fault", "t_max", "exhausted": buses where a
    run spent its step budget (counted as unstable)}."""
    if not (tol > 0 and t_max > tol and t_fault >= 0 and t_end > t_fault + t_max):
        raise ParameterError(
            f"cct: need tol > 0 ({tol}), t_max > tol ({t_max}), t_fault >= 0 "
            f"({t_fault}) and t_end > t_fault + t_max ({t_end})"
        )
    pos = np.array([case.system.bus_index(b) for b in buses], dtype=np.int64)
    n = len(pos)
    kw = dict(t_end=t_end, dt_save=0.05, rtol=rtol, atol=atol)

    def stable(d):
        ev = (
            BusFault(
                bus=jnp.asarray(pos), t_on=jnp.full(n, t_fault), t_off=t_fault + d
            ),
        )
        tr = simulate_batch(case, op, ev, **kw)
        return np.asarray(tr.stable), np.asarray(tr.exhausted)

    lo = np.zeros(n)
    hi = np.full(n, t_max)
    s_hi, ex_hi = stable(hi)
    s_lo, ex_lo = stable(np.full(n, tol))
    exhausted = ex_hi | ex_lo
    for _ in range(int(math.ceil(math.log2(t_max / tol)))):
        mid = 0.5 * (lo + hi)
        s, ex = stable(mid)
        exhausted |= ex
        lo = np.where(s, mid, lo)
        hi = np.where(s, hi, mid)
    nums = [int(b) for b in buses]
    cct = {}
    for i, b in enumerate(nums):
        if s_hi[i]:
            cct[b] = None
        elif not s_lo[i]:
            cct[b] = 0.0
        else:
            cct[b] = float(lo[i])
    return {
        "cct": cct,
        "tol": tol,
        "t_fault": t_fault,
        "t_max": t_max,
        "exhausted": [nums[i] for i in np.flatnonzero(exhausted)],
    }
