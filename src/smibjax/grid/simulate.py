"""`simulate_case`: one run of a multi-machine case through a list of events.

The engine's one adaptive solve path (`smibjax._solve.adaptive_solve`, as the SMIB's):
Tsit5 with a PID step-size controller (rtol 1e-6, atol 1e-8 by default), steps that end
exactly on the switch times (no step crosses a change of the network) and whose lengths
carry no gradient (`RigidSteps`: derivatives with respect to clearing and reclosing
times stay right after the switch). A run
that loses synchronism (a machine's angle more than pi from the centre of inertia;
from the infinite bus where the case has one) stops there: `stable` is False and
`t_unstable` says when; samples after it are NaN. With current injectors (loads
other than impedances) a network that has no solution (voltage collapse: the
Newton solve's residual above `network.COLLAPSE_TOL`) stops the run the same way,
with `collapsed` True and `t_collapse` its time. Pure and jittable; vmap over events
of one structure (`simulate_batch`), differentiable through the adaptive solver.
"""

from __future__ import annotations

import math

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._options import SolverOptions
from .._solve import adaptive_solve
from .._validate import ParameterError
from .events import check_events, switch_times
from .loop import (
    IBR_MEASUREMENTS,
    Case,
    Operating,
    evaluate,
    has_renewables,
    network_residual,
    vector_field,
)
from .network import COLLAPSE_TOL, stage_configs, stage_matrices
from .trajectory import GridTrajectory, angle_spread, coi_angles, coi_weights

__all__ = [
    "GridTrajectory",
    "simulate_case",
    "check_events",
    "coi_angles",
    "coi_weights",
    "angle_spread",
]


def _machine_mask(case: Case):
    mask = np.zeros(case.n_gen, dtype=bool)
    for gt in case.layout.machine_gen:
        mask[list(gt)] = True
    return jnp.asarray(mask)


def simulate_case(
    case: Case,
    op: Operating,
    events=(),
    *,
    t_end: float = 10.0,
    dt_save: float = 0.01,
    rtol: float = 1e-6,
    atol: float = 1e-8,
    max_steps: int = 100_000,
    dt0: float = 1e-3,
    fixed_dt: float | None = None,
    solver: SolverOptions | None = None,
) -> GridTrajectory:
    """Integrate `case` from its operating point `op` (`operating_point`) through
    `events` to `t_end` (s), saving every `dt_save` s: the engine's adaptive solve
    (`smibjax._solve.adaptive_solve`: Tsit5 with PID error control, steps ending on
    every switch time, step lengths rigid under differentiation), with the options
    `solver` (a `SolverOptions`; None: one from `rtol`, `atol` and `max_steps`), or,
    with `fixed_dt` (s), explicit Euler at that constant step and no error control
    (the prior art's fixed-step integration, for comparison; switching times should
    then be multiples of `fixed_dt`)."""
    check_events(case, events)
    if not (0 < dt_save <= t_end < math.inf):
        raise ParameterError(
            f"dt_save = {dt_save:g} s is not allowed: must lie in (0, t_end = "
            f"{t_end:g} s] (a finite horizon sampled at least twice)"
        )
    cfgs = stage_configs(op.grid, events)
    mats = stage_matrices(op.grid, cfgs, events)
    t_sw = switch_times(events)
    f = vector_field(case, op, mats, t_sw)
    n_save = int(round(t_end / dt_save)) + 1
    ts = jnp.linspace(0.0, t_end, n_save)
    mask = _machine_mask(case)

    def lost(t, y, args, **kw):
        stage = jnp.sum(t >= t_sw) if t_sw.shape[0] else 0
        delta = _delta_of(case, op, y)
        spread = angle_spread(case, delta, mats.gen_status[stage] * mask)
        return (spread > jnp.pi) | _collapsed(t, y)

    def _collapsed(t, y):
        if not case.injectors:
            return jnp.asarray(False)
        stage = jnp.sum(t >= t_sw) if t_sw.shape[0] else 0
        return ~(network_residual(case, op, mats, stage, y) <= COLLAPSE_TOL)

    if fixed_dt is None:
        if solver is None:
            solver = SolverOptions(rtol=rtol, atol=atol, max_steps=max_steps)
        sol = adaptive_solve(f, op.y0, ts, t_sw, solver, lost, dt0=dt0)
    else:
        sol = dfx.diffeqsolve(
            dfx.ODETerm(f),
            dfx.Euler(),
            t0=0.0,
            t1=t_end,
            dt0=float(fixed_dt),
            y0=op.y0,
            saveat=dfx.SaveAt(ts=ts, t1=True),
            stepsize_controller=dfx.ConstantStepSize(),
            event=dfx.Event(lost),
            max_steps=max_steps,
            throw=False,
        )
    # SaveAt(ts, t1): the grid samples reached, the final state (t_end or the time
    # synchronism was lost), then inf padding
    k = jnp.sum(jnp.isfinite(sol.ts)) - 1
    ys = sol.ys[:-1]
    stopped = sol.result == dfx.RESULTS.event_occurred
    if t_sw.shape[0]:
        stage = jnp.sum(ts[:, None] >= t_sw[None, :], axis=1)
    else:
        stage = jnp.zeros(ts.shape[0], dtype=jnp.int32)
    gen_on = mats.gen_status[stage] * mask
    same = _same_network(cfgs, stage[-1])
    delta_ref = jnp.where(same, _delta_of(case, op, op.y0), jnp.nan)
    fields = _record(case, op, mats, t_sw, ts, ys, stopped, sol.ts[k], sol, sol.ys[k])
    collapsed = stopped & _collapsed(sol.ts[k], sol.ys[k])
    return GridTrajectory(
        **fields,
        gen_on=gen_on,
        delta_ref=delta_ref,
        collapsed=collapsed,
        t_collapse=jnp.where(collapsed, sol.ts[k], jnp.inf),
    )


