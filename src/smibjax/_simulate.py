"""`simulate`: one closed-loop run from the operating point through the fault sequence.

Pure, jittable (it is jitted), vmappable over any parameter set and differentiable with
respect to gains, plant parameters and switch times.

Integration: the right-hand side changes at t_fault, t_clear and t_reclose, so the
solver is told about them (`jump_ts`): each step ends just before a switch time and the
next starts just after it, and the right-hand side is never evaluated across a switch.

Solver choice (measured, see README "Numerics"): Tsit5 with a PID step-size controller,
rtol = 1e-6, atol = 1e-8 by default; against an independent SciPy DOP853 run at
rtol = 1e-11 this keeps delta within 1.2e-6 rad (AFTSC) and 1e-8 rad (ASC) on the
paper's fault with beta1 = beta2 = -1 (rtol = 1e-7: 2e-7 rad for 1.7x the steps).
Dopri8 was slower and, for alpha < 1, exhausted 50,000 steps in the chattering tail.
Explicit steps are right here: the stiffest linear mode is -1/T1 = -200 1/s (stable for Tsit5 up to
~15 ms), and for alpha < 1 the step size in the tail is limited by the finite-time law
near phi = 0, whose derivative is unbounded (an implicit solver would need its
Jacobian there; measured: SciPy's Radau and BDF take 2.7x and 3.9x the steps of RK45
for alpha = 5/7, and diffrax's Kvaerno3/5 exhaust 50,000 steps, because |phi|^alpha is
not Lipschitz at 0). `solver="fixed"` steps with Tsit5 on a grid known before the run
(`smibjax._fixed`: steps of `dt`, the sample times and the switch times, as a
checkpointed `lax.scan`); it is the paper config's path for gradients through
alpha < 1. Under input limits its gradients are wrong (the loop chatters on the grid,
benchmarks/README.md), and the default tuning path is adaptive at rtol 1e-8 with the
evolution law's boundary layer (tests/test_tuning.py, tests/test_gradients.py).
"""

from __future__ import annotations

import warnings
from typing import Literal

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ._closed_loop import (
    ClosedLoop,
    closed_loop_vector_field,
    healthy,
    initial_state,
)
from ._fixed import solve_fixed
from ._inputs import DEFAULT_DELTA_BAND as _DELTA_BAND
from ._inputs import require_known_values as require_known_values
from ._inputs import simulate_inputs
from ._network import prefault_stage, stage_at
from ._options import DEFAULT_MAX_STEPS, SaveOptions, SolverOptions
from ._parameters import (
    Fault,
    InitialEstimates,
    OperatingPoint,
    Plant,
)
from ._plant import apply_limits, equilibrium_state, sincos, terminal_voltage
from ._solve import METHOD_CLASSES, adaptive_solve
from ._validate import require_x64
from .controllers import AbstractController, Gains

__all__ = ["Trajectory", "simulate", "is_stable", "DEFAULT_DELTA_BAND"]

DEFAULT_DELTA_BAND = _DELTA_BAND  # rad, docs/model.md section 4


Series = Float[Array, "*batch n"]
Scalar = Float[Array, "*batch"]


class Trajectory(eqx.Module):
    """A closed-loop run sampled on a uniform grid t (s).

    After a loss of synchronism the run stops (`lost_sync`), and every later sample
    holds the last sample before the stop, so all arrays stay finite; likewise when the
    adaptive solver runs out of steps (`budget_exhausted`).
    """

    t: Series  # sample times (s)
    delta: Series  # rotor angle (rad)
    omega: Series  # speed deviation domega (rad/s)
    E: Series  # transient EMF E' (pu)
    B: Series  # SVC susceptance (pu)
    Vt: Series  # SVC-bus voltage (pu)
    # estimates of theta = (-D, Pm) (0 for a controller without estimates)
    theta_hat: Float[Array, "*batch n 2"]
    # the controller's two diagnostics: macro-variables (phi1, phi2) of the paper's
    # controller (`AbstractController.diagnostic_names`)
    phi: Float[Array, "*batch n 2"]
    u_f: Series  # field voltage reaching the plant (after limits, pu)
    u_r: Series  # SVC command reaching the plant (after limits, pu)
    u_f_cmd: Series  # field voltage commanded by the controller (before limits, pu)
    u_r_cmd: Series  # SVC command commanded by the controller (before limits, pu)
    effort: Float[Array, "*batch 2"]  # integrals of u_f^2 and u_r^2 over [0, t_end]
    stable: Bool[Array, "*batch"]  # no loss of synchronism, delta in band at t_end
    lost_sync: Bool[Array, "*batch"]  # the run left 0 < delta < pi (or the domain)
    # the adaptive solver spent `max_steps` before t_end: neither stable nor lost
    budget_exhausted: Bool[Array, "*batch"]
    t_stop: Scalar  # time the integration ended (t_end unless lost_sync)
    num_steps: Int[Array, "*batch"]  # accepted solver steps
    num_rejected: Int[Array, "*batch"]  # rejected solver steps
    delta_e: Scalar  # operating-point angle (rad)
    Vt_e: Scalar  # operating-point SVC-bus voltage (pu)
    t_fault: Scalar  # fault inception (s)


