"""Critical clearing time (MODEL.md section 4): the largest clearing duration
t_clear - t_fault for which the run is stable, by bisection over vmapped lanes.

Every (gain set, fault location) pair is one lane; each bisection step simulates all
lanes at their current midpoints in one batched call (split over the devices), so the
cost is about log2(window / tol) batched runs. The window is
(0, t_reclose - t_fault]: a clearing duration cannot run past reclosure. Where the
run is still stable at the end of the window the CCT is not a number (it lies beyond
the window: reported as status "exceeds_window"); where it is unstable even for the
shortest duration tried (`tol`), status "unstable_at_min".

Bisection assumes one stability boundary along the duration axis; it returns a
duration that is stable with a duration at most `tol` longer that is not.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._validate import require_count, require_positive, require_samples
from .controller import static_alpha
from .metrics import metrics
from .parallel import device_map
from .parameters import (
    Fault,
    Gains,
    InitialEstimates,
    OperatingPoint,
    ParameterError,
    Plant,
)
from .simulate import simulate

__all__ = ["critical_clearing_times"]

MIN_TOL = 1e-9  # s: a finer bisection is below the solver's accuracy


def _stable_batch_fn(
    plant,
    op,
    init,
    adaptation: str,
    t_end: float,
    alpha_one: bool = False,
    max_steps: int = 50_000,
    rtol: float = 1e-6,
    atol: float = 1e-8,
):
    """Jitted (gains, fault) lanes -> stable flags. The plant, operating point and
    initial estimates are compile-time constants (XLA folds what derives from them, as
    in the Monte Carlo engine); one compilation serves every bisection step.
    `alpha_one`: every lane has alpha = 1 (compiled without signed powers)."""

    @eqx.filter_jit
    def run(lanes):
        gains, fault = lanes

        def one(g, f):
            g = static_alpha(g, alpha_one)
            tr = simulate(
                g,
                f,
                plant,
                op=op,
                init=init,
                adaptation=adaptation,
                t_end=t_end,
                rtol=rtol,
                atol=atol,
                max_steps=max_steps,
            )
            return metrics(tr).stable

        return jax.vmap(one)(gains, fault)

    return run


def critical_clearing_times(
    gain_sets: dict[str, Gains],
    plant: Plant | None = None,
    *,
    op: OperatingPoint | None = None,
    init: InitialEstimates | None = None,
    fault_locations=(0.1, 0.3, 0.5, 0.7, 0.9),
    fault_time: float = 0.5,
    reclose_time: float = 2.0,
    fault_reactance: float = 0.0,
    tol: float = 1e-3,
    adaptation: str = "oracle",
    t_end: float = 10.0,
    max_steps: int = 50_000,
    rtol: float = 1e-6,
    atol: float = 1e-8,
    progress: bool = False,
) -> dict:
    """CCT (s) of every gain set at every fault location.

    **Returns:** `{"fault_location": [...], "cct": [...], "status": [...], "window":
    t_reclose - t_fault, "tol": tol, "sets": {name: {"cct": [...], "status": [...]}}}`;
    `cct[j]` is the largest stable duration found (s) where status is "ok", and None
    otherwise ("exceeds_window", "unstable_at_min"). With several gain sets the
    top-level "cct" and "status" are tables name -> list.
    """
    plant = Plant() if plant is None else plant
    op = OperatingPoint() if op is None else op
    init = InitialEstimates() if init is None else init
    locs = [float(x) for x in np.atleast_1d(fault_locations)]
    if not locs:
        raise ParameterError("fault_location: give at least one location")
    for lam in locs:
        if not 0 < lam < 1:
            raise ParameterError(
                f"fault location {lam:g} is not allowed: must be within (0, 1)"
            )
    window = reclose_time - fault_time
    if not (math.isfinite(fault_time) and fault_time >= 0):
        raise ParameterError(
            f"fault time = {fault_time:g} is not allowed: must be >= 0"
        )
    if not window > 0:
        raise ParameterError(
            f"reclose time = {reclose_time:g} s is not allowed: must be after the "
            f"fault time {fault_time:g} s"
        )
    if reclose_time >= t_end:
        raise ParameterError(
            f"reclose time = {reclose_time:g} s is not allowed: must be before "
            f"t_end = {t_end:g} s"
        )
    if not MIN_TOL <= tol < window:
        raise ParameterError(
            f"tol = {tol:g} is not allowed: must be within [{MIN_TOL:g}, {window:g}) s"
        )
    require_positive("t_end", t_end)
    require_samples(t_end, 0.01)  # simulate's default sampling, as the lanes run
    for duration in (tol, window):  # the lanes' extremes, before any work
        Fault(fault_time, fault_time + duration, reclose_time, locs[0], fault_reactance)
    if not gain_sets:
        raise ParameterError("give at least one gain set")
    names = list(gain_sets)
    pairs = [(n, lam) for n in names for lam in locs]
    gains = jax.tree_util.tree_map(
        lambda *xs: jnp.stack(xs), *[gain_sets[n] for n, _ in pairs]
    )
    lam = jnp.asarray([p[1] for p in pairs])
    n_lanes = len(pairs)

    alpha_one = all(float(gain_sets[n].alpha) == 1.0 for n in names)
    require_count("max_steps", max_steps)
    require_positive("rtol", rtol)
    require_positive("atol", atol)
    batch_fn = _stable_batch_fn(
        plant, op, init, adaptation, t_end, alpha_one, max_steps, rtol, atol
    )

    def stable_at(durations: np.ndarray) -> np.ndarray:
        tf = jnp.full(n_lanes, fault_time)
        fault = Fault(
            t_fault=tf,
            t_clear=tf + jnp.asarray(durations),
            t_reclose=jnp.full(n_lanes, reclose_time),
            lam=lam,
            Xf=jnp.full(n_lanes, fault_reactance),
        )
        out = device_map(lambda _, b: batch_fn(b), None, (gains, fault))
        return np.asarray(out, dtype=bool)

    steps = max(1, math.ceil(math.log2((window - tol) / tol)))
    from tqdm.auto import tqdm

    bar = tqdm(total=steps + 2, desc="cct bisection", disable=not progress)
    at_max = stable_at(np.full(n_lanes, window))
    bar.update()
    at_min = stable_at(np.full(n_lanes, tol))
    bar.update()
    lo = np.full(n_lanes, tol)  # stable
    hi = np.full(n_lanes, window)  # unstable
    active = at_min & ~at_max
    for _ in range(steps):
        if not active.any() or np.all(hi[active] - lo[active] <= tol):
            break
        mid = np.where(active, 0.5 * (lo + hi), tol)
        ok = stable_at(mid)
        lo = np.where(active & ok, mid, lo)
        hi = np.where(active & ~ok, mid, hi)
        bar.update()
    bar.close()
    status = np.where(
        at_max, "exceeds_window", np.where(at_min, "ok", "unstable_at_min")
    )
    result = {
        "fault_location": locs,
        "fault_time": fault_time,
        "reclose_time": reclose_time,
        "fault_reactance": fault_reactance,
        "window": window,
        "tol": tol,
        "sets": {},
    }
    for i, name in enumerate(names):
        sl = slice(i * len(locs), (i + 1) * len(locs))
        result["sets"][name] = {
            "cct": [
                float(v) if s == "ok" else None
                for v, s in zip(lo[sl], status[sl], strict=True)
            ],
            "status": [str(s) for s in status[sl]],
        }
    sets = result["sets"]
    one = len(names) == 1
    result["cct"] = sets[names[0]]["cct"] if one else {n: sets[n]["cct"] for n in names}
    result["status"] = (
        sets[names[0]]["status"] if one else {n: sets[n]["status"] for n in names}
    )
    return result
