"""Blocks shared by the inverter-based resource models (REGCA1, REECB1, REPCA1):
the PSS/E deadband, the non-windup PI controller, and a group's parameter columns
from dyr records. Vectorized over the device axis."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError

__all__ = ["columns", "deadband", "pi_nonwindup"]


def columns(cls, records, names, text=()) -> dict:
    """{name: float64 array over the records} for the parameter `names` of
    `records` (dicts); `text` names are skipped. A missing or non-numeric value is
    refused in one line naming the model and the parameter."""
    out = {}
    for n in names:
        if n in text:
            continue
        col = []
        for i, rec in enumerate(records):
            if n not in rec:
                raise ParameterError(f"{cls.__name__} record {i} has no {n}")
            try:
                col.append(float(rec[n]))
            except (TypeError, ValueError):
                raise ParameterError(
                    f"{cls.__name__} record {i}: {n} = {rec[n]!r} is not a number"
                ) from None
        out[n] = np.asarray(col, dtype=np.float64)
    return out


def deadband(x, lo, hi):
    """PSS/E's deadband without offset: x - hi above hi, x - lo below lo, 0 between
    (continuous)."""
    return jnp.where(x > hi, x - hi, jnp.where(x < lo, x - lo, 0.0))


def pi_nonwindup(xi, e, kp, ki, lo, hi, freeze=False):
    """The PI controller kp + ki/s with non-windup limits [lo, hi] on its output:
    returns (y, dxi/dt), y = clip(kp e + xi, lo, hi), dxi/dt = ki e, zero while the
    output is at a limit and e pushes it outwards, or while `freeze` holds."""
    u = kp * e + xi
    d = ki * e
    pinned = ((u >= hi) & (d > 0)) | ((u <= lo) & (d < 0)) | freeze
    return jnp.clip(u, lo, hi), jnp.where(pinned, 0.0, d)
