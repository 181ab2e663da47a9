"""Metrics of a multi-machine run (`GridTrajectory`).

Stability: no machine's angle departs from the centre of inertia (COI; the
synchronous frame where the case has an infinite bus) by more than pi within the
horizon (ANDES's criterion is a 180 degree spread between machines, which is at most
twice ours). A tripped machine leaves the COI and every metric from its trip.
Settling and overshoot are of the COI-referred angles and of the speeds, from the
first event, about a *reference*: the post-disturbance equilibrium where it is
known (the operating point when the network at t_end is the one before the events:
faults cleared, branches reclosed), else the last sample:
- `settling_angle`: the time from the first event after which every COI angle stays
  within `band_angle` (rad) of its reference, provided it then stays there for at
  least the last `window` s of the run; inf otherwise (still outside the band, or
  inside it for less than `window` s before t_end: a swing the horizon cut short
  is not settled), and inf for a run that lost synchronism;
- `settling_speed`: the same for the speed deviations within `band_speed` (pu) of 0;
- `overshoot`: the largest |COI angle - its reference| after the first event (rad);
  inf for a run that lost synchronism;
- `max_spread`: the largest |angle - COI| over the run (rad), up to the loss;
- `v_min`, `v_max`: bus voltage magnitude range after the first event (pu);
- `efd_max`: the largest field voltage of the machines in service (pu).
None of them is NaN.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .events import switch_times
from .loop import Case, Operating
from .trajectory import GridTrajectory, coi_angles

__all__ = ["GridMetrics", "grid_metrics", "batch_metrics", "settling_time", "WINDOW"]


class GridMetrics(eqx.Module):
    stable: Bool[Array, "*b"]
    t_unstable: Float[Array, "*b"]
    settling_angle: Float[Array, "*b"]
    settling_speed: Float[Array, "*b"]
    overshoot: Float[Array, "*b"]
    max_spread: Float[Array, "*b"]
    v_min: Float[Array, "*b"]
    v_max: Float[Array, "*b"]
    efd_max: Float[Array, "*b"]
    exhausted: Bool[Array, "*b"]
    n_steps: Array | None = None  # accepted steps of the run (not a CSV column)

    FIELDS = (
        "stable",
        "t_unstable",
        "settling_angle",
        "settling_speed",
        "overshoot",
        "max_spread",
        "v_min",
        "v_max",
        "efd_max",
        "exhausted",
    )


WINDOW = 1.0  # s: how long a quantity must stay in its band before t_end


def settling_time(ts, err, band, t0, window):
    """Time (s) from t0 after which err (T, n) stays at or below band in every
    column, if it then stays there for at least the last `window` s; else inf."""
    out = jnp.any(err > band, axis=-1)
    last = jnp.maximum(jnp.max(jnp.where(out, ts, -jnp.inf)), t0)
    return jnp.where(ts[-1] - last >= window, last - t0, jnp.inf)


def grid_metrics(
    case: Case,
    tr: GridTrajectory,
    t_first: Float[Array, ""],
    band_angle: float = 0.01,
    band_speed: float = 1e-4,
    window: float = WINDOW,
) -> GridMetrics:
    """Metrics (module docstring) of one run whose first event is at t_first (s);
    bands in rad and pu, `window` in s; vmap for a batch."""
    ok = tr.stable
    on = tr.gen_on > 0  # (T, n_gen): machines in service at each sample
    valid = jnp.all(jnp.isfinite(tr.delta) | ~on, axis=-1)  # samples before a loss
    delta = jnp.where(on, jnp.nan_to_num(tr.delta), 0.0)
    rel = coi_angles(case, delta, tr.gen_on)
    ref_eq = coi_angles(case, jnp.nan_to_num(tr.delta_ref), tr.gen_on[-1])
    ref = jnp.where(jnp.all(jnp.isfinite(tr.delta_ref)), ref_eq, rel[-1])
    after = (tr.ts >= t_first) & valid
    use = on & after[:, None]
    d_err = jnp.where(use, jnp.abs(rel - ref), 0.0)
    w_err = jnp.where(use, jnp.abs(jnp.nan_to_num(tr.omega)), 0.0)
    s_a = jnp.where(
        ok, settling_time(tr.ts, d_err, band_angle, t_first, window), jnp.inf
    )
    s_w = jnp.where(
        ok, settling_time(tr.ts, w_err, band_speed, t_first, window), jnp.inf
    )
    spread = jnp.max(jnp.where(on & valid[:, None], jnp.abs(rel), 0.0))
    vb = jnp.where(after[:, None], jnp.nan_to_num(tr.v_bus, nan=jnp.inf), jnp.inf)
    efd = jnp.where(on & valid[:, None], tr.efd, -jnp.inf)
    return GridMetrics(
        stable=ok,
        t_unstable=tr.t_unstable,
        settling_angle=s_a,
        settling_speed=s_w,
        overshoot=jnp.where(ok, jnp.max(d_err), jnp.inf),
        max_spread=spread,
        v_min=jnp.min(vb),  # inf, -inf: no sample after the first event
        v_max=jnp.max(jnp.where(jnp.isfinite(vb), vb, -jnp.inf)),
        efd_max=jnp.max(efd),
        exhausted=tr.exhausted,
        n_steps=tr.n_steps,
    )


def batch_metrics(
    case: Case,
    op: Operating,
    *,
    devices=None,
    band_angle: float = 0.01,
    band_speed: float = 1e-4,
    **options,
):
    """A function `events -> GridMetrics` (leading batch axis) that simulates a batch of
    scenarios of one event structure and returns only their metrics, in one compiled
    program: the trajectories stay inside it (XLA drops the samples the metrics do not
    read, and no trajectory is copied out). `options` as `simulate_case`; a
    scenario's first event time is its first switch time. Compiled once per batch
    size (a chunked Monte Carlo pads its last chunk to the chunk size).

    `devices`: the host devices to split the batch over with `jax.shard_map` (each
    running its own adaptive loop); default the first device only. Splitting over two
    host devices deadlocks in this JAX/XLA (0.10.2) on the CPU backend at larger
    batches: kundur-gencls, 10 s, through `shard_map` returned at 8 and 32 scenarios
    and hung at 64 (the process idle, every thread asleep, CPU time flat); through
    `device_map` (one executable per device, run from two threads) it returned at 64
    and the first call at 256, then hung on the second call at 256; `NamedSharding`
    on the batch axis hung at 256 (issue 28; its partitioned while loops also
    all-reduce the loop predicate across devices at every iteration). See
    docs/performance.md.
    """
    from .._parallel import shard_batch
    from .simulate import check_events, simulate_case

    rep, static = eqx.partition((case, op), eqx.is_array)

    def grid_batch_metrics(rep, events):  # its name keys the compilation cache
        case_, op_ = eqx.combine(rep, static)

        def one(ev):
            tr = simulate_case(case_, op_, ev, **options)
            t_first = switch_times(ev)[0]
            return grid_metrics(case_, tr, t_first, band_angle, band_speed)

        return jax.vmap(one)(events)

    if devices is None:
        devices = jax.devices()[:1]
    call = shard_batch(grid_batch_metrics, devices)

    def run(events) -> GridMetrics:
        check_events(case, events)
        n = max(
            jnp.shape(x)[0] for x in jax.tree_util.tree_leaves(events) if jnp.ndim(x)
        )
        full = jax.tree_util.tree_map(
            lambda x: jnp.broadcast_to(x, (n,)) if jnp.ndim(x) == 0 else jnp.asarray(x),
            events,
        )
        return call(rep, full)

    return run
