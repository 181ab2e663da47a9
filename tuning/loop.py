"""The training loop of the tuner: its state (`TrainState`, an equinox Module), the
checkpoints it writes and resumes from, and the optional gradient-free warm start.

A checkpoint is two files in the run folder: `checkpoint.eqx`, the state's arrays
(raw parameters, the optimizer state, the best raw parameters) written by
`equinox.tree_serialise_leaves`, and `checkpoint.json`, the rest as readable JSON
(step, seed, history, validation summaries, search history, best step and summary;
NaN written as Python's json writes it).
A run folder of the older tuner (a pickled `checkpoint.pkl`) cannot be resumed: one
line says so.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import numpy as np
import optax

from smibjax import TERM_NAMES
from smibjax._commandline import progress_bars
from smibjax._files import atomic_write, write_text

from . import problem as problem_module
from .outputs import write_history
from .problem import UsageError, build, continuation_scale, make_validation
from .resume import OLD_CHECKPOINT
from .search import cma_search, make_population_score
from .train import draw_scenarios, make_step

__all__ = [
    "TrainState",
    "Best",
    "run",
    "save_checkpoint",
    "load_checkpoint",
    "CHECKPOINT",
    "SIDECAR",
]

CHECKPOINT = "checkpoint.eqx"  # the arrays (equinox serialisation)
SIDECAR = "checkpoint.json"  # everything else, readable


class Best(eqx.Module):
    """The best validation so far: its raw parameters, step and summary."""

    raw: dict
    step: int = eqx.field(static=True)
    summary: dict = eqx.field(static=True)


class TrainState(eqx.Module):
    """The state of a tuning run after `step` optimizer steps: the raw parameters
    and the optimizer state (arrays), the best validation (`Best`), the seed of the
    training batches (batch k is drawn from fold_in(PRNGKey(seed), k)), one history
    row per step, the validation summaries, the search's history, and the wall time
    over all sessions (set by the command line when it finishes)."""

    raw: dict
    opt_state: optax.OptState
    best: Best
    step: int = eqx.field(static=True)
    seed: int = eqx.field(static=True)
    history: list = eqx.field(static=True, default_factory=list)
    validation: list = eqx.field(static=True, default_factory=list)
    search: list = eqx.field(static=True, default_factory=list)
    wall_seconds: float | None = eqx.field(static=True, default=None)
    wall_sessions: int = eqx.field(static=True, default=1)


def _plain(x):
    """JSON's fallback for NumPy scalars."""
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not JSON-serialisable")


def save_checkpoint(out: Path, state: TrainState) -> None:
    """Write the state's arrays (`CHECKPOINT`) and the rest (`SIDECAR`), each
    atomically; the sidecar last, so that it names a complete array file."""

    def dump(tmp):
        with open(tmp, "wb") as fh:
            eqx.tree_serialise_leaves(fh, state)

    atomic_write(out / CHECKPOINT, dump)
    sidecar = {
        "step": state.step,
        "seed": state.seed,
        "rng": "batch k: fold_in(PRNGKey(seed), k)",
        "best_step": state.best.step,
        "best_summary": state.best.summary,
        "history": state.history,
        "validation": state.validation,
        "search": state.search,
    }
    # NaN stays NaN (a summary with nothing stable has NaN settling times): Python's
    # json writes and reads it, where strict JSON would need null
    write_text(out / SIDECAR, json.dumps(sidecar, default=_plain, indent=1) + "\n")


def load_checkpoint(out: Path, opt, raw0) -> TrainState:
    """The state saved in `out` (`opt` and `raw0` give the structure of the arrays:
    the optimizer and the start of the run)."""
    path, side = out / CHECKPOINT, out / SIDECAR
    if not (path.is_file() and side.is_file()):
        if (out / OLD_CHECKPOINT).is_file():
            raise UsageError(
                f"--resume: {str(out / OLD_CHECKPOINT)!r} is a checkpoint of an older "
                "tuner (pickle), which this one does not read: start the run afresh "
                "in a new folder"
            )
        raise UsageError(
            f"--resume: no checkpoint in {str(out)!r} ({CHECKPOINT} missing)"
        )
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
        like = TrainState(
            raw=raw0,
            opt_state=opt.init(raw0),
            best=Best(raw=raw0, step=meta["best_step"], summary=meta["best_summary"]),
            step=_count(meta["step"]),
            seed=_count(meta["seed"]),
            history=list(meta["history"]),
            validation=list(meta["validation"]),
            search=meta["search"],
        )
        with open(path, "rb") as fh:
            return eqx.tree_deserialise_leaves(fh, like)
    except Exception as e:  # a damaged file: JSON, keys, types or the arrays
        reason = (str(e).splitlines() or [""])[0][:80] or type(e).__name__
        raise UsageError(
            f"--resume: the checkpoint in {str(out)!r} is damaged "
            f"({type(e).__name__}: {reason}): start the run afresh in a new folder"
        ) from None


def _count(v) -> int:
    """A step or seed of a checkpoint: an integer >= 0 (not a bool)."""
    if isinstance(v, bool) or not isinstance(v, int) or v < 0 or v > 2**63 - 1:
        raise ValueError(f"{v!r} is not an integer >= 0")
    return v


def advance(state: TrainState, raw, opt_state, row: dict) -> TrainState:
    """`state` after one training step: its parameters, optimizer state, step
    (`row["step"]`) and history row (the SMIB and the grid tuner alike)."""
    return dataclasses.replace(
        state,
        step=row["step"],
        raw=raw,
        opt_state=opt_state,
        history=[*state.history, row],
    )


