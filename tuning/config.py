"""Tuning configuration: `configs/default.toml` is both the defaults and the schema."""

from __future__ import annotations

import copy
import math
from pathlib import Path

from smibjax import ParameterError

CONFIG_DIR = Path(__file__).parent / "configs"
DEFAULT = CONFIG_DIR / "default.toml"

# Tables whose keys are free (gain names), checked elsewhere.
_FREE_TABLES = {("gains", "bounds"), ("search", "scenarios")}


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


# Keys of configs/default.toml that belong to the paper's law (aftsc, asc) alone: a
# controller without an adaptation mode (avr-pss) has none of them, and a config that
# sets one for it is refused.
SYNERGETIC_ONLY = (("adaptation",), ("options",), ("gains", "beta_abs_min"))

# Defaults of default.toml that belong to one controller family, replaced for the other
# controllers (before the user's config applies): the paper's law starts from gains that
# lose synchronism under the real limits (continuation), freezes its k and c gains and
# bounds its T1 for the fixed training step; the conventional AVR + PSS + SVC regulator
# keeps synchronism (no continuation), has no k or c, and its own bounds.
FAMILY_DEFAULTS = {
    "avr-pss": {
        "continuation": {"steps": 0},
        "gains": {
            "freeze": [],
            "bounds": {
                "T_A": [0.005, 0.5],  # exciter lag: T_A >> the 2 ms fixed step
                "T2": [0.005, 1.0],  # the lead-lag denominators
                "T4": [0.005, 1.0],
                "K_A": [10.0, 400.0],  # typical static-exciter range
                "vs_max": [0.02, 0.5],  # PSS output limit (pu)
            },
        },
    },
}


def controller_defaults(controller: str) -> dict:
    """configs/default.toml as it applies to `controller`: the paper's law's keys
    (`SYNERGETIC_ONLY`) removed for a controller without adaptation, and the
    family's defaults (`FAMILY_DEFAULTS`) in place of the paper's law's."""
    cfg = load_toml(DEFAULT)
    cfg["controller"] = controller
    if controller in FAMILY_DEFAULTS:
        for path in SYNERGETIC_ONLY:
            table = cfg
            for k in path[:-1]:
                table = table[k]
            table.pop(path[-1], None)
        for table, values in FAMILY_DEFAULTS[controller].items():
            cfg[table].update(copy.deepcopy(values))
    return cfg


def _refuse_foreign(over: dict, controller: str, where: str) -> None:
    """One line for a key of `over` (a config file's or the flags' table) that does
    not apply to `controller`."""
    if controller not in FAMILY_DEFAULTS:
        return
    for path in SYNERGETIC_ONLY:
        table = over
        for k in path[:-1]:
            table = table.get(k, {}) if isinstance(table, dict) else {}
        if isinstance(table, dict) and path[-1] in table:
            raise ParameterError(
                f"config key {'.'.join(path)!r}{where} does not apply to controller "
                f"{controller!r}: it belongs to the paper's law (aftsc, asc)"
            )


def load_config(
    path: str | Path | None = None,
    controller: str | None = None,
    flags: dict | None = None,
) -> dict:
    """The default configuration for the chosen controller (`controller_defaults`),
    overridden by the file at `path` (if any), then by `flags` (top-level keys set on
    the command line). The controller is `controller`, else `flags`', else the
    file's, else the default's (aftsc). A key that does not apply to that controller
    is refused in one line. A relative `init` (gains file) in the file is taken from
    the file's folder (on the command line: from the working directory)."""
    user = load_toml(path) if path is not None else {}
    init = user.get("init")
    if isinstance(init, str) and init != "paper" and not Path(init).is_absolute():
        # a gains file named in a config file: relative to the file's folder
        user["init"] = str((Path(path).resolve().parent / init).resolve())
    flags = {k: v for k, v in (flags or {}).items() if v is not None}
    chosen = (
        controller
        or flags.get("controller")
        or user.get("controller")
        or load_toml(DEFAULT)["controller"]
    )
    if isinstance(chosen, str) and chosen in FAMILY_DEFAULTS:
        _refuse_foreign(user, chosen, f" in {str(path)!r}")
        _refuse_foreign(flags, chosen, " (command line)")
    cfg = controller_defaults(chosen if isinstance(chosen, str) else "aftsc")
    cfg = _merge(cfg, user)
    cfg = _merge(cfg, flags)
    cfg["controller"] = chosen
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


