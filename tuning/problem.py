"""The tuning problem a configuration builds: the start, the gain space, the static
set-up of the training and validation runs, the scenario distribution and the
optimizer (`build`); the jitted step and validation built once per process."""

from __future__ import annotations

import json
from typing import NamedTuple

import jax
import numpy as np
import optax

import smibjax as sj
from smibjax import TERM_NAMES, LossWeights, ScenarioDistribution
from smibjax._files import read_gains, read_table
from smibjax.controllers import CONTROLLERS, EstimateBox, make_controller

from .params import GainSpace
from .train import Setup, draw_scenarios, make_train_step, make_validate, summarize

__all__ = [
    "Problem",
    "UsageError",
    "build",
    "parameter_names",
    "initial_gains",
    "projection_box",
    "continuation_scale",
    "validation_scenarios",
    "make_validation",
    "engine",
]


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
    box = cfg.get("options", {}).get("projection", [])
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


def train_solver(train: dict) -> sj.SolverOptions:
    """The solver options of the training runs, from the config's [train] table:
    fixed (Tsit5 on a grid of `dt` s) or adaptive (`rtol`, `atol`, `max_steps`);
    `checkpoints` (0: the solver's default) either way."""
    checkpoints = int(train["checkpoints"]) or None
    if str(train["solver"]) == "adaptive":
        return sj.SolverOptions(
            "adaptive",
            rtol=float(train["rtol"]),
            atol=float(train["atol"]),
            max_steps=int(train["max_steps"]),
            checkpoints=checkpoints,
        )
    return sj.SolverOptions("fixed", dt=float(train["dt"]), checkpoints=checkpoints)


def build(cfg) -> Problem:
    init = initial_gains(cfg)
    controller_cls = CONTROLLERS[cfg["controller"]]
    space = GainSpace.build(
        init,
        list(cfg["gains"]["freeze"]),
        dict(cfg["gains"]["bounds"]),
        float(cfg["gains"].get("beta_abs_min", 0.0)),
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
        adaptation=cfg.get("adaptation", "oracle"),  # (avr-pss: none)
        train_t_end=float(t["t_end"]),
        train_solver=train_solver(t),
        input_smoothing=float(t["input_smoothing"]),
        tail_weight=float(lw["tail_weight"]),
        cvar_q=float(lw["cvar_q"]),
        val_t_end=float(cfg["validation"]["t_end"]),
        controller=cfg["controller"],
        projection=box,
        phi_layer=float(cfg.get("options", {}).get("phi_layer", 0.0)),
        train_phi_layer=float(t["phi_layer"]),
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


_ENGINES: dict[str, tuple] = {}


def engine(cfg: dict, setup: Setup):
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
    _, validate_fn = engine(cfg, problem.setup)
    val = validation_scenarios(cfg, problem)

    def validate(raw):
        m = validate_fn(problem.space.to_gains(raw), val)
        m = jax.tree_util.tree_map(np.asarray, m)
        return summarize(m), m

    return validate