def record_validation(
    out: Path, state: TrainState, summary: dict, better
) -> TrainState:
    """`state` with the validation `summary` of its parameters at its step recorded
    and kept as the best if `better(summary, best summary)`, then the checkpoint and
    history.csv written (what `--resume` reads back)."""
    best = state.best
    if better(summary, best.summary):
        best = Best(raw=state.raw, step=state.step, summary=summary)
    state = dataclasses.replace(
        state,
        validation=[*state.validation, {"step": state.step, **summary}],
        best=best,
    )
    save_checkpoint(out, state)
    write_history(out, state.history)
    return state


def _better(a: dict, b: dict) -> bool:
    """Validation summary a beats b: more stable scenarios, then faster mean settling."""

    def key(v):
        ts = v["settling_delta_mean"]
        return (v["stable_fraction"], -(ts if ts == ts else float("inf")))

    return key(a) > key(b)


def _progress(total, initial, quiet, make):
    """The tuning bar (steps) from the factory `make` of `progress_bars()`; None
    with `quiet`."""
    if quiet:
        return None
    return make(
        total=total,
        initial=initial,
        desc="tuning",
        unit="step",
        dynamic_ncols=True,
    )


def search_distribution(cfg: dict, dist):
    """The distribution of the search's faults: `dist` (the config's [scenarios])
    with the ranges named in [search.scenarios] replaced (the same object when none
    is)."""
    narrowed = cfg["search"].get("scenarios", {})
    if not narrowed:
        return dist
    return type(dist).from_dict(
        {**dist.to_dict(), **{k: list(map(float, v)) for k, v in narrowed.items()}}
    )


def _search(cfg, space, setup, dist, raw0, quiet):
    """The optional gradient-free warm start ([search] in the config)."""
    sc = cfg["search"]
    if int(sc["generations"]) == 0:
        return raw0, []
    faults = draw_scenarios(
        jax.random.PRNGKey(int(sc["seed"])),
        int(sc["batch"]),
        search_distribution(cfg, dist),
        setup.plant,
    )

    def report(row):
        if not quiet:
            print(
                f"search generation {row['generation']}: best score "
                f"{row['best_score']:.3f} s (this generation: "
                f"{row['generation_best']:.3f} s, "
                f"{100 * row['generation_best_stable']:.0f}% stable)",
                file=sys.stderr,
            )

    return cma_search(
        space,
        raw0,
        make_population_score(
            setup, unstable_cost=2 * float(cfg["validation"]["t_end"])
        ),
        faults,
        generations=int(sc["generations"]),
        population=int(sc["population"]),
        sigma=float(sc["sigma"]),
        seed=int(sc["seed"]),
        progress=report,
    )


def run(
    cfg: dict,
    out: Path,
    resume: bool = False,
    quiet: bool = False,
    stop_after: int | None = None,
) -> TrainState:
    """Tune; returns the final `TrainState`. Checkpoints go to `out` at every
    validation (`save_checkpoint`); `resume` continues from the last one.
    `stop_after` ends early after that many steps of this call (used by the tests to
    interrupt a run)."""
    problem = build(cfg)
    init, space, setup, dist, opt = problem
    raw0 = space.to_raw(init)
    every = int(cfg["validation"]["every"])
    steps, batch, seed = int(cfg["steps"]), int(cfg["batch"]), int(cfg["seed"])
    train_step, _ = problem_module.engine(cfg, setup)
    step_fn = make_step(setup, opt, train_step)
    validate = make_validation(cfg, problem)
    if not quiet:
        from smibjax._commandline import say_compiling

        say_compiling("the training step and the validation", "jit_run", "jit_reduce")
    if resume:
        state = load_checkpoint(out, opt, raw0)
    else:
        raw0, search_history = _search(cfg, space, setup, dist, raw0, quiet)
        v0, _ = validate(raw0)
        state = TrainState(
            raw=raw0,
            opt_state=opt.init(raw0),
            best=Best(raw=raw0, step=0, summary=v0),
            step=0,
            seed=seed,
            validation=[{"step": 0, **v0}],
            search=search_history,
        )
        if search_history:  # a resume starts after the search
            save_checkpoint(out, state)
    state = dataclasses.replace(state, seed=seed)
    key = jax.random.PRNGKey(seed)
    with progress_bars() as make:  # the bar is closed also when a step fails
        bar = _progress(steps, state.step, quiet, make)
        done_here = 0
        while state.step < steps:
            step = state.step
            scenarios = draw_scenarios(
                jax.random.fold_in(key, step), batch, dist, setup.plant
            )
            scale = continuation_scale(cfg, step)
            t0 = time.perf_counter()
            raw, opt_state, info = step_fn(
                state.raw, state.opt_state, (scenarios, scale)
            )
            row = {
                "step": step + 1,
                "loss": float(info.loss),
                "limit_scale": scale,
                "train_stable_fraction": float(np.mean(np.asarray(info.stable))),
                **{
                    f"term_{k}": float(np.mean(np.asarray(info.terms[k])))
                    for k in TERM_NAMES
                },
                "grad_norm": info.grad_norm,
                "dropped": info.dropped,
                "seconds": time.perf_counter() - t0,
            }
            state = advance(state, raw, opt_state, row)
            if (step + 1) % every == 0 or step + 1 == steps:
                v, _ = validate(raw)
                state = record_validation(out, state, v, _better)
            if bar is not None:
                last = state.validation[-1]
                bar.set_postfix(
                    loss=f"{float(info.loss):.3f}",
                    val_stable=f"{last['stable_fraction']:.2f}",
                    val_ts=f"{last['settling_delta_mean']:.2f}s",
                )
                bar.update(1)
            done_here += 1
            if stop_after is not None and done_here >= stop_after:
                break
    return state
