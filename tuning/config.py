"""Tuning configuration: `configs/default.toml` is both the defaults and the schema."""

from __future__ import annotations

import copy
import math
from pathlib import Path

from smibjax import ParameterError

CONFIG_DIR = Path(__file__).parent / "configs"
DEFAULT = CONFIG_DIR / "default.toml"

# Tables whose keys are free (gain names), checked elsewhere.
_FREE_TABLES = {("gains", "bounds")}


def load_toml(path: str | Path) -> dict:
    """A configuration table from a TOML file (the one reader, `smibjax._files`)."""
    from smibjax._files import read_data

    if Path(path).suffix.lower() != ".toml":
        raise ParameterError(f"config file {str(path)!r} is not allowed: must be .toml")
    data = read_data(path)
    if not isinstance(data, dict):  # pragma: no cover - a TOML document is a table
        raise ParameterError(f"config file {str(path)!r} must hold a table")
    return data


def _merge(base: dict, over: dict, path=()) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        here = (*path, k)
        if path in _FREE_TABLES:
            out[k] = v
            continue
        if k not in base:
            allowed = ", ".join(base)
            raise ParameterError(
                f"unknown config key {'.'.join(here)!r}: allowed here are {allowed}"
            )
        if isinstance(base[k], dict):
            if not isinstance(v, dict):
                raise ParameterError(f"config key {'.'.join(here)!r} must be a table")
            out[k] = _merge(base[k], v, here) if here not in _FREE_TABLES else dict(v)
        else:
            out[k] = v
    return out


def load_config(path: str | Path | None = None) -> dict:
    """The default configuration, overridden by the file at `path` (if any)."""
    cfg = load_toml(DEFAULT)
    if path is not None:
        cfg = _merge(cfg, load_toml(path))
    return cfg


CMA_MISSING = (
    "search.generations > 0 needs pycma (CMA-ES, the [search] stage): "
    'pip install -e ".[search]"'
)


def require_cma():
    """The `cma` module (pycma, the `search` extra); a `ParameterError` naming the
    extra to install if it is missing (the command line prints it as one line and
    exits with 2, before it writes anything)."""
    try:
        import cma
    except ImportError:
        raise ParameterError(CMA_MISSING) from None
    return cma


def check_config(cfg: dict) -> None:
    """One-line errors for values out of range."""
    from .finite import check_finite

    check_finite(cfg)  # inf/NaN anywhere (issue 16)

    def req(ok, key, value, allowed):
        if not ok:
            raise ParameterError(f"{key} = {value!r} is not allowed: {allowed}")

    from smibjax.controllers import CONTROLLERS

    tunable = [c for c in CONTROLLERS if c != "none"]
    req(
        cfg["controller"] in tunable,
        "controller",
        cfg["controller"],
        f"must be one of {', '.join(tunable)}",
    )
    req(
        cfg["preset"] in ("paper", "realistic"),
        "preset",
        cfg["preset"],
        "must be paper or realistic",
    )
    req(
        cfg["adaptation"] in ("oracle", "realizable"),
        "adaptation",
        cfg["adaptation"],
        "must be oracle or realizable",
    )
    for key in ("steps", "batch", "seed"):
        v = cfg[key]
        req(
            isinstance(v, int) and not isinstance(v, bool), key, v, "must be an integer"
        )
    req(cfg["steps"] >= 0, "steps", cfg["steps"], "must be >= 0")
    req(cfg["batch"] >= 1, "batch", cfg["batch"], "must be >= 1")
    v = cfg["validation"]
    req(isinstance(v["n"], int) and v["n"] >= 1, "validation.n", v["n"], "must be >= 1")
    req(
        isinstance(v["every"], int) and v["every"] >= 1,
        "validation.every",
        v["every"],
        "must be >= 1",
    )
    t = cfg["train"]
    req(t["dt"] > 0, "train.dt", t["dt"], "must be > 0")
    req(t["t_end"] > 0 and v["t_end"] > 0, "t_end", t["t_end"], "must be > 0")
    req(
        isinstance(t["checkpoints"], int) and t["checkpoints"] >= 0,
        "train.checkpoints",
        t["checkpoints"],
        "must be an integer >= 0",
    )
    tf = cfg["scenarios"].get("t_fault")
    if (
        isinstance(tf, list)
        and len(tf) == 2
        and all(isinstance(x, (int, float)) for x in tf)
    ):  # (a malformed range is reported by the scenario checks)
        req(
            t["t_end"] > tf[1],
            "train.t_end",
            t["t_end"],
            f"must be after the latest fault time (scenarios.t_fault up to {tf[1]:g} s)",
        )
    req(
        t["solver"] in ("adaptive", "fixed"),
        "train.solver",
        t["solver"],
        "must be adaptive or fixed",
    )
    for key in ("rtol", "atol"):
        req(
            isinstance(t[key], (int, float)) and math.isfinite(t[key]) and t[key] > 0,
            f"train.{key}",
            t[key],
            "must be > 0",
        )
    req(
        isinstance(t["max_steps"], int) and t["max_steps"] >= 1,
        "train.max_steps",
        t["max_steps"],
        "must be an integer >= 1",
    )
    c = cfg["continuation"]
    req(
        isinstance(c["steps"], int) and c["steps"] >= 0,
        "continuation.steps",
        c["steps"],
        "must be an integer >= 0",
    )
    req(
        isinstance(c["start"], (int, float))
        and math.isfinite(c["start"])
        and c["start"] >= 1,
        "continuation.start",
        c["start"],
        "must be a finite number >= 1",
    )
    o = cfg["options"]
    req(
        isinstance(o["phi_layer"], (int, float))
        and math.isfinite(o["phi_layer"])
        and o["phi_layer"] >= 0,
        "options.phi_layer",
        o["phi_layer"],
        "must be a finite number >= 0 (0: the exact law)",
    )
    req(
        t["input_smoothing"] >= 0,
        "train.input_smoothing",
        t["input_smoothing"],
        "must be >= 0",
    )
    sc = cfg["search"]
    for key, lo in (("generations", 0), ("population", 2), ("batch", 1)):
        v = sc[key]
        req(
            isinstance(v, int) and not isinstance(v, bool) and v >= lo,
            f"search.{key}",
            v,
            f"must be an integer >= {lo}",
        )
    req(sc["sigma"] > 0, "search.sigma", sc["sigma"], "must be > 0")
    if sc["generations"] > 0:
        require_cma()  # the stage is on: pycma must be installed (the search extra)
    o = cfg["optimizer"]
    req(
        o["learning_rate"] > 0,
        "optimizer.learning_rate",
        o["learning_rate"],
        "must be > 0",
    )
    lo = cfg["loss"]
    req(0 <= lo["cvar_q"] < 1, "loss.cvar_q", lo["cvar_q"], "must be in [0, 1)")
    req(
        isinstance(cfg["gains"]["freeze"], list),
        "gains.freeze",
        cfg["gains"]["freeze"],
        "must be a list of gain names",
    )
