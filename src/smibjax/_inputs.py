"""The inputs of one `simulate` run made whole and checked, without the solver:
defaults filled in, the controller resolved, every known value checked.

`simulate` calls `simulate_inputs` before it solves; the command line's warm path
(`smibjax.cli._exported`) calls it too, so that a run from a stored program refuses
exactly what a traced run refuses. This module loads equinox but not diffrax.
"""

from __future__ import annotations

import equinox as eqx
import jax
import numpy as np

from ._closed_loop import require_start
from ._options import SaveOptions, SolverOptions
from ._parameters import (
    Fault,
    InitialEstimates,
    OperatingPoint,
    ParameterError,
    Plant,
)
from ._validate import (
    concrete_value,
    is_concrete,
    require_in_horizon,
    require_samples,
    require_x64,
)
from .controllers import AbstractController, Gains, as_controller

__all__ = [
    "DEFAULT_DELTA_BAND",
    "resolve_controller",
    "require_known_values",
    "simulate_inputs",
]

DEFAULT_DELTA_BAND = 0.01  # rad, docs/model.md section 4


def resolve_controller(gains, adaptation) -> AbstractController:
    """The controller to simulate: `gains` as a controller (`Gains`: the paper's law,
    oracle unless `adaptation` says otherwise), with alpha = 1 compiled as a constant
    where it is known to be 1 (ASC, concrete gains: spow(y, 1) is y)."""
    if adaptation not in (None, "oracle", "realizable"):
        raise ParameterError(
            f"adaptation = {adaptation!r} is not allowed: must be 'oracle' or "
            "'realizable'"
        )
    gains = Gains() if gains is None else gains
    controller = as_controller(gains).with_adaptation(adaptation)
    return controller.specialized()


def require_known_values(*trees) -> None:
    """Raise `ParameterError` where a parameter whose value is known (concrete, or
    the primal under `jax.grad` outside jit) is NaN: a NaN gain or plant value would
    spend the whole step budget and return NaN silently (and its gradient too)."""
    for tree in trees:
        leaves = jax.tree_util.tree_leaves_with_path(eqx.filter(tree, eqx.is_array))
        for path, leaf in leaves:
            v = concrete_value(leaf)
            if v is not None and v.dtype.kind == "f" and np.isnan(v).any():
                name = jax.tree_util.keystr(path).lstrip(".") or "value"
                raise ParameterError(
                    f"{type(tree).__name__}.{name} = nan is not allowed: must be a "
                    "number (checked before solving, also under jax.grad)"
                )


def simulate_inputs(
    gains,
    fault: Fault | None,
    plant: Plant | None,
    op: OperatingPoint | None,
    init: InitialEstimates | None,
    adaptation,
    solver: SolverOptions | None,
    save: SaveOptions | None,
):
    """(controller, fault, plant, op, init, solver, save) of a `simulate` call: the
    defaults for those given as None (the paper's AFTSC gains, fault, plant,
    operating point and initial estimates; `SolverOptions()`, `SaveOptions()`), the
    controller resolved (`resolve_controller`), and the values checked: 64-bit
    mode, the controller's initial estimates, no NaN, a starting point inside the
    model's domain, at least one sample interval, the fault inside the horizon
    (`ParameterError`, one line)."""
    require_x64()
    solver = SolverOptions() if solver is None else solver
    save = SaveOptions() if save is None else save
    controller = resolve_controller(gains, adaptation)
    fault = Fault() if fault is None else fault
    plant = Plant() if plant is None else plant
    op = OperatingPoint() if op is None else op
    init = InitialEstimates() if init is None else init
    controller.check_estimates(init)
    require_known_values(controller, fault, plant, op, init)
    require_start(plant, op)
    require_samples(save.t_end, save.dt_save)
    if is_concrete(fault.t_fault, fault.t_clear):
        require_in_horizon(fault.t_fault, fault.t_clear, save.t_end)
    return controller, fault, plant, op, init, solver, save
