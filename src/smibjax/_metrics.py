"""Exact performance metrics of a sampled trajectory (docs/model.md section 4).

All functions are pure jnp, so they jit and vmap with `simulate`. Settling times are
measured from fault inception: the last time after t_fault at which the signal is
outside its band, located by linear interpolation between samples, minus t_fault
(0 if the signal never leaves the band, inf if it is still outside at t_end). A run
that spent the solver's step budget before t_end has no metrics: NaN ("not reached").
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from ._simulate import DEFAULT_DELTA_BAND, Trajectory, is_stable

__all__ = [
    "Metrics",
    "settling_time",
    "overshoot",
    "on_limit",
    "total_variation",
    "physics_summary",
    "PHYSICS",
    "metrics",
    "DEFAULT_BANDS",
]

DEFAULT_BANDS = {"delta": DEFAULT_DELTA_BAND, "Vt": 0.01, "omega": 0.01}


def settling_time(
    t: Float[Array, " n"],
    signal: Float[Array, " n"],
    reference: Float[Array, ""],
    band: float,
    t_from: Float[Array, ""],
) -> Float[Array, ""]:
    """Last time (s, from `t_from`) at which |signal - reference| > band, for t >= t_from.

    The exit from the band is interpolated linearly between the last sample outside
    and the next one; 0 if the signal is never outside, inf if it is outside at t[-1].
    """
    dev = jnp.abs(signal - reference)
    outside = (dev > band) & (t >= t_from)
    n = t.shape[0]
    idx = jnp.arange(n)
    last = jnp.max(jnp.where(outside, idx, -1))
    i = jnp.clip(last, 0, n - 2)
    d0, d1 = dev[i], dev[i + 1]
    frac = jnp.clip((d0 - band) / jnp.where(d0 > d1, d0 - d1, 1.0), 0.0, 1.0)
    t_cross = t[i] + frac * (t[i + 1] - t[i])
    settled = jnp.where(last < 0, 0.0, t_cross - t_from)
    return jnp.where(last == n - 1, jnp.inf, jnp.maximum(settled, 0.0))


def overshoot(traj: Trajectory) -> Float[Array, ""]:
    """First-swing overshoot: max over t >= t_fault of |delta - delta_e| (rad)."""
    dev = jnp.abs(traj.delta - traj.delta_e)
    return jnp.max(jnp.where(traj.t >= traj.t_fault, dev, 0.0))


class Metrics(NamedTuple):
    """Exact metrics of one run (arrays, so they vmap)."""

    stable: Bool[Array, ""]  # no loss of synchronism and delta in band at t_end
    settling_delta: Float[Array, ""]  # s from t_fault (inf: not settled)
    settling_Vt: Float[Array, ""]  # s from t_fault
    settling_omega: Float[Array, ""]  # s from t_fault
    overshoot: Float[Array, ""]  # rad
    effort_uf: Float[Array, ""]  # integral of u_f^2 over [0, t_end] (pu^2 s)
    effort_ur: Float[Array, ""]  # integral of u_r^2 over [0, t_end] (pu^2 s)
    peak_uf: Float[Array, ""]  # max |u_f| reaching the plant, on the samples (pu)
    peak_ur: Float[Array, ""]  # max |u_r| reaching the plant, on the samples (pu)
    peak_B: Float[Array, ""]  # max |B| on the samples (pu)
    # The physics of the run (on the samples up to the end of the run):
    peak_uf_cmd: Float[Array, ""]  # max |u_f| commanded, before the limits (pu)
    peak_ur_cmd: Float[Array, ""]  # max |u_r| commanded, before the limits (pu)
    limit_time_uf: Float[Array, ""]  # fraction of the run with u_f on a limit
    limit_time_ur: Float[Array, ""]  # fraction of the run with u_r on a limit
    tv_uf: Float[Array, ""]  # total variation of the applied u_f (pu): chatter
    tv_ur: Float[Array, ""]  # total variation of the applied u_r (pu)
    Vt_min: Float[Array, ""]  # range of the SVC-bus voltage (pu)
    Vt_max: Float[Array, ""]
    B_min: Float[Array, ""]  # range of the SVC susceptance (pu)
    B_max: Float[Array, ""]
    E_min: Float[Array, ""]  # range of E' (pu)
    E_max: Float[Array, ""]


def on_limit(
    cmd: Float[Array, " n"], applied: Float[Array, " n"]
) -> Float[Array, " n"]:
    """1 where the commanded input is cut by a limit (|cmd - applied| > 1e-9 pu)."""
    return (jnp.abs(cmd - applied) > 1e-9).astype(applied.dtype)


def total_variation(u: Float[Array, " n"]) -> Float[Array, ""]:
    """sum |u[i+1] - u[i]| over the samples (pu): 2 (hi - lo) per full swing between
    two limits, so chatter shows as a large value."""
    return jnp.sum(jnp.abs(jnp.diff(u)))


PHYSICS = (
    "peak_uf_cmd",
    "peak_ur_cmd",
    "limit_time_uf",
    "limit_time_ur",
    "tv_uf",
    "tv_ur",
    "Vt_min",
    "Vt_max",
    "B_min",
    "B_max",
    "E_min",
    "E_max",
)


def physics_summary(rows) -> dict[str, float]:
    """What the inputs and the plant did over a set of runs (a mapping of the
    `PHYSICS` fields to arrays, e.g. `Metrics._asdict()` of a batch or Monte Carlo
    rows): the largest commanded inputs (pu, before limits), the mean fraction of time
    on a limit and mean total variation (pu) of each applied input, the ranges of Vt,
    B and E' (pu) over the whole set."""
    import numpy as np

    r = {k: np.asarray(rows[k], dtype=float) for k in PHYSICS}
    out = {f"{k}_max": float(r[k].max()) for k in ("peak_uf_cmd", "peak_ur_cmd")}
    for k in ("limit_time_uf", "limit_time_ur", "tv_uf", "tv_ur"):
        out[f"{k}_mean"] = float(r[k].mean())
    for q in ("Vt", "B", "E"):
        out[f"{q}_min"] = float(r[f"{q}_min"].min())
        out[f"{q}_max"] = float(r[f"{q}_max"].max())
    return out


