"""The configuration of a tuning run on a multi-machine case (a `[case]` table).

A config file with a `[case]` table tunes device parameters of a grid case
(`smibjax.grid`) instead of the SMIB's controller gains; `GRID_DEFAULTS` below is both
its defaults and its schema (an unknown key is refused with the keys allowed there).
The tables (docs/tuning-grid.md has the full description):

- `[case]`: `name` (a built-in case, `smibjax.grid.case.BUILTIN`) or `raw` + `dyr`
  (PSS/E v33 files; relative paths are taken from the config file's folder);
  `set`: fixed parameter values by name that override the dyr file's;
- `[gains]`: `names`, the parameters to train (`MODEL.PARAM`: every device of the
  model, expanded to one trained value per device when `per_device`, or one value
  shared by all of them; `MODEL[BUS:ID].PARAM`: one device); `bounds` and `transform`
  (`log` or `linear`) by name, the bounds checked against the parameter's meaning
  (`tuning.grid_bounds`); `tie`: parameters that follow a trained one
  (`"IEEEST.T5" = "IEEEST.T6"`: each device's T5 equals its T6); `groups`: named
  lists of device parameters of one model trained as one value;
- `[scenarios]`: the fault distribution (`smibjax.grid.scenarios.FaultDistribution`
  fields) and `load_factor`, the range of the load (and non-slack generation) factor
  drawn per scenario; the power flow is re-solved for every scenario;
- `[train]`: the horizon and solver tolerances of the training runs;
- `[loss]`: the weights of the terms and the damping target;
- `[optimizer]`, `[validation]`, `[report]` (the reference fault of the plots).
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

from smibjax import ParameterError
from smibjax._validate import MAX_SAMPLES, MAX_STEPS

__all__ = ["GRID_DEFAULTS", "is_grid_config", "load_grid_config", "check_grid_config"]

GRID_DEFAULTS: dict = {
    "case": {"name": "", "raw": "", "dyr": "", "skip_unsupported": False, "set": {}},
    "steps": 20,
    "batch": 4,
    "seed": 0,
    "gains": {
        "names": ["IEEEST.KS"],
        "per_device": True,
        "bounds": {},
        "transform": {},
        "tie": {},
        "groups": {},
    },
    "scenarios": {
        "kind": "bus",
        "buses": [],
        "branches": [],
        "t_fault": [0.5, 0.5],
        "clear_after": [0.05, 0.1],
        "location": [0.1, 0.9],
        "reclose": [],
        "fault_r": [0.0, 0.0],
        "fault_x": [0.0, 0.0],
        "load_factor": [0.8, 1.2],
    },
    "train": {
        "t_end": 8.0,
        "dt_save": 0.05,
        "rtol": 1e-6,
        "atol": 1e-8,
        "max_steps": 20000,
    },
    "loss": {
        "settling": 1.0,
        "itae": 0.1,
        "overshoot": 1.0,
        "effort": 0.1,
        "damping": 100.0,
        "target_damping": 0.15,
        "damping_load_factors": [0.8, 1.0, 1.2],
        "damping_reduce": "max",
        "reference_every": 0,
        "unstable": 20.0,
        "band_angle": 0.01,
        "band_speed": 1e-4,
    },
    "optimizer": {"learning_rate": 0.05, "clip": 1.0},
    "validation": {
        "n": 16,
        "seed": 1000,
        "every": 5,
        "t_end": 10.0,
        "load_factors": [0.8, 1.0, 1.2],
    },
    "report": {"fault_bus": 0, "clear_after": 0.1, "load_factor": 1.0, "t_end": 10.0},
}

# tables whose keys are free (parameter names)
_FREE = {
    ("case", "set"),
    ("gains", "bounds"),
    ("gains", "transform"),
    ("gains", "tie"),
    ("gains", "groups"),
}


def is_grid_config(path) -> bool:
    """True when the TOML file at `path` has a `[case]` table (a grid tuning run)."""
    from .config import load_toml

    if path is None:
        return False
    try:
        data = load_toml(path)
    except (ParameterError, OSError, ValueError):
        return False  # the SMIB path reports it
    return isinstance(data, dict) and "case" in data


def _merge(base: dict, over: dict, path=()) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        here = (*path, k)
        if k not in base:
            raise ParameterError(
                f"unknown config key {'.'.join(here)!r}: allowed here are "
                f"{', '.join(base)}"
            )
        if isinstance(base[k], dict):
            if not isinstance(v, dict):
                raise ParameterError(f"config key {'.'.join(here)!r} must be a table")
            out[k] = dict(v) if here in _FREE else _merge(base[k], v, here)
        else:
            out[k] = v
    return out


def load_grid_config(path) -> dict:
    """`GRID_DEFAULTS` overridden by the file at `path`; the case's file paths made
    absolute (relative to the config file's folder)."""
    from .config import load_toml

    cfg = _merge(GRID_DEFAULTS, load_toml(path))
    base = Path(path).resolve().parent
    for key in ("raw", "dyr"):
        p = cfg["case"][key]
        if p and not Path(p).is_absolute():
            cfg["case"][key] = str((base / p).resolve())
    return cfg


def _req(ok, key, value, allowed):
    if not ok:
        raise ParameterError(f"{key} = {value!r} is not allowed: {allowed}")


def _num(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _range(key, v, lo=-math.inf, hi=math.inf):
    _req(
        isinstance(v, list) and len(v) == 2 and all(_num(x) for x in v),
        key,
        v,
        "must be a range [lo, hi] of two finite numbers",
    )
    _req(v[0] <= v[1], key, v, "must have lo <= hi")
    _req(lo <= v[0] and v[1] <= hi, key, v, f"must lie in [{lo:g}, {hi:g}]")


def check_grid_config(cfg: dict) -> None:
    """One-line errors (`ParameterError`) for values out of range; what needs the
    case (names, bounds against the start values, buses, power flows) is checked by
    `grid_problem.build`."""
    c = cfg["case"]
    _req(
        bool(c["name"]) != bool(c["raw"] or c["dyr"]),
        "case",
        c,
        "give either name (a built-in case) or raw and dyr (PSS/E files)",
    )
    if not c["name"]:
        _req(bool(c["raw"] and c["dyr"]), "case", c, "raw needs its dyr file")
    _req(
        isinstance(c["skip_unsupported"], bool),
        "case.skip_unsupported",
        c["skip_unsupported"],
        "must be true or false",
    )
    for name, v in c["set"].items():
        _req(_num(v), f"case.set.{name}", v, "must be a finite number")
    for key, lo in (("steps", 0), ("batch", 1)):
        v = cfg[key]
        _req(isinstance(v, int) and not isinstance(v, bool), key, v, "an integer")
        _req(v >= lo, key, v, f"must be >= {lo}")
    for key, val in (
        ("seed", cfg["seed"]),
        ("validation.seed", cfg["validation"]["seed"]),
    ):
        _req(
            isinstance(val, int) and not isinstance(val, bool) and 0 <= val < 2**32,
            key,
            val,
            "must be an integer in [0, 2^32 - 1]",
        )
    g = cfg["gains"]
    _req(
        isinstance(g["names"], list)
        and g["names"]
        and all(isinstance(n, str) for n in g["names"]),
        "gains.names",
        g["names"],
        "must be a non-empty list of MODEL.PARAM names",
    )
    _req(isinstance(g["per_device"], bool), "gains.per_device", g["per_device"], "bool")
    for name, b in g["bounds"].items():
        _range(f"gains.bounds.{name}", b)
    for name, t in g["transform"].items():
        _req(t in ("log", "linear"), f"gains.transform.{name}", t, "log or linear")
    for dst, src in g["tie"].items():
        _req(isinstance(src, str), f"gains.tie.{dst}", src, "a parameter name")
    for label, members in g.get("groups", {}).items():
        _req(
            isinstance(members, list)
            and members
            and all(isinstance(m, str) for m in members),
            f"gains.groups.{label}",
            members,
            "must be a list of parameter names (MODEL.PARAM or MODEL[BUS:ID].PARAM)",
        )
    s = cfg["scenarios"]
    _req(s["kind"] in ("bus", "line"), "scenarios.kind", s["kind"], "bus or line")
    _req(
        isinstance(s["buses"], list) and all(isinstance(b, int) for b in s["buses"]),
        "scenarios.buses",
        s["buses"],
        "must be a list of bus numbers",
    )
    for key in ("t_fault", "clear_after", "location", "fault_r", "fault_x"):
        _range(f"scenarios.{key}", s[key])
    _range("scenarios.t_fault", s["t_fault"], lo=0.0)
    _req(
        s["clear_after"][0] > 0,
        "scenarios.clear_after",
        s["clear_after"],
        "must be > 0",
    )
    if s["reclose"]:
        _range("scenarios.reclose", s["reclose"], lo=0.0)
    _range("scenarios.load_factor", s["load_factor"], lo=1e-3)
    t = cfg["train"]
    for key in ("t_end", "dt_save", "rtol", "atol"):
        _req(_num(t[key]) and t[key] > 0, f"train.{key}", t[key], "must be > 0")
    _req(
        isinstance(t["max_steps"], int) and 1 <= t["max_steps"] <= MAX_STEPS,
        "train.max_steps",
        t["max_steps"],
        f"must be an integer in [1, {MAX_STEPS:g}]",
    )
    t_last = s["t_fault"][1] + s["clear_after"][1] + (s["reclose"] or [0, 0])[1]
    v = cfg["validation"]
    for key, val in (("train.t_end", t["t_end"]), ("validation.t_end", v["t_end"])):
        _req(
            val > t_last,
            key,
            val,
            f"must be after the latest switch time ({t_last:g} s)",
        )
    lo = cfg["loss"]
    for key in (
        "settling",
        "itae",
        "overshoot",
        "effort",
        "damping",
        "unstable",
        "band_angle",
        "band_speed",
    ):
        _req(_num(lo[key]) and lo[key] >= 0, f"loss.{key}", lo[key], "must be >= 0")
    for key in ("band_angle", "band_speed"):
        _req(lo[key] > 0, f"loss.{key}", lo[key], "must be > 0")
    _req(
        _num(lo["target_damping"]) and 0 < lo["target_damping"] < 1,
        "loss.target_damping",
        lo["target_damping"],
        "must be in (0, 1)",
    )
    _req(
        lo.get("damping_reduce", "max") in ("max", "mean"),
        "loss.damping_reduce",
        lo.get("damping_reduce"),
        "max or mean (over loss.damping_load_factors)",
    )
    re_ = lo.get("reference_every", 0)
    _req(
        isinstance(re_, int)
        and not isinstance(re_, bool)
        and re_ >= 0
        and (
            re_ == 0
            or isinstance(v["every"], int)
            and v["every"] >= 1
            and v["every"] % re_ == 0
        ),
        "loss.reference_every",
        re_,
        "an integer >= 0 dividing validation.every (0: refresh the reference modes "
        "at the validations only)",
    )
    for key, lfs in (
        ("loss.damping_load_factors", lo["damping_load_factors"]),
        ("validation.load_factors", v["load_factors"]),
    ):
        _req(
            isinstance(lfs, list) and lfs and all(_num(x) and x > 0 for x in lfs),
            key,
            lfs,
            "must be a non-empty list of positive load factors",
        )
    o = cfg["optimizer"]
    for key in ("learning_rate", "clip"):
        _req(_num(o[key]) and o[key] > 0, f"optimizer.{key}", o[key], "must be > 0")
    for key in ("n", "every"):
        _req(
            isinstance(v[key], int) and v[key] >= 1,
            f"validation.{key}",
            v[key],
            "must be an integer >= 1",
        )
    r = cfg["report"]
    _req(
        _num(r["clear_after"]) and r["clear_after"] > 0,
        "report.clear_after",
        r["clear_after"],
        "must be > 0",
    )
    _req(
        _num(r["load_factor"]) and r["load_factor"] > 0,
        "report.load_factor",
        r["load_factor"],
        "must be > 0",
    )
    _req(
        _num(r["t_end"]) and r["t_end"] > 0.5 + r["clear_after"],
        "report.t_end",
        r["t_end"],
        "must be after the reference fault's clearing (0.5 s + clear_after)",
    )
    # every run samples at train.dt_save: at most MAX_SAMPLES samples a run
    dt = t["dt_save"]
    for key, val in (
        ("train.t_end", t["t_end"]),
        ("validation.t_end", v["t_end"]),
        ("report.t_end", r["t_end"]),
    ):
        _req(
            _num(val) and val / dt <= MAX_SAMPLES,
            key,
            val,
            f"must be <= {MAX_SAMPLES * dt:g} s (at most {MAX_SAMPLES:g} samples of "
            f"train.dt_save = {dt:g} s a run)",
        )
