"""Gains files that carry their context: the one place of the schema.

A gains file written by the tuner (schema `smibjax.gains/1`, JSON or TOML) holds
the gains beside what they were tuned for:

    {
      "schema": "smibjax.gains/1",
      "controller": "aftsc",                 # one of KNOWN_CONTROLLERS
      "adaptation": "realizable",            # one of KNOWN_ADAPTATIONS
      "plant": {"preset": "realistic",       # a key of parameters.PRESETS, then any
                "uf_min": -5, "uf_max": 5,   #   Plant fields that override it (the
                "ur_min": -1, "ur_max": 1},  #   limits: null = no limit)
      "options": {},                         # the controller's options (OPTION_CHECKS)
      "gains": {"beta1": -1.0, ...}          # parameter name -> number
    }

The old format, a flat table of gain name -> number, still loads
(`smibjax._files.read_gains_file`) as `legacy(gains)`, with the paper's context
(controller by alpha: aftsc if alpha < 1, asc if alpha = 1; oracle adaptation; paper
preset). `resolve` settles each context
entry as: the command-line flag if given, else the file, else the paper's default,
and returns the warnings and notes for the caller to print.

This module holds the schema (validation, the context and its resolution); it never
reads, writes or prints: `smibjax._files` reads and writes gains files.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from ._parameters import PLANT_NAMES, PRESETS, ParameterError
from .controllers import CONTROLLERS, controller_parameter_names

__all__ = [
    "SCHEMA",
    "KNOWN_CONTROLLERS",
    "KNOWN_ADAPTATIONS",
    "OPTION_CHECKS",
    "GainsFile",
    "Context",
    "legacy",
    "validate",
    "resolve",
    "is_schema_table",
]

SCHEMA = "smibjax.gains/1"
KNOWN_SCHEMAS = (SCHEMA,)
# Controllers a gains file may name: the registry (smibjax.controllers.CONTROLLERS).
KNOWN_CONTROLLERS: tuple[str, ...] = tuple(CONTROLLERS)
KNOWN_ADAPTATIONS: tuple[str, ...] = ("oracle", "realizable")
DEFAULTS = {"controller": "aftsc", "adaptation": "oracle", "preset": "paper"}
# Plant input limits and their "no limit" values (null in a file).
_LIMITS = {
    "uf_min": -math.inf,
    "uf_max": math.inf,
    "ur_min": -math.inf,
    "ur_max": math.inf,
}


# controller -> hook(controller, options) -> validated options (raises ParameterError
# with one line): the controller's `check_options`.
OPTION_CHECKS: dict[str, Callable[[str, dict], dict]] = {
    name: cls.check_options for name, cls in CONTROLLERS.items()
}


@dataclasses.dataclass(frozen=True)
class GainsFile:
    """The content of a gains file. `plant` is {"preset": name, field: value, ...}
    (values in pu; inf for no limit); `gains` maps parameter names to numbers;
    `legacy`: read from a flat table (the context is the paper's default)."""

    controller: str
    adaptation: str
    plant: dict
    options: dict
    gains: dict
    schema: str = SCHEMA
    legacy: bool = False

    def to_dict(self) -> dict:
        """The JSON layout of the schema (an infinite limit written as null: no
        limit)."""
        plant = {
            k: None if isinstance(v, float) and math.isinf(v) else v
            for k, v in self.plant.items()
        }
        out = {"schema": self.schema, "controller": self.controller}
        if _has_adaptation(self.controller):  # (none, avr-pss have no adaptation)
            out["adaptation"] = self.adaptation
        out.update(
            plant=plant,
            options=dict(self.options),
            gains={k: float(v) for k, v in self.gains.items()},
        )
        return out


@dataclasses.dataclass(frozen=True)
class Context:
    """What a gain set runs under, resolved from flags, file and defaults: the
    controller name, the adaptation mode, the plant preset and the plant overrides
    (Plant field -> value) of the file, and the controller's options."""

    controller: str
    adaptation: str
    preset: str
    plant: dict
    options: dict

    def describe(self) -> dict:
        """{"controller", "adaptation", "plant": {"preset", overrides...}, "options"}
        for tables and files (infinite limits written as None)."""
        plant = {"preset": self.preset}
        plant.update({k: None if math.isinf(v) else v for k, v in self.plant.items()})
        out = {"controller": self.controller}
        if _has_adaptation(self.controller):
            out["adaptation"] = self.adaptation
        out.update(plant=plant, options=dict(self.options))
        return out


def _has_adaptation(controller: str) -> bool:
    """True for a controller with an adaptation mode (the paper's law: aftsc, asc);
    a gains file or summary of another records none."""
    cls = CONTROLLERS.get(controller)
    return cls is not None and cls.has_adaptation


def _where(path) -> str:
    return f" in {str(path)!r}" if path is not None else ""


def _number(name: str, v, path) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParameterError(
            f"{name} = {v!r}{_where(path)} is not allowed: must be a number"
        )
    return float(v)


def is_schema_table(data) -> bool:
    """True when `data` (a parsed file) is a schema gains file, not a flat table."""
    return isinstance(data, dict) and "schema" in data


def validate(data: dict, path=None) -> GainsFile:
    """A `GainsFile` from a parsed schema table; one-line `ParameterError` naming the
    value and what is allowed for an unknown schema version, controller, adaptation
    mode, preset, plant field, gain or option, or a missing or non-numeric entry."""
    where = _where(path)
    schema = data.get("schema")
    if schema not in KNOWN_SCHEMAS:
        raise ParameterError(
            f"schema = {schema!r}{where} is not allowed: this version reads "
            f"{', '.join(KNOWN_SCHEMAS)}"
        )
    allowed = ("schema", "controller", "adaptation", "plant", "options", "gains")
    for key in data:
        if key not in allowed:
            raise ParameterError(
                f"unknown key {key!r}{where}: allowed are {', '.join(allowed)}"
            )
    for key in ("controller", "gains"):
        if key not in data:
            raise ParameterError(f"{key!r} is missing{where} (schema {schema})")
    controller = data["controller"]
    if controller not in KNOWN_CONTROLLERS:
        raise ParameterError(
            f"controller = {controller!r}{where} is not allowed: must be one of "
            f"{', '.join(KNOWN_CONTROLLERS)}"
        )
    if _has_adaptation(controller) and "adaptation" not in data:
        raise ParameterError(f"'adaptation' is missing{where} (schema {schema})")
    # a controller without adaptation (none, avr-pss): an entry (written by older
    # versions) is read and ignored
    adaptation = data.get("adaptation", DEFAULTS["adaptation"])
    if adaptation not in KNOWN_ADAPTATIONS:
        raise ParameterError(
            f"adaptation = {adaptation!r}{where} is not allowed: must be one of "
            f"{', '.join(KNOWN_ADAPTATIONS)}"
        )
    plant_in = data.get("plant", {"preset": DEFAULTS["preset"]})
    if not isinstance(plant_in, dict):
        raise ParameterError(f"plant{where} must be a table")
    preset = plant_in.get("preset", DEFAULTS["preset"])
    if not isinstance(preset, str) or preset not in PRESETS:
        raise ParameterError(
            f"plant preset = {preset!r}{where} is not allowed: must be one of "
            f"{', '.join(PRESETS)}"
        )
    plant = {"preset": preset}
    for k, v in plant_in.items():
        if k == "preset":
            continue
        if k not in PLANT_NAMES:
            raise ParameterError(
                f"unknown plant field {k!r}{where}: allowed are preset, "
                f"{', '.join(PLANT_NAMES)}"
            )
        plant[k] = _LIMITS[k] if v is None and k in _LIMITS else _number(k, v, path)
    options = data.get("options", {})
    if not isinstance(options, dict):
        raise ParameterError(f"options{where} must be a table")
    options = OPTION_CHECKS[controller](controller, options)
    gains_in = data["gains"]
    if not isinstance(gains_in, dict):
        raise ParameterError(f"gains{where} must be a table of name = number")
    gains = {}
    names = controller_parameter_names(controller)
    for k, v in gains_in.items():
        if k not in names:
            raise ParameterError(
                f"{k!r}{where} is not a parameter of controller {controller!r}: "
                f"allowed are {', '.join(names) or '(none)'}"
            )
        gains[k] = _number(k, v, path)
    _check_alpha(controller, gains, path)
    return GainsFile(controller, adaptation, plant, options, gains, schema)


def _check_alpha(controller: str, gains: dict, path) -> None:
    """aftsc needs alpha < 1, asc alpha = 1 (docs/model.md section 2)."""
    alpha = gains.get("alpha")
    if alpha is None:
        return
    if controller == "asc" and alpha != 1.0:
        raise ParameterError(
            f"alpha = {alpha:g}{_where(path)} is not allowed for controller 'asc': "
            "must be 1 (alpha < 1 is aftsc)"
        )
    if controller == "aftsc" and alpha == 1.0:
        raise ParameterError(
            f"alpha = 1{_where(path)} is not allowed for controller 'aftsc': must be "
            "< 1 (alpha = 1 is asc)"
        )


def legacy(gains: dict) -> GainsFile:
    """A flat table of gains as a gains file with the paper's context: aftsc unless
    alpha = 1 (asc), oracle adaptation, paper preset."""
    controller = "asc" if gains.get("alpha") == 1.0 else "aftsc"
    return GainsFile(
        controller,
        DEFAULTS["adaptation"],
        {"preset": DEFAULTS["preset"]},
        {},
        dict(gains),
        legacy=True,
    )


def check_complete(gf: GainsFile, path=None) -> None:
    """For batch studies: the paper's law needs every gain but c1, c2 (1: the
    paper's form)."""
    required = CONTROLLERS[gf.controller].required_parameters()
    missing = [g for g in required if g not in gf.gains]
    if missing:
        raise ParameterError(
            f"gain {missing[0]!r} is missing"
            + (f" from {str(path)!r}" if path is not None else "")
            + f": a gain set needs all of {', '.join(required)}"
        )


def resolve(
    gf: GainsFile | None,
    controller: str | None = None,
    adaptation: str | None = None,
    preset: str | None = None,
    source: str = "the gains file",
) -> tuple[Context, dict, list[str]]:
    """(context, gains, messages): each context entry is the flag (`controller`,
    `adaptation`, `preset`; None = not given) if given, else the file's, else the
    paper's default. A flag that contradicts the file wins and adds a one-line
    warning naming both values; where the controller flag wins, the file's alpha is
    dropped (the controller sets it). A legacy flat file adds a note naming the
    defaults assumed (a flag replaces an assumed default silently; only its alpha,
    if any, is a stated controller). `gains` are the file's gain values to apply."""
    messages: list[str] = []
    if gf is None:
        ctx = Context(
            controller or DEFAULTS["controller"],
            adaptation or DEFAULTS["adaptation"],
            preset or DEFAULTS["preset"],
            {},
            {},
        )
        return ctx, {}, messages
    file_preset = gf.plant.get("preset", DEFAULTS["preset"])
    flags = {"controller": controller, "adaptation": adaptation, "preset": preset}
    given = {"controller": gf.controller, "adaptation": gf.adaptation}
    given["preset"] = file_preset
    if gf.legacy:
        assumed = [f"{k} {given[k]}" for k in given if flags[k] is None]
        if assumed:
            messages.append(
                f"note: {source} is a flat table of gains (no context): assuming "
                + ", ".join(assumed)
                + " (the paper's defaults; controller by alpha)"
            )
    # a flat file states no context, only alpha (which names the controller)
    stated = {"controller", "adaptation", "preset"}
    if gf.legacy:
        stated = {"controller"} if "alpha" in gf.gains else set()
    if not _has_adaptation(gf.controller):
        stated.discard("adaptation")  # (none, avr-pss: no adaptation to override)
    if controller is not None and controller != gf.controller:
        foreign = [
            g
            for g in gf.gains
            if g != "alpha" and g not in controller_parameter_names(controller)
        ]
        if foreign:
            raise ParameterError(
                f"--controller {controller} cannot run the gains of {source} "
                f"(controller {gf.controller}: {', '.join(foreign)}): drop "
                f"--controller, or give a gains file of {controller}"
            )
    out = {}
    for key in ("controller", "adaptation", "preset"):
        flag = flags[key]
        if flag is not None and flag != given[key] and key in stated:
            messages.append(
                f"warning: --{key} {flag} overrides {key} {given[key]} of {source}"
            )
        out[key] = flag if flag is not None else given[key]
    gains = dict(gf.gains)
    if out["controller"] != gf.controller:
        gains.pop("alpha", None)
    plant = {}
    if out["preset"] == file_preset:
        plant = {k: v for k, v in gf.plant.items() if k != "preset"}
    options = gf.options if out["controller"] == gf.controller else {}
    ctx = Context(out["controller"], out["adaptation"], out["preset"], plant, options)
    return ctx, gains, messages
