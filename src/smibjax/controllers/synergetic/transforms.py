"""The tuner's transforms of the paper's gains (`tuning/params.py`): each gain's kind
names the map from an unconstrained raw parameter to a legal value."""

from __future__ import annotations

from .gains import GAIN_NAMES

__all__ = ["GAIN_KINDS"]

# The tuner's transforms of the synergetic gains (tuning/params.py).
GAIN_KINDS = {
    "beta1": "inverse",
    "beta2": "inverse",
    "T1": "log",
    "T2": "log",
    "alpha": "alpha",
    "gamma1": "log",
    "gamma2": "log",
    "k1": "softplus",
    "k2": "softplus",
    "c1": "log",
    "c2": "log",
}
assert tuple(GAIN_KINDS) == GAIN_NAMES