def _type_name(v) -> str:
    if isinstance(v, bool):
        return "true or false"
    if isinstance(v, int):
        return "an integer"
    if isinstance(v, float):
        return "a number"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, list):
        return "a list"
    return "a table"


def _check_types(cfg: dict, schema: dict, path=()) -> None:
    """Every value has the type of its default (the schema): a bool is never a
    number, a float never an integer (`validation.n = 2.5`), a number never a
    string (`learning_rate = "0.1"`), a table never a list or a value."""
    for k, v in cfg.items():
        here = (*path, k)
        key = ".".join(here)
        if k not in schema:
            continue
        d = schema[k]
        if isinstance(d, dict):
            if not isinstance(v, dict):
                raise ParameterError(
                    f"{key} = {_short(v)} is not allowed: must be a table"
                )
            if here in _FREE_TABLES:
                continue
            _check_types(v, d, here)
            continue
        if isinstance(d, bool):
            ok = isinstance(v, bool)
        elif isinstance(d, int):
            ok = isinstance(v, int) and not isinstance(v, bool)
        elif isinstance(d, float):
            ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        elif isinstance(d, str):
            ok = isinstance(v, str)
        else:  # a list
            ok = isinstance(v, list)
        if not ok:
            raise ParameterError(
                f"{key} = {_short(v)} is not allowed: must be {_type_name(d)}"
            )


def _short(v) -> str:
    if isinstance(v, int) and not isinstance(v, bool) and abs(v) > 10**30:
        return f"<an integer of {len(str(abs(v)))} digits>"
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_range(key: str, v) -> tuple[float, float]:
    """A [lo, hi] range of two finite numbers, lo <= hi."""
    if not (isinstance(v, list) and len(v) == 2 and all(_is_num(x) for x in v)):
        raise ParameterError(
            f"{key} = {_short(v)} is not allowed: must be a range [lo, hi] of two "
            "numbers"
        )
    lo, hi = (float(x) for x in v)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ParameterError(f"{key} = {_short(v)} is not allowed: must be finite")
    return lo, hi  # an empty range (lo > hi) is named by the scenario checks


def check_config(cfg: dict) -> None:
    """One-line errors for values of the wrong type or out of range, and for
    settings that make the task meaningless (horizons before the faults, unknown
    bounded gains, a negative clip norm or settling band)."""
    from smibjax._validate import check_tree

    from .finite import check_finite

    check_tree(cfg, "the configuration")
    _check_types(cfg, load_toml(DEFAULT))
    check_finite(cfg)  # inf/NaN anywhere (issue 16)
    _check_meaning(cfg)

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
    if cfg["controller"] not in FAMILY_DEFAULTS:  # (avr-pss: no adaptation)
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
    req(
        math.isfinite(t["phi_layer"]) and t["phi_layer"] >= 0,
        "train.phi_layer",
        t["phi_layer"],
        "must be a finite number >= 0",
    )
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
    o = cfg.get("options", {"phi_layer": 0.0})
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
    from smibjax.controllers import controller_parameter_names

    names = controller_parameter_names(cfg["controller"])
    for key, given in (
        ("gains.freeze", cfg["gains"]["freeze"]),
        ("gains.bounds", list(cfg["gains"]["bounds"])),
    ):
        for n in given:
            if n not in names:
                raise ParameterError(
                    f"unknown gain {n!r} in {key} is not allowed: controller "
                    f"{cfg['controller']!r} "
                    f"has {', '.join(names)}"
                )


