"""smibjax: a differentiable simulator of a single-machine-infinite-bus power system
with a static var compensator under adaptive (finite-time) synergetic control.

Importing smibjax enables JAX's 64-bit mode: the closed loop is stiff and the finite-time
law works near phi = 0, where float32 is not enough.
"""

import os

# Equinox turns runtime checks into host callbacks, and XLA's persistent compilation
# cache refuses programs with host callbacks. The only such checks in smibjax's
# compiled graphs are diffrax's argument checks (save times ordered and inside
# [t0, t1], jump times ordered), which smibjax's validated inputs always satisfy; as
# NaN-on-failure checks they compile without callbacks, so the cache can store the
# simulator (first call in a new process: seconds instead of tens of seconds). Set
# EQX_ON_ERROR yourself (before importing equinox) to choose otherwise.
os.environ.setdefault("EQX_ON_ERROR", "nan")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

from .closed_loop import ClosedLoop, closed_loop_vector_field, initial_state  # noqa: E402
from .controller import (  # noqa: E402
    adaptation_rate,
    control_law,
    drift_and_gain,
    drift_and_gain_closed_form,
    paper_coordinates,
    spow,
)
from .metrics import Metrics, metrics  # noqa: E402
from .network import Stage, fault_stage, stage_at  # noqa: E402
from .parameters import (  # noqa: E402
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
from .plant import electrical_power, plant_vector_field, terminal_voltage  # noqa: E402
from .simulate import Trajectory, simulate  # noqa: E402

__version__ = "0.1.0"


def enable_compilation_cache(path: str | None = None) -> str | None:
    """Turn on JAX's persistent compilation cache for smibjax's programs, in `path`
    (default: $SMIBJAX_CACHE_DIR, else ~/.cache/smibjax/jax; an empty
    SMIBJAX_CACHE_DIR turns it off). Programs that took >= 0.5 s to compile are kept,
    so a new process skips XLA compilation (tracing still runs). Returns the folder."""
    from pathlib import Path

    if path is None:
        path = os.environ.get(
            "SMIBJAX_CACHE_DIR", str(Path.home() / ".cache" / "smibjax" / "jax")
        )
    if path:
        jax.config.update("jax_compilation_cache_dir", str(path))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    return path or None


__all__ = [
    "enable_compilation_cache",
    "ClosedLoop",
    "Fault",
    "FAULT_NAMES",
    "GAIN_NAMES",
    "Gains",
    "InitialEstimates",
    "Metrics",
    "OperatingPoint",
    "ParameterError",
    "PLANT_NAMES",
    "Plant",
    "Stage",
    "Trajectory",
    "adaptation_rate",
    "closed_loop_vector_field",
    "control_law",
    "drift_and_gain",
    "drift_and_gain_closed_form",
    "electrical_power",
    "fault_stage",
    "initial_state",
    "metrics",
    "paper_coordinates",
    "plant_vector_field",
    "simulate",
    "spow",
    "stage_at",
    "terminal_voltage",
]
