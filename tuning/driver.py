"""The tuner's driver: builds the problem from a configuration, runs the training
loop over the pure step (`tuning.train.make_step`), checkpoints, resumes and writes the
results. The command line is `tuning.optimize`.
"""

from __future__ import annotations

import json
import pickle
import sys
import time
from pathlib import Path
from typing import NamedTuple

import jax
import numpy as np
import optax

import smibjax as sj
from smibjax import TERM_NAMES, GainsFile, LossWeights, ScenarioDistribution
from smibjax.cli.files import (
    atomic_write,
    read_gains,
    read_table,
    write_gains_file,
    write_text,
)
from smibjax.controllers import CONTROLLERS, EstimateBox, make_controller

from .params import GainSpace, gains_to_dict
from .search import cross_entropy_search, make_population_score
from .train import (
    Setup,
    draw_scenarios,
    make_step,
    make_train_step,
    make_validate,
    summarize,
)


class UsageError(Exception):
    """A command-line usage error (one line, exit 2)."""


class Problem(NamedTuple):
    """What a configuration builds: the start (parameter values), the gain space,
    the static setup, the scenario distribution and the optimizer."""

    init: dict
    space: GainSpace
    setup: Setup
    dist: ScenarioDistribution
    opt: optax.GradientTransformation


CHECKPOINT = "checkpoint.pkl"


def parameter_names(cfg) -> tuple[str, ...]:
    """The tunable parameter names of the configured controller."""
    return tuple(CONTROLLERS[cfg["controller"]].parameter_kinds())


def initial_gains(cfg) -> dict[str, float]:
    """The start: the controller's defaults (the paper's gains for aftsc/asc),
    overridden by the gains file `init` (if not "paper"), validated."""
    base = make_controller(cfg["controller"]).parameters()
    if cfg["init"] != "paper":
        names = parameter_names(cfg)
        table = read_gains(cfg["init"]) if names == sj.GAIN_NAMES else None
        if table is None:
            table = read_table(cfg["init"])
        base.update(table)
        make_controller(cfg["controller"], base)  # validate (unknown names too)
    return base


def projection_box(cfg) -> EstimateBox | None:
    """[options] projection = [[th1_min, th1_max], [th2_min, th2_max]] or [] (off)."""
    box = cfg["options"]["projection"]
    if box in ([], None):
        return None
    try:
        (a, b), (c, d) = box
        lo, hi = [float(a), float(c)], [float(b), float(d)]
    except (TypeError, ValueError):
        raise sj.ParameterError(
            f"options.projection = {box!r} is not allowed: must be "
            "[[th1_min, th1_max], [th2_min, th2_max]] or [] (off)"
        ) from None
    return EstimateBox(lo, hi)


def continuation_scale(cfg, step: int) -> float:
    """The factor on the input limits at training step `step`: `start` at step 0,
    falling geometrically to 1 at step `steps` of [continuation] (1 throughout when
    `steps` = 0): the tuner starts on a nearly unlimited plant, where the gradient
    leads off the paper's unstable gains, and ends on the real one."""
    c = cfg["continuation"]
    n, start = int(c["steps"]), float(c["start"])
    if n <= 0 or step >= n:
        return 1.0
    return start ** (1.0 - step / n)


def build(cfg) -> Problem:
    init = initial_gains(cfg)
    names = parameter_names(cfg)
    controller_cls = CONTROLLERS[cfg["controller"]]
    space = GainSpace.build(
        init,
        [n for n in cfg["gains"]["freeze"] if n in names or n not in sj.GAIN_NAMES],
        {k: v for k, v in cfg["gains"]["bounds"].items() if k in names},
        float(cfg["gains"]["beta_abs_min"]),
        kinds=controller_cls.parameter_kinds(),
        make=controller_cls.parameter_type(),
    )
    lw = cfg["loss"]
    weights = LossWeights(
        **{k: float(lw[k]) for k in (*TERM_NAMES, "delta_band", "Vt_band")}
    )
    box = projection_box(cfg) if "projection" in controller_cls.option_names else None
    if box is not None:
        th0 = (sj.InitialEstimates().th1, sj.InitialEstimates().th2)
        if not box.contains(th0):
            raise sj.ParameterError(
                f"options.projection = {cfg['options']['projection']!r} is not "
                f"allowed: it must contain the initial estimates (th1, th2) = "
                f"({float(th0[0]):g}, {float(th0[1]):g})"
            )
    t = cfg["train"]
    setup = Setup(
        space=space,
        plant=sj.Plant.preset(cfg["preset"]),
        weights=weights,
        adaptation=cfg["adaptation"],
        train_t_end=float(t["t_end"]),
        train_dt=float(t["dt"]),
        input_smoothing=float(t["input_smoothing"]),
        tail_weight=float(lw["tail_weight"]),
        cvar_q=float(lw["cvar_q"]),
        val_t_end=float(cfg["validation"]["t_end"]),
        train_checkpoints=int(t["checkpoints"]) or None,
        controller=cfg["controller"],
        projection=box,
        phi_layer=float(cfg["options"]["phi_layer"]),
        train_solver=str(t["solver"]),
        train_rtol=float(t["rtol"]),
        train_atol=float(t["atol"]),
        train_max_steps=int(t["max_steps"]),
    )
    # D = [] in a config: the plant's own damping (not drawn)
    dist = ScenarioDistribution.from_dict(
        {k: v for k, v in cfg["scenarios"].items() if not (k == "D" and v == [])}
    )
    opt = optax.chain(
        optax.zero_nans(),
        optax.clip_by_global_norm(float(cfg["optimizer"]["clip_norm"])),
        optax.adam(
            optax.cosine_decay_schedule(
                float(cfg["optimizer"]["learning_rate"]),
                decay_steps=max(int(cfg["steps"]), 1),
                alpha=float(cfg["optimizer"]["final_lr_fraction"]),
            )
        ),
    )
    return Problem(init, space, setup, dist, opt)


