"""Gradient-free warm start: CMA-ES (pycma, the `search` extra) on the raw (transformed)
gains, scored with the exact metrics of the accurate adaptive solver.

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

import math

import jax
import jax.numpy as jnp
import numpy as np

from smibjax import Scenarios

from .config import require_cma

__all__ = ["make_population_score", "cma_search"]


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


def cma_search(
    space,
    raw0: dict,
    score,
    faults,
    *,
    generations: int,
    population: int,
    sigma: float,
    seed: int,
    progress=None,
) -> tuple[dict, list[dict]]:
    """Minimize `score` over the raw gains with CMA-ES (pycma), from `raw0`.

    The search distribution starts at mean `raw0` with step size `sigma` (raw
    coordinates) and the identity covariance; every generation is `population`
    candidates, the first of which is the current mean (injected, so its score is
    known and the best never scores worse than the start). The normal draws come
    from `numpy.random.default_rng(seed)` (pycma's `randn` option), never from
    NumPy's global generator: a seed gives the same generations bit for bit,
    whatever else ran in the process. The search stops after `generations`, or
    earlier when pycma's criteria on the distribution (tolx, conditioncov,
    noeffectaxis, ...) say it has collapsed; the criteria on the scores (tolfun,
    flat fitness) are off, so generations whose candidates all score the same
    (every run unstable) do not stop it.

    Non-finite scores count as 1e30 s. Returns (best raw parameters seen, one
    history row per generation: its number, the mean's score, the best score so
    far, the generation's best and that candidate's stable fraction, the step
    size sigma after the update).
    """
    cma = require_cma()
    names = list(raw0)
    x0 = np.array([float(raw0[n]) for n in names])
    rng = np.random.default_rng(seed)
    opts = {
        "popsize": int(population),
        "seed": math.nan,  # leave NumPy's global generator alone: draws come from rng
        "randn": lambda *shape: rng.standard_normal(shape),
        "maxiter": int(generations),
        # a generation whose candidates all score the same (every run unstable: the
        # realistic plant's start) is no convergence: no value-based stop
        "tolflatfitness": int(generations) + 1,
        "tolfun": 0.0,
        "tolfunhist": 0.0,
        "tolfunrel": 0.0,
        "verbose": -9,
        "verb_disp": 0,
        "verb_log": 0,
    }
    es = cma.CMAEvolutionStrategy(x0, float(sigma), opts)
    best_x, best_cost, history = x0.copy(), np.inf, []
    for gen in range(int(generations)):
        es.inject([es.mean], force=True)  # the mean, scored as candidate 0
        xs = np.asarray(es.ask(), dtype=float)
        cands = [
            space.to_gains({n: jnp.asarray(x[i]) for i, n in enumerate(names)})
            for x in xs
        ]
        cost, stable = score(cands, faults)
        cost = np.asarray(cost, dtype=float)
        cost = np.where(np.isfinite(cost), cost, 1e30)
        k = int(np.argmin(cost))
        if cost[k] < best_cost:
            best_cost, best_x = float(cost[k]), xs[k].copy()
        es.tell(list(xs), cost.tolist())
        history.append(
            {
                "generation": gen + 1,
                "mean_score": float(cost[0]),  # the distribution mean's own score
                "best_score": best_cost,
                "generation_best": float(cost[k]),
                "generation_best_stable": float(np.asarray(stable)[k]),
                "sigma": float(es.sigma),
            }
        )
        if progress is not None:
            progress(history[-1])
        if es.stop():
            break
    return {n: jnp.asarray(best_x[i]) for i, n in enumerate(names)}, history
