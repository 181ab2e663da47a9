"""The differentiated batch loss and the exact validation, sharded over CPU devices.

One call evaluates a whole batch of fault scenarios: `jax.vmap` over the scenarios,
split over the host devices (one per core), so every core integrates its own slice
with its own solver loop: the value-and-grad as one `shard_map` program
(`smibjax._parallel.shard_batch`, compiled once), the forward losses and the
validation by `smibjax._parallel.device_map`.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

import smibjax as sj
from smibjax import (
    Engine,
    LossWeights,
    Scenarios,
    aggregate,
    device_map,
    loss_terms,
    physics_summary,
    scenario_loss,
    shard_batch,
)
from smibjax.controllers import AbstractController, EstimateBox, as_controller

from .params import GainSpace


@dataclasses.dataclass(frozen=True)
class Setup:
    """Static description of the tuning problem.

    `controller`: a registry name (`smibjax.controllers.CONTROLLERS`); for the paper's
    law `adaptation`, `projection` and `phi_layer` are its options. `train_solver`:
    the `SolverOptions` of the differentiated training runs, passed whole to
    `simulate`: fixed (Tsit5 on a grid of `dt`) or adaptive (Tsit5 with `rtol`,
    `atol`, step lengths held fixed in the reverse pass); see
    benchmarks/README.md, "Gradients through the saturated loop".
    """

    space: GainSpace
    plant: sj.Plant
    weights: LossWeights
    adaptation: str
    train_t_end: float
    train_solver: sj.SolverOptions
    input_smoothing: float
    tail_weight: float
    cvar_q: float
    val_t_end: float
    controller: str = "aftsc"
    projection: EstimateBox | None = None
    phi_layer: float = 0.0
    train_phi_layer: float = 0.0

    def controller_of(self, params, training: bool = False) -> AbstractController:
        """The controller with parameter set `params` (`space.to_gains(raw)`);
        `training`: the differentiated runs' controller, whose evolution law has the
        boundary layer max(phi_layer, train_phi_layer) (the validated one: phi_layer)."""
        if isinstance(params, AbstractController):
            return params
        layer = (
            max(self.phi_layer, self.train_phi_layer) if training else self.phi_layer
        )
        options = {"projection": self.projection, "phi_layer": layer}
        return as_controller(params, self.adaptation, options)


def scaled_limits(plant: sj.Plant, scale) -> sj.Plant:
    """`plant` with its input limits multiplied by `scale` (>= 1; infinite limits
    stay infinite): the continuation from a nearly unlimited plant to the real one."""
    return eqx.tree_at(
        lambda p: (p.uf_min, p.uf_max, p.ur_min, p.ur_max),
        plant,
        (
            plant.uf_min * scale,
            plant.uf_max * scale,
            plant.ur_min * scale,
            plant.ur_max * scale,
        ),
    )


def with_damping(plant: sj.Plant, D) -> sj.Plant:
    """`plant` with its true damping D (pu) replaced (a scenario's draw)."""
    return eqx.tree_at(lambda p: p.D, plant, D)


def draw_scenarios(key, n: int, dist, plant: sj.Plant):
    """`n` scenarios from `key`: a batched `Fault` (drawn exactly as
    `sample_faults(key, n, dist.faults)`) and the true damping D of each (uniform in
    `dist.D` from an independent key, or the plant's D where not drawn)."""
    from smibjax import sample_faults

    faults = sample_faults(key, n, dist.faults)
    if dist.D is None:
        d = jnp.full((n,), plant.D, dtype=float)
    else:
        lo, hi = dist.D
        d = jax.random.uniform(
            jax.random.fold_in(key, 0xD), (n,), minval=lo, maxval=hi, dtype=float
        )
    return faults, d


def train_run(s: Setup, raw, fault: sj.Fault, D=None, scale=1.0) -> sj.Trajectory:
    """One differentiated training simulation: the training solver, soft input limits
    scaled by `scale`, the scenario's true damping `D` (None: the plant's)."""
    plant = s.plant if D is None else with_damping(s.plant, D)
    plant = scaled_limits(plant, scale)
    return sj.simulate(
        s.controller_of(s.space.to_gains(raw), training=True),
        fault,
        plant,
        solver=s.train_solver,
        save=sj.SaveOptions(t_end=s.train_t_end),
        input_smoothing=s.input_smoothing,
    )


def make_train_step(setup: Setup):
    """(raw, (faults, D), scale) -> (loss, per-scenario losses, terms, stable, grad
    wrt raw, number of scenarios dropped for a non-finite gradient); `scale`
    multiplies the input limits (continuation, 1: the real plant).

    Each device computes per-scenario losses and their gradients for its slice of the
    batch (a vmapped gradient costs one batched reverse pass); the batch aggregate's
    gradient is then sum_i d(aggregate)/d(l_i) * grad(l_i).
    """
    s = setup

    def one(raw, scale, f, d):
        tr = train_run(s, raw, f, d, scale)
        return scenario_loss(tr, s.weights), (loss_terms(tr, s.weights), tr.stable)

    # One program over all devices (compiled once; device_map would compile one per
    # device, side by side: the first step took 15.5 s instead of ~10 s).
    vg = jax.vmap(jax.value_and_grad(one, has_aux=True), in_axes=(None, None, 0, 0))
    per_scenario = shard_batch(lambda rep, bat: vg(rep[0], rep[1], *bat))

    def agg(per):
        return aggregate(per, s.tail_weight, s.cvar_q)

    # One small program (eagerly, its ~20 operations compiled one kernel each on the
    # first step: 0.5 s).
    @jax.jit
    def reduce(per, grads):
        loss, weights = jax.value_and_grad(agg)(per)
        # A scenario whose gradient is not finite contributes none (counted in the
        # history as `dropped`; the simulator is built so that this does not happen).
        finite = jnp.all(
            jnp.stack([jnp.isfinite(g) for g in jax.tree_util.tree_leaves(grads)]), 0
        )
        weights = jnp.where(finite, weights, 0.0)
        grad = jax.tree_util.tree_map(
            lambda g: jnp.tensordot(weights, jnp.where(finite, g, 0.0), 1), grads
        )
        return loss, grad, jnp.sum(~finite)

    def step(raw, scenarios, scale=1.0):
        rep = (raw, jnp.asarray(scale, dtype=float))
        (per, (terms, stable)), grads = per_scenario(rep, scenarios)
        loss, grad, dropped = reduce(per, grads)
        return loss, per, terms, stable, grad, int(dropped)

    return step


class StepInfo(NamedTuple):
    """What a training step measured on its batch."""

    loss: jax.Array  # the batch aggregate (mean + tail_weight CVaR)
    per_scenario: jax.Array  # each scenario's loss
    terms: dict  # each named loss term, per scenario (`smibjax._losses.TERMS`)
    stable: jax.Array  # each scenario's stability (training solver)
    grad_norm: float  # global norm of the batch gradient, before clipping
    dropped: int  # scenarios left out for a non-finite gradient


def make_step(setup: Setup, opt, train_step=None):
    """The training step as a pure function, optax-style:

        raw, opt_state, info = step(raw, opt_state, (scenarios, scale))

    `raw`: the raw (transformed) parameters; `opt_state`: `opt`'s state; the batch:
    (faults, D) of the scenarios and the factor on the input limits; `info`: a
    `StepInfo`. `train_step` (default: `make_train_step(setup)`) computes the batch
    loss and gradient."""
    train = make_train_step(setup) if train_step is None else train_step

    def step(raw, opt_state, batch):
        scenarios, scale = batch
        loss, per, terms, stable, grads, dropped = train(raw, scenarios, scale)
        updates, opt_state = opt.update(grads, opt_state, raw)
        gnorm = float(
            jnp.sqrt(sum(jnp.sum(g**2) for g in jax.tree_util.tree_leaves(grads)))
        )
        info = StepInfo(loss, per, terms, stable, gnorm, dropped)
        return optax.apply_updates(raw, updates), opt_state, info

    return step


def make_loss(setup: Setup):
    """(raw, (faults, D)) -> batch loss, forward only (for gradient-free
    optimizers)."""
    s = setup

    def one(raw, sc):
        tr = train_run(s, raw, *sc)
        return scenario_loss(tr, s.weights)

    per_scenario = eqx.filter_jit(jax.vmap(one, in_axes=(None, 0)))
    return lambda raw, scenarios: aggregate(
        device_map(per_scenario, raw, scenarios), s.tail_weight, s.cvar_q
    )


def validation_engine(setup: Setup) -> Engine:
    """The batch engine of the exact validation: the accurate adaptive solver, hard
    limits, the loss's settling bands, horizon `val_t_end`."""
    s = setup
    return Engine(
        s.plant,
        t_end=s.val_t_end,
        delta_band=s.weights.delta_band,
        Vt_band=s.weights.Vt_band,
    )


def make_validate(setup: Setup):
    """(parameters, (faults, D)) -> exact `Metrics` per scenario (the accurate
    adaptive solver, hard limits, the scenario's true damping D)."""
    engine = validation_engine(setup)

    def validate(params, scenarios):
        faults, d = scenarios
        return engine.run(setup.controller_of(params), Scenarios(faults, d)).metrics

    return validate


def summarize(m) -> dict[str, float]:
    """Exact validation summary: stable fraction; mean and p95 settling of the stable
    scenarios (s); mean overshoot (rad) and effort of all; the physics: the largest
    commanded inputs (pu, before limits), the mean fraction of time on a limit and
    mean total variation (pu) of each applied input, the ranges of Vt, B and E' (pu)
    over the whole set."""
    stable = np.asarray(m.stable)
    a = {k: np.asarray(v) for k, v in m._asdict().items()}
    ts = np.asarray(m.settling_delta)[stable]
    tv = np.asarray(m.settling_Vt)[stable]
    nan = float("nan")
    return {
        "stable_fraction": float(stable.mean()),
        "settling_delta_mean": float(ts.mean()) if ts.size else nan,
        "settling_delta_p95": float(np.percentile(ts, 95)) if ts.size else nan,
        "settling_Vt_mean": float(tv.mean()) if tv.size else nan,
        "overshoot_mean": float(np.mean(np.asarray(m.overshoot))),
        "effort_mean": float(
            np.mean(np.asarray(m.effort_uf) + np.asarray(m.effort_ur))
        ),
        **physics_summary(a),
    }


__all__ = [
    "Setup",
    "train_run",
    "draw_scenarios",
    "scaled_limits",
    "with_damping",
    "make_train_step",
    "make_step",
    "StepInfo",
    "make_loss",
    "make_validate",
    "validation_engine",
    "summarize",
]