def _better(a: dict, b: dict) -> bool:
    """Validation summary a beats b: more stable scenarios, then faster mean settling."""

    def key(v):
        ts = v["settling_delta_mean"]
        return (v["stable_fraction"], -(ts if ts == ts else float("inf")))

    return key(a) > key(b)


def save_checkpoint(out: Path, state: dict) -> None:
    blob = {
        "step": state["step"],
        "raw": jax.tree_util.tree_map(np.asarray, state["raw"]),
        "opt_leaves": [
            np.asarray(x) for x in jax.tree_util.tree_leaves(state["opt_state"])
        ],
        "history": state["history"],
        "validation": state["validation"],
        "best": {
            **state["best"],
            "raw": jax.tree_util.tree_map(np.asarray, state["best"]["raw"]),
        },
        "rng": {"seed": state["seed"], "batches": "fold_in(PRNGKey(seed), step)"},
        "search": state.get("search", []),
    }

    def dump(tmp):
        with open(tmp, "wb") as fh:
            pickle.dump(blob, fh)

    atomic_write(out / CHECKPOINT, dump)


def load_checkpoint(out: Path, opt, raw0) -> dict:
    path = out / CHECKPOINT
    if not path.is_file():
        raise UsageError(
            f"--resume: no checkpoint in {str(out)!r} ({CHECKPOINT} missing)"
        )
    with open(path, "rb") as fh:
        blob = pickle.load(fh)
    treedef = jax.tree_util.tree_structure(opt.init(raw0))
    opt_state = jax.tree_util.tree_unflatten(
        treedef, [jax.numpy.asarray(x) for x in blob["opt_leaves"]]
    )
    raw = jax.tree_util.tree_map(jax.numpy.asarray, blob["raw"])
    return {
        "step": blob["step"],
        "raw": raw,
        "opt_state": opt_state,
        "history": blob["history"],
        "validation": blob["validation"],
        "search": blob.get("search", []),
        "best": {
            **blob["best"],
            "raw": jax.tree_util.tree_map(jax.numpy.asarray, blob["best"]["raw"]),
        },
    }


def write_history(out: Path, history: list[dict]) -> None:
    if not history:
        return
    cols = list(history[0])
    lines = [",".join(cols)] + [
        ",".join("" if r.get(c) is None else f"{r[c]:.10g}" for c in cols)
        for r in history
    ]
    write_text(out / "history.csv", "\n".join(lines) + "\n")


def _progress(total, initial, quiet):
    if quiet:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return None
    return tqdm(
        total=total,
        initial=initial,
        desc="tuning",
        unit="step",
        dynamic_ncols=True,
        file=sys.stderr,
    )


_ENGINES: dict[str, tuple] = {}


def _engine(cfg: dict, setup: Setup):
    """The jitted training step and validation for this configuration, built once per
    process (a resumed or repeated run reuses the compiled functions)."""
    key = json.dumps(
        {k: v for k, v in cfg.items() if k not in ("steps", "seed")}, sort_keys=True
    )
    if key not in _ENGINES:
        _ENGINES[key] = (make_train_step(setup), make_validate(setup))
    return _ENGINES[key]


def validation_scenarios(cfg: dict, problem: Problem):
    """The fixed validation set: (faults, D) of `validation.n` scenarios."""
    return draw_scenarios(
        jax.random.PRNGKey(int(cfg["validation"]["seed"])),
        int(cfg["validation"]["n"]),
        problem.dist,
        problem.setup.plant,
    )


def make_validation(cfg: dict, problem: Problem):
    """raw -> (validation summary, per-scenario metrics) on the fixed set."""
    _, validate_fn = _engine(cfg, problem.setup)
    val = validation_scenarios(cfg, problem)

    def validate(raw):
        m = validate_fn(problem.space.to_gains(raw), val)
        m = jax.tree_util.tree_map(np.asarray, m)
        return summarize(m), m

    return validate


