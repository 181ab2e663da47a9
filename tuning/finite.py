"""Every number of a tuning configuration must be finite: an inf or NaN learning rate,
step, horizon or weight would run and report nonsense (or a traceback) instead of a
one-line refusal (a bound's end too: the tuner maps a bounded gain between its ends).
The seeds must be integers in [0, 2**32), like `smibjax montecarlo --seed`.
"""

from __future__ import annotations

import math

from smibjax import ParameterError

__all__ = ["check_finite"]


_SEEDS = (("seed",), ("validation", "seed"), ("search", "seed"))


def check_finite(cfg: dict, path: tuple[str, ...] = ()) -> None:
    """Raise `ParameterError` naming the first non-finite number in `cfg` (nested
    tables and lists included), or a seed outside [0, 2**32)."""
    if not path:
        for keys in _SEEDS:
            v = cfg
            for k in keys:
                v = v.get(k) if isinstance(v, dict) else None
            if isinstance(v, int) and not isinstance(v, bool) and not 0 <= v < 2**32:
                raise ParameterError(
                    f"{'.'.join(keys)} = {v!r} is not allowed: must be an integer in "
                    "[0, 2**32)"
                )
    items = cfg.items() if isinstance(cfg, dict) else enumerate(cfg)
    for k, v in items:
        here = (*path, str(k))
        if isinstance(v, (dict, list)):
            check_finite(v, here)
        elif isinstance(v, float) and not math.isfinite(v):
            name = ".".join(p for p in here if not p.isdigit())
            raise ParameterError(f"{name} = {v!r} is not allowed: must be finite")
