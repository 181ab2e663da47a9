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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import smibjax as sj
from smibjax.metrics import metrics
from smibjax.parallel import device_map

__all__ = ["make_population_score", "cross_entropy_search"]


def make_population_score(setup, unstable_cost: float = 20.0):
    """(list of Gains, batched Fault) -> array of scores (s), one per candidate."""
    s = setup

    from .train import with_damping

    def one(gains, f, d):
        tr = sj.simulate(
            s.controller_of(gains), f, with_damping(s.plant, d), t_end=s.val_t_end
        )
        m = metrics(tr, delta_band=s.weights.delta_band, Vt_band=s.weights.Vt_band)
        return jnp.where(m.stable, m.settling_delta, unstable_cost), m.stable

    batched = eqx.filter_jit(jax.vmap(one))

    def score(candidates: list, scenarios):
        faults, damping = scenarios
        p = len(candidates)
        b = jax.tree_util.tree_leaves(faults)[0].shape[0]
        gains = jax.tree_util.tree_map(
            lambda *xs: jnp.repeat(jnp.stack(xs), b, axis=0), *candidates
        )
        tiled = jax.tree_util.tree_map(lambda a: jnp.tile(a, p), (faults, damping))
        cost, stable = device_map(
            lambda _, x: batched(x[0], *x[1]), None, (gains, tiled)
        )
        cost = np.asarray(cost).reshape(p, b)
        stable = np.asarray(stable).reshape(p, b)
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