def _search(cfg, space, setup, dist, raw0, quiet):
    """The optional gradient-free warm start ([search] in the config)."""
    sc = cfg["search"]
    if int(sc["generations"]) == 0:
        return raw0, []
    faults = draw_scenarios(
        jax.random.PRNGKey(int(sc["seed"])), int(sc["batch"]), dist, setup.plant
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

    return cross_entropy_search(
        space,
        raw0,
        make_population_score(
            setup, unstable_cost=2 * float(cfg["validation"]["t_end"])
        ),
        faults,
        generations=int(sc["generations"]),
        population=int(sc["population"]),
        elite=int(sc["elite"]),
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
) -> dict:
    """Tune; returns the final state (plain data: step, raw, opt_state, history,
    validation, search, best, seed). `stop_after` ends early after that many steps
    of this call (used by the tests to interrupt a run)."""
    problem = build(cfg)
    init, space, setup, dist, opt = problem
    raw0 = space.to_raw(init)
    every = int(cfg["validation"]["every"])
    steps, batch, seed = int(cfg["steps"]), int(cfg["batch"]), int(cfg["seed"])
    train_step, _ = _engine(cfg, setup)
    step_fn = make_step(setup, opt, train_step)
    validate = make_validation(cfg, problem)
    if resume:
        state = load_checkpoint(out, opt, raw0)
    else:
        raw0, search_history = _search(cfg, space, setup, dist, raw0, quiet)
        state = {
            "step": 0,
            "raw": raw0,
            "opt_state": opt.init(raw0),
            "history": [],
            "validation": [],
            "search": search_history,
            "seed": seed,
        }
        v0, _ = validate(raw0)
        state["validation"].append({"step": 0, **v0})
        state["best"] = {"step": 0, "raw": raw0, "summary": v0}
        if search_history:  # a resume starts after the search
            save_checkpoint(out, state)
    state["seed"] = seed
    key = jax.random.PRNGKey(seed)
    bar = _progress(steps, state["step"], quiet)
    done_here = 0
    while state["step"] < steps:
        step = state["step"]
        scenarios = draw_scenarios(
            jax.random.fold_in(key, step), batch, dist, setup.plant
        )
        scale = continuation_scale(cfg, step)
        t0 = time.perf_counter()
        raw, opt_state, info = step_fn(
            state["raw"], state["opt_state"], (scenarios, scale)
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
        state.update(step=step + 1, raw=raw, opt_state=opt_state)
        state["history"].append(row)
        if (step + 1) % every == 0 or step + 1 == steps:
            v, _ = validate(raw)
            state["validation"].append({"step": step + 1, **v})
            if _better(v, state["best"]["summary"]):
                state["best"] = {"step": step + 1, "raw": raw, "summary": v}
            save_checkpoint(out, state)
            write_history(out, state["history"])
        if bar is not None:
            last = state["validation"][-1]
            bar.set_postfix(
                loss=f"{float(info.loss):.3f}",
                val_stable=f"{last['stable_fraction']:.2f}",
                val_ts=f"{last['settling_delta_mean']:.2f}s",
            )
            bar.update(1)
        done_here += 1
        if stop_after is not None and done_here >= stop_after:
            break
    if bar is not None:
        bar.close()
    return state


def _gains_file(cfg: dict, gains, names=None) -> GainsFile:
    """The gains with what they were tuned for (schema smibjax.gains/1): controller,
    adaptation mode, the controller's options and the plant preset with its finite
    input limits (pu)."""
    plant = sj.Plant.preset(cfg["preset"])
    limits = {k: float(getattr(plant, k)) for k in ("uf_min", "uf_max")}
    limits.update({k: float(getattr(plant, k)) for k in ("ur_min", "ur_max")})
    limits = {k: v for k, v in limits.items() if np.isfinite(v)}  # none: no limit
    controller = cfg["controller"]
    values = gains_to_dict(gains, names or parameter_names(cfg))
    options = {}
    if "options" in cfg:
        controller, options = CONTROLLERS[controller].options_for_file(
            controller, values, cfg["options"]
        )
    return GainsFile(
        controller=controller,
        adaptation=cfg["adaptation"],
        plant={"preset": cfg["preset"], **limits},
        options=options,
        gains=values,
    )


def finish(cfg: dict, out: Path, state: dict) -> None:
    """gains.json, history.csv, report.md and plots."""
    from .report import write_report

    problem = build(cfg)
    space = problem.space
    names = tuple(space.kinds)
    gains = space.to_gains(state["best"]["raw"])
    write_gains_file(out / "gains.json", _gains_file(cfg, gains, names))
    last = space.to_gains(state["raw"])
    write_gains_file(out / "gains_last.json", _gains_file(cfg, last, names))
    write_history(out, state["history"])
    write_report(
        cfg,
        out,
        state,
        problem,
        make_validation(cfg, problem),
        validation_scenarios(cfg, problem),
    )
