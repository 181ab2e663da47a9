"""Controllers of the closed loop, by name.

| name | controller | parameters |
|---|---|---|
| `aftsc` | `Synergetic`, alpha = 5/7 (the paper's AFTSC) | `Gains` |
| `asc` | `Synergetic`, alpha = 1 (the paper's ASC) | `Gains` |
| `none` | `NoControl`: E_fd0 held, u_r = 0 | none |
| `avr-pss` | `AvrPss`: static exciter + PSS + SVC voltage regulator | its fields |

Adding a controller: write one module with a subclass of `AbstractController`
(`controllers/base.py`), and register its name in `CONTROLLERS` below.
"""

from __future__ import annotations

from collections.abc import Mapping

from .._validate import ParameterError
from .avr_pss import AvrPss
from .base import AbstractController, ControllerOutput
from .none import NoControl
from .synergetic import EstimateBox, Gains, Synergetic, project

__all__ = [
    "AbstractController",
    "ControllerOutput",
    "Synergetic",
    "EstimateBox",
    "NoControl",
    "AvrPss",
    "CONTROLLERS",
    "make_controller",
    "parameter_set",
    "as_controller",
    "controller_parameter_names",
    "project",
    "describe",
]

CONTROLLERS: dict[str, type[AbstractController]] = {
    "aftsc": Synergetic,
    "asc": Synergetic,
    "none": NoControl,
    "avr-pss": AvrPss,
}


def _check_name(name: str) -> None:
    if name not in CONTROLLERS:
        raise ParameterError(
            f"controller = {name!r} is not allowed: must be one of "
            f"{', '.join(CONTROLLERS)}"
        )


def controller_parameter_names(name: str) -> tuple[str, ...]:
    """The tunable parameter names of controller `name`."""
    _check_name(name)
    return tuple(CONTROLLERS[name].parameter_kinds())


def make_controller(
    name: str,
    params: Mapping[str, float] | None = None,
    *,
    adaptation: str = "oracle",
    projection: EstimateBox | None = None,
) -> AbstractController:
    """Controller `name` with its defaults overridden by `params` (an unknown
    parameter name is a `ParameterError`). For `aftsc` / `asc` the defaults are the
    paper's gains (alpha = 5/7 or 1), `adaptation` is `oracle` or `realizable` and
    `projection` an optional `EstimateBox`; the other controllers take neither."""
    _check_name(name)
    params = dict(params or {})
    allowed = controller_parameter_names(name)
    for k in params:
        if k not in allowed:
            raise ParameterError(
                f"{k!r} is not a parameter of controller {name!r}: allowed are "
                f"{', '.join(allowed) or '(none)'}"
            )
    cls = CONTROLLERS[name]
    if cls.has_adaptation:
        if adaptation not in ("oracle", "realizable"):
            raise ParameterError(
                f"adaptation = {adaptation!r} is not allowed: must be 'oracle' or "
                "'realizable'"
            )
        gains = cls.parameter_set(name, params)
        return cls(gains, oracle=adaptation == "oracle", projection=projection)
    if projection is not None:
        raise ParameterError(
            f"a projection box is an option of aftsc/asc, not of controller {name!r}"
        )
    return cls(**params)


def parameter_set(name: str, values: Mapping[str, float] | None = None):
    """The parameter set of controller `name` with its defaults overridden by
    `values` (an unknown name is a `ParameterError`): the paper's `Gains` for
    aftsc/asc (alpha = 5/7 or 1), the controller itself otherwise."""
    _check_name(name)
    values = dict(values or {})
    allowed = controller_parameter_names(name)
    for k in values:
        if k not in allowed:
            raise ParameterError(
                f"{k!r} is not a parameter of controller {name!r}: allowed are "
                f"{', '.join(allowed) or '(none)'}"
            )
    return CONTROLLERS[name].parameter_set(name, values)


def as_controller(
    params: Gains | AbstractController,
    adaptation: str = "oracle",
    options: dict | None = None,
) -> AbstractController:
    """`params` itself if it is a controller, else the paper's law with gains
    `params`, the `adaptation` mode ("oracle" or "realizable") and the options of a
    gains file or spec (projection, phi_layer; absent: off)."""
    if isinstance(params, AbstractController):
        return params
    return Synergetic.from_parameters(params, adaptation, options)


def describe(params) -> str:
    """A one-line label of a parameter set or controller for titles and reports:
    'AFTSC: beta = (-1, -1), alpha = 0.714' for the paper's law (ASC where alpha =
    1), 'no control', 'AVR + PSS + SVC regulator'."""
    return as_controller(params).label()