def is_stable(lost_sync, delta_end, delta_e, delta_band: float = DEFAULT_DELTA_BAND):
    """docs/model.md section 4: no loss of synchronism (nor a run cut short: pass
    `lost_sync | budget_exhausted`), and delta back within `delta_band` (rad) of
    delta_e at t_end."""
    return (~lost_sync) & (jnp.abs(delta_end - delta_e) <= delta_band)


class _RmsDynamic(eqx.Module):
    """RMS norm over the first `n` (dynamic) states only: the effort integrals are
    outputs."""

    n: int = eqx.field(static=True)

    def __call__(self, y):
        return jnp.sqrt(jnp.mean(y[: self.n] ** 2))


_SOLVERS = METHOD_CLASSES  # the one table of methods: _solve.py


def _solve_adaptive(loop, y0, ts, jumps, solver: SolverOptions):
    """diffrax's adaptive loop (`solver`'s method, tolerances, step budget and
    checkpoints): PID step control, exact steps onto the switch times, an event on
    leaving the domain. Returns (samples, held state, lost_sync, budget exhausted,
    t_stop, accepted steps, rejected steps)."""
    n = ts.shape[0]
    sol = adaptive_solve(
        closed_loop_vector_field,
        y0,
        ts,
        jumps,
        solver,
        lambda t, y, args, **kw: ~healthy(t, y, args),
        args=loop,
        norm=_RmsDynamic(loop.n_dynamic),
    )
    # SaveAt(ts, t1) stores the grid points reached, then the final state (t_end, or the
    # time the run stopped on loss of synchronism), then inf padding. After a stop, the
    # samples hold the last grid sample reached: the state at the stop itself lies past
    # the breakdown margin.
    k = jnp.sum(jnp.isfinite(sol.ts)) - 1
    t_stop = sol.ts[k]
    stopped = sol.result != dfx.RESULTS.successful
    exhausted = sol.result == dfx.RESULTS.max_steps_reached
    lost_sync = stopped & ~exhausted
    y_hold = jnp.where(stopped, sol.ys[jnp.maximum(k - 1, 0)], sol.ys[k])
    reached = jnp.arange(n) < k
    ys = jnp.where(reached[:, None], sol.ys[:n], y_hold[None, :])
    return (
        ys,
        y_hold,
        lost_sync,
        exhausted,
        t_stop,
        sol.stats["num_accepted_steps"],
        sol.stats["num_rejected_steps"],
    )


@eqx.filter_jit
def _simulate(
    controller: AbstractController,
    fault: Fault,
    plant: Plant,
    op: OperatingPoint,
    init: InitialEstimates,
    *,
    t_end: float,
    dt_save: float,
    solver: SolverOptions,
    delta_band: float,
    input_smoothing: float,
) -> Trajectory:
    loop = ClosedLoop(
        gains=controller,
        fault=fault,
        plant=plant,
        op=op,
        input_smoothing=input_smoothing,
    )
    y0 = initial_state(op, plant, init, controller)
    n_dyn = loop.n_dynamic
    ts_np = np.linspace(0.0, t_end, int(round(t_end / dt_save)) + 1)
    ts = jnp.asarray(ts_np)
    jumps = jnp.stack([fault.t_fault, fault.t_clear, fault.t_reclose])
    if solver.kind == "fixed":
        checkpoints = solver.checkpoints
        sol = solve_fixed(
            closed_loop_vector_field,
            loop,
            y0,
            jumps,
            healthy,
            t_end=t_end,
            dt=float(solver.dt),
            ts=ts_np,
            solver=_SOLVERS[solver.method](),
            checkpoints=None if checkpoints is None else int(checkpoints),
        )
        ys, y_hold, lost_sync = sol.samples, sol.y_hold, sol.lost_sync
        t_stop, num_steps = sol.t_stop, sol.num_steps
        num_rejected = jnp.zeros_like(num_steps)
        exhausted = jnp.zeros_like(lost_sync)
    else:
        ys, y_hold, lost_sync, exhausted, t_stop, num_steps, num_rejected = (
            _solve_adaptive(loop, y0, ts, jumps, solver)
        )

    def observe(t, y):
        z = y[:4]
        stage = stage_at(t, fault, plant)
        trig = sincos(z[0])
        out = controller(t, z, y[4:n_dyn], stage, plant, op, trig)
        u_f, u_r = apply_limits(out.u_f, out.u_r, plant, input_smoothing)
        vt = terminal_voltage(z[0], z[2], z[3], stage, plant, trig)
        return vt, out.diagnostics, u_f, u_r, out.u_f, out.u_r

    vt, phi, u_f, u_r, u_f_cmd, u_r_cmd = jax.vmap(observe)(ts, ys)
    if controller.has_estimates:
        theta_hat = ys[:, 4:6]
    else:
        theta_hat = jnp.zeros((ys.shape[0], 2), ys.dtype)
    z_e = equilibrium_state(op, plant)
    vt_e = terminal_voltage(z_e[0], z_e[2], z_e[3], prefault_stage(plant), plant)
    delta = ys[:, 0]
    stable = is_stable(lost_sync | exhausted, delta[-1], op.delta_e, delta_band)
    return Trajectory(
        t=ts,
        delta=delta,
        omega=ys[:, 1],
        E=ys[:, 2],
        B=ys[:, 3],
        Vt=vt,
        theta_hat=theta_hat,
        phi=phi,
        u_f=u_f,
        u_r=u_r,
        u_f_cmd=u_f_cmd,
        u_r_cmd=u_r_cmd,
        effort=y_hold[n_dyn : n_dyn + 2],
        stable=stable,
        lost_sync=lost_sync,
        budget_exhausted=exhausted,
        t_stop=t_stop,
        num_steps=num_steps,
        num_rejected=num_rejected,
        delta_e=op.delta_e,
        Vt_e=vt_e,
        t_fault=fault.t_fault,
    )


