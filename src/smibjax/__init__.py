"""smibjax: a differentiable simulator of a single-machine-infinite-bus power system
with a static var compensator under adaptive (finite-time) synergetic control.

Importing smibjax changes nothing in your process: it sets no JAX option, no
environment variable and no matplotlib backend, and it loads its modules (and JAX)
only when a name is first used. smibjax needs JAX's 64-bit mode (the closed loop is
stiff and the finite-time law works near phi = 0, where float32 is not enough); set
it before you create any array:

    import jax
    jax.config.update("jax_enable_x64", True)
    import smibjax as sj

`sj.simulate` refuses to run without it. The command line and the tuner set it, and
more, themselves (`smibjax.cli.process.configure_process`).
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING

__version__ = "0.1.0"

# public name -> the module that defines it
_EXPORTS = {
    "ClosedLoop": "closed_loop",
    "closed_loop_vector_field": "closed_loop",
    "initial_state": "closed_loop",
    "adaptation_rate": "controllers.synergetic",
    "control_law": "controllers.synergetic",
    "drift_and_gain": "controllers.synergetic",
    "drift_and_gain_closed_form": "controllers.synergetic",
    "paper_coordinates": "controllers.synergetic",
    "spow": "controllers.synergetic",
    "Metrics": "metrics",
    "metrics": "metrics",
    "Stage": "network",
    "fault_stage": "network",
    "stage_at": "network",
    "FAULT_NAMES": "parameters",
    "GAIN_NAMES": "controllers.synergetic",
    "PLANT_NAMES": "parameters",
    "Fault": "parameters",
    "Gains": "controllers.synergetic",
    "InitialEstimates": "parameters",
    "OperatingPoint": "parameters",
    "ParameterError": "parameters",
    "Plant": "parameters",
    "electrical_power": "plant",
    "plant_vector_field": "plant",
    "terminal_voltage": "plant",
    "Trajectory": "simulate",
    "simulate": "simulate",
    "Engine": "batch",
    "Scenarios": "batch",
    "Outcome": "batch",
}

if TYPE_CHECKING:  # for type checkers and documentation tools
    from .batch import Engine, Outcome, Scenarios
    from .closed_loop import ClosedLoop, closed_loop_vector_field, initial_state
    from .controller import (
        adaptation_rate,
        control_law,
        drift_and_gain,
        drift_and_gain_closed_form,
        paper_coordinates,
        spow,
    )
    from .metrics import Metrics, metrics
    from .network import Stage, fault_stage, stage_at
    from .parameters import (
        FAULT_NAMES,
        GAIN_NAMES,
        PLANT_NAMES,
        Fault,
        Gains,
        InitialEstimates,
        OperatingPoint,
        ParameterError,
        Plant,
    )
    from .plant import electrical_power, plant_vector_field, terminal_voltage
    from .simulate import Trajectory, simulate


def __getattr__(name: str):
    """Load a public name (or a submodule, `sj.controllers`) on first use."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    try:
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as e:
        if e.name != f"{__name__}.{name}":
            raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])


class _Package(types.ModuleType):
    """The package module. When a submodule loads, the import system binds it as an
    attribute of its package; where a public function has the submodule's name
    (`smibjax.simulate`, `smibjax.metrics`), the function is bound instead, so that
    `sj.simulate(...)` works whichever was loaded first."""

    def __setattr__(self, name, value):
        if isinstance(value, types.ModuleType) and _EXPORTS.get(name) == name:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


__all__ = sorted(_EXPORTS)
