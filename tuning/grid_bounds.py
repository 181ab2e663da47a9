"""What a tuned parameter means, and so which bounds it may have (issue 48).

Every stabilizer model smibjax reads (IEEEST, ST2CUT, PSS2A, PSS2B, STAB1, STAB2A),
the exciters' gains and time constants and the SVC CSVGN1's regulator can be tuned;
each parameter has a kind:

- `time`: a time constant (s). Tuned within (0, inf): the lower bound must be > 0
  (a log transform by default). A time constant that is 0 in the case is a block
  the case does not have (a lead-lag dropped, a transducer made algebraic): a
  group name (`ST2CUT.T7`) skips those devices (listed in the report), a device
  name (`ST2CUT[5:1].T7`) is refused;
- `gain`: a gain (pu/pu). Its bounds lie on one side of 0, the side of the case's
  value, so that tuning never flips the sign of the feedback; a gain on the speed
  deviation (input code 1, and STAB1's K/T) must be >= 0, the sign that adds
  damping torque (a faster rotor raises the field), and CSVGN1's regulator gain
  K must be >= 0. A gain that is 0 in the case
  (a stabilizer switched off) may be tuned to either side: its bounds choose;
- `ratio`: a lead-lag's high-frequency gain (STAB1's T1/T3, T2/T4): >= 0;
- `upper`, `lower`: output limits, >= 0 and <= 0;
- `cutoff`: a voltage cutoff (IEEEST's, ST2CUT's VCU, VCL): >= 0;
- `coefficient`: a filter coefficient (IEEEST's A1..A6): >= 0, tuned only where the
  case's value is > 0 (a zero changes the filter's order);
- `code`: an input code, remote bus or filter order (ICS, IB, M, N): not tunable.

Models not listed here (machines, governors, SYNEX) keep the plain checks of
`grid_problem.make_space` (a bound must contain the start value).
"""

from __future__ import annotations

import math

from smibjax import ParameterError

__all__ = ["MEANING", "kind_of", "check_bounds", "default_bounds", "absent"]

_T = "time"
_G = "gain"

MEANING: dict[str, dict[str, object]] = {
    "IEEEST": {
        "ICS": "code",
        "IB": "code",
        **{f"A{k}": "coefficient" for k in range(1, 7)},
        **{f"T{k}": _T for k in range(1, 7)},
        "KS": (_G, "ICS"),
        "LSMAX": "upper",
        "LSMIN": "lower",
        "VCU": "cutoff",
        "VCL": "cutoff",
    },
    "ST2CUT": {
        **{k: "code" for k in ("ICS1", "IB1", "ICS2", "IB2")},
        "K1": (_G, "ICS1"),
        "K2": (_G, "ICS2"),
        **{f"T{k}": _T for k in range(1, 11)},
        "LSMAX": "upper",
        "LSMIN": "lower",
        "VCU": "cutoff",
        "VCL": "cutoff",
    },
    "PSS2A": {
        **{k: "code" for k in ("ICS1", "IB1", "ICS2", "IB2", "M", "N")},
        **{k: _T for k in ("TW1", "TW2", "T6", "TW3", "TW4", "T7", "T8", "T9")},
        **{f"T{k}": _T for k in range(1, 5)},
        "KS1": (_G, "ICS1"),
        "KS2": _G,
        "KS3": _G,
        "VSTMAX": "upper",
        "VSTMIN": "lower",
    },
    "STAB1": {
        "K_T": (_G, "speed"),
        "T": _T,
        "T1_T3": "ratio",
        "T3": _T,
        "T2_T4": "ratio",
        "T4": _T,
        "HLIM": "upper",
    },
    "STAB2A": {
        **{k: _G for k in ("K2", "K3", "K4", "K5")},
        **{k: _T for k in ("T2", "T3", "T5")},
        "HLIM": "upper",
    },
    "CSVGN1": {
        "K": (_G, "positive"),
        **{f"T{k}": _T for k in range(1, 6)},
    },
}
MEANING["PSS2B"] = {
    **MEANING["PSS2A"],
    "T10": _T,
    "T11": _T,
    "VS1MAX": "upper",
    "VS1MIN": "lower",
    "VS2MAX": "upper",
    "VS2MIN": "lower",
}

# exciters: their gains (K...) and time constants (T...); limits, saturation and
# other constants are not tuned (one-line refusal)
_EXCITER_NOT = {"THETAP"}  # ESST3A's angle, not a time constant


def kind_of(model: str, par: str):
    """(kind, input-code field or None) of `model.par`; None for a model without a
    meaning table (its parameters keep the plain checks)."""
    from smibjax.grid.case import EXCITERS

    table = MEANING.get(model)
    if table is None and model in EXCITERS and model not in ("SYNEX",):
        if par in _EXCITER_NOT:
            return ("other", None)
        if par.startswith("K"):
            return (_G, None)
        if par.startswith("T"):
            return (_T, None)
        return ("other", None)
    if table is None:
        return None
    k = table.get(par, "other")
    return k if isinstance(k, tuple) else (k, None)