_LEGACY = (
    "t_end",
    "dt_save",
    "method",
    "rtol",
    "atol",
    "dt",
    "max_steps",
    "checkpoints",
)


def _legacy_options(solver, legacy: dict) -> tuple[SolverOptions, SaveOptions]:
    """The option objects of the keyword arguments `simulate` took before 0.2
    (`solver` as the string "adaptive"/"fixed", `t_end`, `dt_save`, `method`,
    `rtol`, `atol`, `dt`, `max_steps`, `checkpoints`): a deprecated shim, kept for
    one release."""
    for k in legacy:
        if k not in _LEGACY:
            raise TypeError(f"simulate() got an unexpected keyword argument {k!r}")
    warnings.warn(
        "simulate(t_end=, dt_save=, rtol=, ..., solver='fixed') is deprecated: pass "
        "solver=SolverOptions(...) and save=SaveOptions(...)",
        DeprecationWarning,
        stacklevel=3,
    )
    if isinstance(solver, SolverOptions):
        raise TypeError(
            "simulate(): give solver=SolverOptions(...) or the old solver keywords, "
            "not both"
        )
    max_steps = legacy.get("max_steps")
    sopts = SolverOptions(
        "adaptive" if solver is None else solver,
        legacy.get("method", "tsit5"),
        legacy.get("rtol", 1e-6),
        legacy.get("atol", 1e-8),
        DEFAULT_MAX_STEPS if max_steps is None else max_steps,
        legacy.get("dt", 1e-3),
        legacy.get("checkpoints"),
    )
    save = SaveOptions(legacy.get("t_end", 10.0), legacy.get("dt_save", 0.01))
    return sopts, save


def simulate(
    gains: Gains | AbstractController | None = None,
    fault: Fault | None = None,
    plant: Plant | None = None,
    *,
    op: OperatingPoint | None = None,
    init: InitialEstimates | None = None,
    adaptation: Literal["oracle", "realizable"] | None = None,
    solver: SolverOptions | None = None,
    save: SaveOptions | None = None,
    delta_band: float = DEFAULT_DELTA_BAND,
    input_smoothing: float = 0.0,
    **legacy,
) -> Trajectory:
    """Simulate the closed loop from the operating point over [0, save.t_end] (s).

    **Arguments:**

    - `gains`: the paper's `Gains` (the AFTSC/ASC law, `smibjax.Synergetic`) or any
      controller (`smibjax.controllers`; default: the paper's AFTSC gains).
    - `fault`, `plant`, `op`, `init`: parameter sets (defaults: the paper's fault, the
      paper plant, operating point and initial estimates). Any of them may carry
      arrays; vmap `simulate` over them for batches.
    - `adaptation`: for the paper's law, `"oracle"` (its update law, using the true
      theta in its k-terms; the default for `Gains`) or `"realizable"` (without them);
      None keeps a `Synergetic` controller's own setting. Other controllers have no
      adaptation and ignore it.
    - `solver`: a `SolverOptions` (default: adaptive Tsit5, rtol 1e-6, atol 1e-8,
      50,000 steps).
    - `save`: a `SaveOptions`, the horizon and sampling interval of the returned
      arrays (default: 10 s sampled every 0.01 s).
    - `delta_band`: the band (rad) that delta must be back in at t_end to be stable.
    - `input_smoothing`: 0 for the hard input limiter; > 0 (pu) for a soft one that
      keeps gradients beyond the limits (for training losses).

    The keywords of 0.1 (`t_end`, `dt_save`, `method`, `rtol`, `atol`, `dt`,
    `max_steps`, `checkpoints`, and `solver` as a string) still work, with a
    `DeprecationWarning`, for one release.

    **Returns:** a `Trajectory`.
    """
    require_x64()
    if legacy or isinstance(solver, str):
        solver, save = _legacy_options(solver, legacy)
    controller, fault, plant, op, init, solver, save = simulate_inputs(
        gains, fault, plant, op, init, adaptation, solver, save
    )
    t_end, dt_save = save.t_end, save.dt_save
    return _simulate(
        controller,
        fault,
        plant,
        op,
        init,
        t_end=float(t_end),
        dt_save=float(dt_save),
        solver=solver,
        delta_band=float(delta_band),
        input_smoothing=float(input_smoothing),
    )
