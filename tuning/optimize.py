"""`python -m tuning.optimize`: tune the controller gains with optax over batches of
fault scenarios; checkpoints, resume, report.

    python -m tuning.optimize [--config FILE.toml] [--init paper|FILE] [--steps N]
        [--batch B] [--seed S] [--out DIR] [--resume] [--preset paper|realistic]
        [--controller aftsc|asc]
"""

from __future__ import annotations

from smibjax.parallel import use_host_devices

use_host_devices()  # one host device per core, before JAX starts its CPU backend

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import optax  # noqa: E402

import smibjax as sj  # noqa: E402
from smibjax import gainsfile  # noqa: E402
from smibjax.controllers import (  # noqa: E402
    CONTROLLERS,
    EstimateBox,
    Synergetic,
    make_controller,
)
from smibjax.io import atomic_write, read_gains, write_json, write_text  # noqa: E402
from smibjax.losses import TERM_NAMES, LossWeights  # noqa: E402
from smibjax.scenarios import ScenarioDistribution  # noqa: E402

from .config import check_config, load_config  # noqa: E402
from .params import GainSpace, gains_to_dict  # noqa: E402
from .resume import SessionClock, start_mode  # noqa: E402
from .search import cross_entropy_search, make_population_score  # noqa: E402
from .train import (  # noqa: E402
    Setup,
    draw_scenarios,
    make_train_step,
    make_validate,
    summarize,
)

CHECKPOINT = "checkpoint.pkl"


class UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(f"{message} (see `python -m tuning.optimize --help`)")


def parse_args(argv):
    p = _Parser(prog="python -m tuning.optimize", description=__doc__.splitlines()[0])
    p.add_argument("--config", help="TOML file overriding configs/default.toml")
    p.add_argument("--init", help="'paper' or a gains file (JSON/TOML)")
    p.add_argument("--steps", type=int, help="optimizer steps")
    p.add_argument("--batch", type=int, help="training scenarios per step")
    p.add_argument("--seed", type=int, help="seed of the training batches")
    p.add_argument("--out", help="output folder (default: a new folder under runs/)")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its last checkpoint",
    )
    p.add_argument("--preset", choices=["paper", "realistic"])
    p.add_argument("--controller", choices=[c for c in CONTROLLERS if c != "none"])
    p.add_argument("--adaptation", choices=["oracle", "realizable"])
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p.parse_args(argv)


def resolve_config(args) -> dict:
    cfg = load_config(args.config)
    for key in ("init", "steps", "batch", "seed", "preset", "controller", "adaptation"):
        v = getattr(args, key)
        if v is not None:
            cfg[key] = v
    check_config(cfg)
    return cfg


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
            from smibjax.io import read_table

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


