"""What a tuning run writes: gains.json and gains_last.json (gains files with what
they were tuned for), history.csv, and the report with its plots (`tuning.report`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import smibjax as sj
from smibjax import GainsFile
from smibjax._files import write_gains_file, write_text
from smibjax.controllers import CONTROLLERS

from .params import gains_to_dict
from .problem import build, make_validation, parameter_names, validation_scenarios

__all__ = ["finish", "write_history", "gains_file"]


def write_history(out: Path, history: list[dict]) -> None:
    if not history:
        return
    cols = list(history[0])
    lines = [",".join(cols)] + [
        ",".join("" if r.get(c) is None else f"{r[c]:.10g}" for c in cols)
        for r in history
    ]
    write_text(out / "history.csv", "\n".join(lines) + "\n")


def gains_file(cfg: dict, gains, names=None) -> GainsFile:
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
        adaptation=cfg.get("adaptation", "oracle"),  # (written for aftsc/asc only)
        plant={"preset": cfg["preset"], **limits},
        options=options,
        gains=values,
    )


def finish(cfg: dict, out: Path, state) -> None:
    """gains.json, history.csv, report.md and plots."""
    from .report import write_report

    problem = build(cfg)
    space = problem.space
    names = tuple(space.kinds)
    gains = space.to_gains(state.best.raw)
    write_gains_file(out / "gains.json", gains_file(cfg, gains, names))
    last = space.to_gains(state.raw)
    write_gains_file(out / "gains_last.json", gains_file(cfg, last, names))
    write_history(out, state.history)
    write_report(
        cfg,
        out,
        state,
        problem,
        make_validation(cfg, problem),
        validation_scenarios(cfg, problem),
    )
