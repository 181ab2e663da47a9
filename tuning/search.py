"""Gradient-free warm start: the cross-entropy method on the raw (transformed) gains,
scored with the exact metrics of the accurate adaptive solver.

Why: under the realistic input limits the gradients of the saturated loop overflow
unless the training step is very fine, and from a start where most runs wind up the
loss surface is nearly flat (see tuning/configs/realistic.toml). A population search
needs only values: each generation simulates every candidate on a fixed batch of
faults in one vmapped call (candidates x faults lanes, split over the cores). The
gradient steps then start from the best candidate found.

Score of a candidate (s, lower is better): the mean over the batch of the delta
settling time for a stable run and `unstable_cost` for an unstable one.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from smibjax import Scenarios

__all__ = ["make_population_score", "cross_entropy_search"]


def make_population_score(setup, unstable_cost: float = 20.0):
    """(list of parameter sets, (faults, D)) -> (mean score (s), stable fraction),
    one per candidate: every candidate on every scenario, as lanes of one batch of
    the validation engine; a run's score is its delta settling time, or
    `unstable_cost` if it is not stable."""
    from .train import validation_engine

    engine = validation_engine(setup)

    def score(candidates: list, scenarios):
        faults, damping = scenarios
        p = len(candidates)
        b = jax.tree_util.tree_leaves(faults)[0].shape[0]
        ctrls = [setup.controller_of(c) for c in candidates]
        lanes = jax.tree_util.tree_map(
            lambda *xs: jnp.repeat(jnp.stack([jnp.asarray(x) for x in xs]), b, axis=0),
            *[c.tunable() for c in ctrls],
        )
        tiled = jax.tree_util.tree_map(lambda a: jnp.tile(a, p), (faults, damping))
        m = engine.run(ctrls[0], Scenarios(*tiled), lanes=lanes).metrics
        stable = np.asarray(m.stable).reshape(p, b)
        cost = np.where(
            stable, np.asarray(m.settling_delta).reshape(p, b), unstable_cost
        )
        return cost.mean(axis=1), stable.mean(axis=1)

    return score


def cross_entropy_search(
    space,
    raw0: dict,
    score,
    faults,
    *,
    generations: int,
    population: int,
    elite: int,
    sigma: float,
    seed: int,
    progress=None,
) -> tuple[dict, list[dict]]:
    """Minimize `score` over the raw gains from `raw0`.

    Each generation draws `population - 1` candidates from N(mean, diag(std^2)) plus the
    mean itself, keeps the `elite` best and moves the mean and std to theirs (std
    floored at sigma / 20 so the search does not freeze early). Returns (best raw
    parameters seen, one history row per generation).
    """
    names = list(raw0)
    mean = np.array([float(raw0[n]) for n in names])
    std = np.full(mean.size, float(sigma))
    rng = np.random.default_rng(seed)
    best_x, best_cost, history = mean.copy(), np.inf, []
    for gen in range(generations):
        xs = mean + std * rng.standard_normal((population - 1, mean.size))
        xs = np.vstack([mean, xs])
        cands = [
            space.to_gains({n: jnp.asarray(x[i]) for i, n in enumerate(names)})
            for x in xs
        ]
        cost, stable = score(cands, faults)
        cost = np.where(np.isfinite(cost), cost, np.inf)
        order = np.argsort(cost, kind="stable")
        if cost[order[0]] < best_cost:
            best_cost, best_x = float(cost[order[0]]), xs[order[0]].copy()
        el = xs[order[:elite]]
        mean = el.mean(axis=0)
        std = np.maximum(el.std(axis=0), sigma / 20)
        history.append(
            {
                "generation": gen + 1,
                "mean_score": float(cost[0]),  # the distribution mean's own score
                "best_score": best_cost,
                "generation_best": float(cost[order[0]]),
                "generation_best_stable": float(stable[order[0]]),
                "mean_std": float(std.mean()),
            }
        )
        if progress is not None:
            progress(history[-1])
    return {n: jnp.asarray(best_x[i]) for i, n in enumerate(names)}, history