def metrics(
    traj: Trajectory,
    delta_band: float = DEFAULT_BANDS["delta"],
    Vt_band: float = DEFAULT_BANDS["Vt"],
    omega_band: float = DEFAULT_BANDS["omega"],
) -> Metrics:
    """Exact metrics of a trajectory; bands in rad, pu and rad/s."""
    t, tf = traj.t, traj.t_fault
    m = Metrics(
        stable=is_stable(
            traj.lost_sync | traj.budget_exhausted,
            traj.delta[-1],
            traj.delta_e,
            delta_band,
        ),
        settling_delta=settling_time(t, traj.delta, traj.delta_e, delta_band, tf),
        settling_Vt=settling_time(t, traj.Vt, traj.Vt_e, Vt_band, tf),
        settling_omega=settling_time(t, traj.omega, 0.0, omega_band, tf),
        overshoot=overshoot(traj),
        effort_uf=traj.effort[0],
        effort_ur=traj.effort[1],
        peak_uf=jnp.max(jnp.abs(traj.u_f)),
        peak_ur=jnp.max(jnp.abs(traj.u_r)),
        peak_B=jnp.max(jnp.abs(traj.B)),
        peak_uf_cmd=jnp.max(jnp.abs(traj.u_f_cmd)),
        peak_ur_cmd=jnp.max(jnp.abs(traj.u_r_cmd)),
        limit_time_uf=jnp.mean(on_limit(traj.u_f_cmd, traj.u_f)),
        limit_time_ur=jnp.mean(on_limit(traj.u_r_cmd, traj.u_r)),
        tv_uf=total_variation(traj.u_f),
        tv_ur=total_variation(traj.u_r),
        Vt_min=jnp.min(traj.Vt),
        Vt_max=jnp.max(traj.Vt),
        B_min=jnp.min(traj.B),
        B_max=jnp.max(traj.B),
        E_min=jnp.min(traj.E),
        E_max=jnp.max(traj.E),
    )
    return _not_reached(traj, _lost(traj, m))


def _lost(traj: Trajectory, m: Metrics) -> Metrics:
    """A run that lost synchronism never settled: its settling times are inf ("not
    settled"), whatever the samples held after the stop show (the last sample
    reached may lie inside a band, and before the first sample every one is the
    starting point). Its overshoot is the deviation measured up to the stop, and inf
    where no sample after the fault was reached (the swing was never measured)."""
    lost = traj.lost_sync
    seen = jnp.any((traj.t >= traj.t_fault) & (traj.t < traj.t_stop))
    inf = jnp.inf
    return m._replace(
        settling_delta=jnp.where(lost, inf, m.settling_delta),
        settling_Vt=jnp.where(lost, inf, m.settling_Vt),
        settling_omega=jnp.where(lost, inf, m.settling_omega),
        overshoot=jnp.where(lost & ~seen, inf, m.overshoot),
    )


def _not_reached(traj: Trajectory, m: Metrics) -> Metrics:
    """A run whose solver spent its step budget before t_end never got there: every
    metric but `stable` (False) is "not reached" (NaN), never a number measured on the
    part it did run (`--max-steps 1` would otherwise settle in 0 s with no
    overshoot)."""
    stop = traj.budget_exhausted
    return m._replace(
        **{
            k: jnp.where(stop, jnp.nan, v)
            for k, v in m._asdict().items()
            if k != "stable"
        }
    )