def build(cfg):
    init = initial_gains(cfg)
    names = parameter_names(cfg)
    controller_cls = CONTROLLERS[cfg["controller"]]
    space = GainSpace.build(
        init,
        [n for n in cfg["gains"]["freeze"] if n in names or n not in sj.GAIN_NAMES],
        {k: v for k, v in cfg["gains"]["bounds"].items() if k in names},
        float(cfg["gains"]["beta_abs_min"]),
        kinds=controller_cls.parameter_kinds(),
        make=sj.Gains if controller_cls is Synergetic else controller_cls,
    )
    lw = cfg["loss"]
    weights = LossWeights(
        **{k: float(lw[k]) for k in (*TERM_NAMES, "delta_band", "Vt_band")}
    )
    synergetic = controller_cls is Synergetic
    box = projection_box(cfg) if synergetic else None
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
    return init, space, setup, dist, opt


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
    """Tune; returns the final state. `stop_after` ends early after that many steps
    of this call (used by the tests to interrupt a run)."""
    init, space, setup, dist, opt = build(cfg)
    raw0 = space.to_raw(init)
    every = int(cfg["validation"]["every"])
    steps, batch, seed = int(cfg["steps"]), int(cfg["batch"]), int(cfg["seed"])
    train_step, validate_fn = _engine(cfg, setup)
    n_val = int(cfg["validation"]["n"])
    val_faults = draw_scenarios(
        jax.random.PRNGKey(int(cfg["validation"]["seed"])), n_val, dist, setup.plant
    )

    def validate(raw):
        m = validate_fn(space.to_gains(raw), val_faults)
        m = jax.tree_util.tree_map(np.asarray, m)
        return summarize(m), m

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
        loss, per, terms, stable, grads, dropped = train_step(
            state["raw"], scenarios, scale
        )
        updates, opt_state = opt.update(grads, state["opt_state"], state["raw"])
        raw = optax.apply_updates(state["raw"], updates)
        gnorm = float(
            jnp.sqrt(sum(jnp.sum(g**2) for g in jax.tree_util.tree_leaves(grads)))
        )
        row = {
            "step": step + 1,
            "loss": float(loss),
            "limit_scale": scale,
            "train_stable_fraction": float(np.mean(np.asarray(stable))),
            **{f"term_{k}": float(np.mean(np.asarray(terms[k]))) for k in TERM_NAMES},
            "grad_norm": gnorm,
            "dropped": dropped,
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
                loss=f"{float(loss):.3f}",
                val_stable=f"{last['stable_fraction']:.2f}",
                val_ts=f"{last['settling_delta_mean']:.2f}s",
            )
            bar.update(1)
        done_here += 1
        if stop_after is not None and done_here >= stop_after:
            break
    if bar is not None:
        bar.close()
    state["space"], state["setup"], state["init"] = space, setup, init
    state["val_faults"], state["validate"] = val_faults, validate
    return state


def _gains_file(cfg: dict, gains, names=None) -> gainsfile.GainsFile:
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
    if CONTROLLERS[controller] is Synergetic and "options" in cfg:
        # alpha = 1 is the ASC law whatever the start (a logit can round up to 1.0)
        controller = "asc" if values["alpha"] == 1.0 else controller
        options = {
            "projection": cfg["options"]["projection"],
            "phi_layer": float(cfg["options"]["phi_layer"]),
        }
    return gainsfile.GainsFile(
        controller=controller,
        adaptation=cfg["adaptation"],
        plant={"preset": cfg["preset"], **limits},
        options=options,
        gains=values,
    )


def finish(cfg: dict, out: Path, state: dict) -> None:
    """gains.json, history.csv, report.md and plots."""
    from .report import write_report

    names = tuple(state["space"].kinds)
    gains = state["space"].to_gains(state["best"]["raw"])
    gainsfile.write(out / "gains.json", _gains_file(cfg, gains, names))
    last = state["space"].to_gains(state["raw"])
    gainsfile.write(out / "gains_last.json", _gains_file(cfg, last, names))
    write_history(out, state["history"])
    write_report(cfg, out, state)


def main(argv=None) -> int:
    try:
        args = parse_args(argv)
        cfg = resolve_config(args)
        if args.out:
            out = Path(args.out)
        else:
            stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
            out = Path("runs") / f"tune-{stamp}"
        if args.resume and not args.out:
            raise UsageError("--resume needs --out DIR (the run to continue)")
        resume = start_mode(out, cfg, args.resume, CHECKPOINT)  # tuning/resume.py
        sj.enable_compilation_cache()
        build(cfg)  # validate gains, bounds, scenarios before any work
        out.mkdir(parents=True, exist_ok=True)
        if not resume:
            write_json(out / "config.json", cfg)
        clock, t0 = SessionClock(out, args.resume), time.perf_counter()
        state = run(cfg, out, resume=resume, quiet=args.quiet)
        total, state["wall_sessions"] = clock.finish(time.perf_counter() - t0)
        state["wall_seconds"] = total  # all sessions of the run
        finish(cfg, out, state)
        print(
            f"wrote {out}/gains.json, report.md, history.csv and plots "
            f"({state['wall_seconds']:.0f} s)"
        )
        return 0
    except (UsageError, sj.ParameterError) as e:
        print(f"tuning.optimize: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"tuning.optimize: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\ntuning.optimize: interrupted; continue with --resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