def _check_meaning(cfg: dict) -> None:
    """The settings that type-check but make the task meaningless."""
    from smibjax._validate import MAX_SAMPLES, require_integer, require_memory

    def req(ok, key, value, allowed):
        if not ok:
            raise ParameterError(f"{key} = {_short(value)} is not allowed: {allowed}")

    for key in ("seed",):
        require_integer(key, cfg[key], 0, 2**32 - 1)
    require_integer("validation.seed", cfg["validation"]["seed"], 0, 2**32 - 1)
    require_integer("search.seed", cfg["search"]["seed"], 0, 2**32 - 1)
    require_integer("steps", cfg["steps"], 0, 10**9)
    require_integer("batch", cfg["batch"], 1, 10**9)
    require_integer("validation.n", cfg["validation"]["n"], 1, 10**9)
    require_integer("train.max_steps", cfg["train"]["max_steps"], 1, 10**8)
    # the runs sample every 10 ms (simulate's default): a horizon of more than
    # MAX_SAMPLES samples is refused here, before its sample count overflows the
    # memory plan below
    dt_save = 0.01
    t_end_max = MAX_SAMPLES * dt_save
    for part in ("train", "validation"):
        t_end = cfg[part]["t_end"]
        req(
            0 < t_end <= t_end_max,
            f"{part}.t_end",
            t_end,
            f"must be in (0, {t_end_max:g}] s (at most {MAX_SAMPLES:g} samples of "
            "10 ms a run)",
        )
    ranges = {}
    for k, v in cfg["scenarios"].items():
        if k == "D" and v == []:  # the plant's own damping, not drawn
            continue
        ranges[k] = _check_range(f"scenarios.{k}", v)
    for k, v in cfg["search"]["scenarios"].items():
        req(
            k in cfg["scenarios"] and not (k == "D" and cfg["scenarios"][k] == []),
            f"search.scenarios.{k}",
            v,
            "names a drawn range of [scenarios] ("
            + ", ".join(n for n, r in cfg["scenarios"].items() if r != [])
            + ")",
        )
        lo, hi = _check_range(f"search.scenarios.{k}", v)
        base = ranges[k]
        req(
            base[0] <= lo <= hi <= base[1],
            f"search.scenarios.{k}",
            v,
            f"must be a range lo <= hi within scenarios.{k} = "
            f"[{base[0]:g}, {base[1]:g}]",
        )
    if "t_fault" in ranges and "clear_duration" in ranges:
        latest = ranges["t_fault"][1] + ranges["clear_duration"][1]
        for part in ("train", "validation"):
            t_end = cfg[part]["t_end"]
            req(
                t_end > latest,
                f"{part}.t_end",
                t_end,
                f"must be after the latest fault time and its clearing, {latest:g} "
                "s (the highs of scenarios.t_fault + clear_duration): every fault "
                "must happen and clear within the run",
            )
    for key in ("rtol", "atol"):
        v = cfg["train"][key]
        req(
            0 < v <= 1e-2,
            f"train.{key}",
            v,
            "must be in (0, 0.01] (looser, the solver decides the verdict)",
        )
    o = cfg["optimizer"]
    req(o["clip_norm"] > 0, "optimizer.clip_norm", o["clip_norm"], "must be > 0")
    req(
        0 <= o["final_lr_fraction"] <= 1,
        "optimizer.final_lr_fraction",
        o["final_lr_fraction"],
        "must be in [0, 1]",
    )
    lo = cfg["loss"]
    for key in ("delta_band", "Vt_band"):
        req(lo[key] > 0, f"loss.{key}", lo[key], "must be > 0")
    for key, v in lo.items():
        if key not in ("delta_band", "Vt_band", "cvar_q"):
            req(v >= 0, f"loss.{key}", v, "must be >= 0 (a weight)")
    g = cfg["gains"]
    req(
        g.get("beta_abs_min", 0.0) >= 0,
        "gains.beta_abs_min",
        g.get("beta_abs_min"),
        "must be >= 0",
    )
    req(
        all(isinstance(n, str) for n in g["freeze"]),
        "gains.freeze",
        g["freeze"],
        "must be a list of gain names",
    )
    for k, v in g["bounds"].items():  # (unknown names: check_config)
        _check_range(f"gains.bounds.{k}", v)
    proj = cfg.get("options", {}).get("projection", [])
    req(
        proj == []
        or (
            isinstance(proj, list)
            and len(proj) == 2
            and all(
                isinstance(r, list) and len(r) == 2 and all(_is_num(x) for x in r)
                for r in proj
            )
        ),
        "options.projection",
        proj,
        "must be [] or [[lo1, hi1], [lo2, hi2]] of numbers",
    )
    samples = round(cfg["train"]["t_end"] / dt_save) + 1
    require_memory(
        f"batch = {cfg['batch']}",
        cfg["batch"],
        4 * samples,  # the forward samples and the reverse pass's
        "lower batch (training scenarios per step)",
    )
    require_memory(
        f"validation.n = {cfg['validation']['n']}",
        cfg["validation"]["n"],
        round(cfg["validation"]["t_end"] / dt_save) + 1,
        "lower validation.n",
    )