def _same_network(cfgs, stage):
    """Whether the network of `stage` is the one before the events (stage 0): same
    branch and generator status, no fault, no split branch."""
    keys = (
        "branch_status",
        "fault_y",
        "bolted",
        "seg_on",
        "gen_status",
        "load_scale",
        "vref_add",
        "pref_add",
    )
    out = jnp.asarray(True)
    for k in keys:
        a = getattr(cfgs, k)
        out = out & jnp.all(a[stage] == a[0])
    return out


def _delta_of(case, op, y):
    from .loop import unpack

    xm, _, _ = unpack(case, op, y)
    d = jnp.zeros(case.n_gen)
    for m, x, gt in zip(case.machines, xm, case.layout.machine_gen, strict=True):
        d = d.at[np.asarray(gt, dtype=np.int64)].set(x[m.delta_index])
    return d


def _record(case, op, mats, t_sw, ts, ys, stopped, t_last, sol, y_last):
    """The measurements and bus voltages at the samples: a loop over the stages
    applies each stage's network to every sample at once (kept where that stage is in
    force), so no per-sample (buses x ports) or (ports x ports) matrix is gathered
    (issue 46: 14 GB for 1,001 samples of a 2,224-bus case) and the device model is
    traced once."""
    n_stage = mats.A.shape[0]
    at = jnp.sum(ts[:, None] >= t_sw[None, :], axis=1) if t_sw.shape[0] else None

    def per_stage(s, y):
        _, meas, i_net = evaluate(case, op, mats, s, y)
        return meas, i_net

    valid = jnp.all(jnp.isfinite(ys), axis=-1)
    ys_safe = jnp.where(valid[:, None], ys, op.y0[None, :])

    def stage_pass(s, acc):  # s: traced but shared by all samples (one p x p gather)
        m_s, i_s = jax.vmap(lambda y: per_stage(s, y))(ys_safe)
        v_s = jnp.abs(mats.bus_voltages(s, i_s))
        here = (at == s) if at is not None else jnp.ones(ts.shape[0], dtype=bool)

        def keep(new, old):
            return jnp.where(here.reshape((-1,) + (1,) * (new.ndim - 1)), new, old)

        return jax.tree_util.tree_map(keep, (m_s, v_s), acc)

    shapes = jax.eval_shape(
        lambda: (
            jax.vmap(lambda y: per_stage(0, y)[0])(ys_safe),
            jnp.zeros((ts.shape[0], case.system.n_bus)),
        )
    )
    acc0 = jax.tree_util.tree_map(lambda a: jnp.zeros(a.shape, a.dtype), shapes)
    meas, vbus = jax.lax.fori_loop(0, n_stage, stage_pass, acc0)
    nan = jnp.where(valid, 0.0, jnp.nan)[:, None]
    pick = {k: meas[k] + nan for k in ("delta", "omega", "Efd", "Pm", "Pe", "Vt", "Vs")}
    ibr = {}  # issue 47: the renewables' signals, none without renewables
    if has_renewables(case):
        ibr = {k: meas[k] + nan for k in IBR_MEASUREMENTS if k in meas}
    return dict(
        ts=ts,
        delta=pick["delta"],
        omega=pick["omega"],
        efd=pick["Efd"],
        pm=pick["Pm"],
        pe=pick["Pe"],
        vt=pick["Vt"],
        vs=pick["Vs"],
        v_bus=vbus + nan,
        stable=~stopped & (sol.result == dfx.RESULTS.successful),
        t_unstable=jnp.where(stopped, t_last, jnp.inf),
        exhausted=sol.result == dfx.RESULTS.max_steps_reached,
        n_steps=sol.stats["num_accepted_steps"],
        y_final=y_last,
        ibr=ibr,
    )


_simulate_jit = eqx.filter_jit(simulate_case)


def simulate_jit(case: Case, op: Operating, events=(), **options) -> GridTrajectory:
    """`simulate_case`, jitted (the case and operating point traced, `options`
    static); concrete events are checked first (`check_events`)."""
    check_events(case, events)
    return _simulate_jit(case, op, events, **options)


@eqx.filter_jit
def _simulate_batch(case: Case, op: Operating, events, **options) -> GridTrajectory:
    axes = jax.tree_util.tree_map(lambda x: 0 if jnp.ndim(x) else None, events)
    return jax.vmap(lambda ev: simulate_case(case, op, ev, **options), in_axes=(axes,))(
        events
    )


def simulate_batch(case: Case, op: Operating, events, **options) -> GridTrajectory:
    """`simulate_case` over a batch of scenarios: `events` has a leading batch axis
    on every leaf that varies (scalars are shared); the case and operating point are
    shared. Returns a GridTrajectory with a leading batch axis. Concrete events are
    checked first (`check_events`)."""
    check_events(case, events)
    return _simulate_batch(case, op, events, **options)