def _code(case, model: str, field: str, name: str) -> int | None:
    """The input code `field` of the device `name` (e.g. ICS1 of ST2CUT[5:1])."""
    import numpy as np

    from smibjax.grid.params import get_param, parse_name

    _, dev, _ = parse_name(name)
    ref = f"{model}[{dev}].{field}" if dev else f"{model}.{field}"
    vals = np.asarray(get_param(case, ref))
    return int(vals[0]) if len(set(vals.tolist())) == 1 else None


def absent(case, name: str, start: float) -> bool:
    """True when `name` is a time constant or filter coefficient that is 0 in the
    case: a block the case does not have."""
    from smibjax.grid.params import parse_name

    model, _, par = parse_name(name)
    k = kind_of(model, par)
    return k is not None and k[0] in (_T, "coefficient") and start == 0.0


def default_bounds(case, name: str, start: float, transform: str):
    """Bounds when the config gives none: (start/100, start*100) for a log transform
    (the same side of 0); for a linear one the half-line or line the meaning allows
    (a gain: its side of 0)."""
    from smibjax.grid.params import parse_name

    if transform == "log":
        a, b = start / 100, start * 100
        return (min(a, b), max(a, b))
    model, _, par = parse_name(name)
    k = kind_of(model, par)
    if k is None:
        return (-math.inf, math.inf)
    kind = k[0]
    if kind in ("ratio", "upper", "cutoff", "coefficient"):
        return (0.0, math.inf)
    if kind == "lower":
        return (-math.inf, 0.0)
    if kind == _G:
        sign = _gain_sign(case, name, k[1], start)
        return (0.0, math.inf) if sign > 0 else (-math.inf, 0.0)
    return (-math.inf, math.inf)


def _on_speed(case, name, code_field) -> bool:
    """True for a gain on the speed deviation (input code 1, or STAB1's)."""
    from smibjax.grid.params import parse_name

    if code_field in ("speed", "positive"):
        return code_field == "speed"
    model, _, _ = parse_name(name)
    return code_field is not None and _code(case, model, code_field, name) == 1


def _gain_sign(case, name, code_field, start) -> int:
    """+1 or -1: the side of 0 a gain's bounds must lie on (0: either)."""
    if code_field == "positive" or _on_speed(case, name, code_field):
        return 1
    return 0 if start == 0 else (1 if start > 0 else -1)


def check_bounds(case, name: str, lo: float, hi: float, start: float) -> None:
    """Refuse (one line, `ParameterError`) bounds [lo, hi] of parameter `name`
    (starting at `start`) outside what its model means."""
    from smibjax.grid.params import parse_name

    model, _, par = parse_name(name)
    k = kind_of(model, par)
    if k is None:
        return
    kind, code_field = k
    key = f"gains.bounds.{model}.{par} = [{lo:g}, {hi:g}] is not allowed"
    if kind == "code":
        raise ParameterError(
            f"gains: {name} is an input code, remote bus or filter order of {model} "
            "(the device's structure), not a tunable parameter"
        )
    if kind == "other":
        raise ParameterError(
            f"gains: {name} is not a tunable parameter of {model} (its gains, time "
            "constants and lead-lag ratios are)"
        )
    if kind in (_T, "coefficient") and start == 0.0:
        what = "time constant" if kind == _T else "filter coefficient"
        raise ParameterError(
            f"gains: {name} = 0 in the case: the {what}'s block is absent there; a "
            f"{what} is tuned only where the case has it > 0"
        )
    if kind == _T and not lo > 0:
        raise ParameterError(f"{key}: {name} is a time constant (s): lower bound > 0")
    if kind in ("ratio", "upper", "cutoff", "coefficient") and lo < 0:
        raise ParameterError(f"{key}: {name} ({kind}) must be >= 0")
    if kind == "lower" and hi > 0:
        raise ParameterError(f"{key}: {name} (a lower limit) must be <= 0")
    if kind == _G:
        sign = _gain_sign(case, name, code_field, start)
        if code_field == "positive" and lo < 0:
            raise ParameterError(
                f"{key}: {name} is the voltage regulator's gain: >= 0 (a negative "
                "gain would raise the voltage error)"
            )
        if _on_speed(case, name, code_field) and lo < 0:
            raise ParameterError(
                f"{key}: {name} is a gain on the speed deviation, which damps only "
                ">= 0 (a faster rotor must raise the field)"
            )
        if sign > 0 and lo < 0 or sign < 0 and hi > 0 or lo < 0 < hi:
            side = ">= 0" if sign > 0 else "<= 0" if sign < 0 else "on one side of 0"
            raise ParameterError(
                f"{key}: {name} is a gain of sign fixed by the case "
                f"(start {start:g}): its bounds must be {side}"
            )
