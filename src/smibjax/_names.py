"""Names the command lines offer before any computation (choices in `--help`), in a
module that imports neither JAX nor equinox, so that `python -m smibjax ... --help`
answers without loading them. The registries they name (`controllers.CONTROLLERS`,
`_parameters.PRESETS`) are checked against them (tests/test_cli.py)."""

from __future__ import annotations

__all__ = ["CONTROLLER_NAMES", "PRESETS"]

# the controller registry's names, in its order (smibjax.controllers.CONTROLLERS)
CONTROLLER_NAMES: tuple[str, ...] = ("aftsc", "asc", "none", "avr-pss")

# plant presets: the input limits (pu) each sets on top of the paper's plant
PRESETS: dict[str, dict[str, float]] = {
    "paper": {},
    "realistic": {"uf_min": -5.0, "uf_max": 5.0, "ur_min": -1.0, "ur_max": 1.0},
}
