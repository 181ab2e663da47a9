"""Trainable gains: unconstrained raw parameters <-> legal `Gains`.

| gain | raw parameter | why |
|---|---|---|
| beta1, beta2 | asinh(kappa_i), kappa_i = 1/beta_i | free in sign: the manifold's
|  |  | dynamics depend on kappa = 1/beta1 + 1/beta2 (stable iff kappa < 0), so gradient
|  |  | descent moves kappa through 0 (beta through +-inf, where the control law is
|  |  | continuous) from the paper's beta = 50 (kappa = 0.02) to the stable side; asinh
|  |  | is linear near 0 and logarithmic for the large |kappa| of fast gains |
| T1, T2, gamma1, gamma2 | log(value) | > 0 |
| k1, k2 | inverse softplus | >= 0 |
| alpha | logit((alpha - 1/2) / (1/2)) | in (1/2, 1) (alpha = 1 is frozen) |

A bounded gain [lo, hi] is a sigmoid of its raw parameter between the transformed bounds;
a frozen gain is not trained.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import jax
import jax.numpy as jnp

from smibjax import GAIN_NAMES, Gains, ParameterError
from smibjax.controllers.synergetic import GAIN_KINDS

KIND = dict(GAIN_KINDS)  # the paper's gains (c1, c2: weighted macro-variables)
_KAPPA_MIN = 1e-12


def _fwd(kind, v):
    """value -> transformed coordinate (before any bound squashing)."""
    if kind == "inverse":
        return math.asinh(1.0 / v)
    if kind == "log":
        return math.log(v)
    if kind == "softplus":
        return v  # linear coordinate; squashed below
    return (v - 0.5) / 0.5  # alpha: fraction of (1/2, 1]


def _inv(kind, c):
    """transformed coordinate -> value (jnp)."""
    if kind == "inverse":
        k = jnp.sinh(c)
        k = jnp.where(jnp.abs(k) < _KAPPA_MIN, jnp.where(k < 0, -1, 1) * _KAPPA_MIN, k)
        return 1.0 / k
    if kind == "log":
        return jnp.exp(c)
    if kind == "softplus":
        return c
    return 0.5 + 0.5 * c


@dataclasses.dataclass(frozen=True)
class GainSpace:
    """Which gains train, their bounds (in gain units) and the frozen values."""

    trainable: tuple[str, ...]
    frozen: dict[str, float]
    bounds: dict[str, tuple[float, float]]
    beta_abs_min: float = 0.0
    kinds: dict[str, str] = dataclasses.field(default_factory=lambda: dict(KIND))
    make: Callable = Gains  # the parameter set's class (fields = parameter names)

    @classmethod
    def build(
        cls,
        init: dict[str, float],
        freeze=(),
        bounds=None,
        beta_abs_min: float = 0.0,
        kinds: dict[str, str] | None = None,
        make: Callable = Gains,
    ) -> GainSpace:
        """`beta_abs_min` > 0 keeps |beta_i| >= it (kappa_i in [-1/it, 1/it]) while
        leaving beta free to change sign through +-inf. `kinds` (parameter name ->
        transform, default the paper's gains) and `make` (their parameter set)
        describe another controller's parameters (`parameter_kinds()`)."""
        kinds = dict(KIND if kinds is None else kinds)
        names = tuple(kinds)
        bounds = {k: (float(v[0]), float(v[1])) for k, v in (bounds or {}).items()}
        for name in [n for n in names if kinds[n] == "inverse"]:
            if beta_abs_min > 0 and abs(init[name]) < beta_abs_min:
                raise ParameterError(
                    f"{name} = {init[name]:g} is not allowed with beta_abs_min = "
                    f"{beta_abs_min:g}: |{name}| must be >= it"
                )
        for name in list(freeze) + list(bounds):
            if name not in names:
                raise ParameterError(
                    f"unknown gain {name!r}: allowed are {', '.join(names)}"
                )
        for name, (lo, hi) in bounds.items():
            v = init[name]
            if not lo < hi:
                raise ParameterError(f"bound {name} = [{lo:g}, {hi:g}] is empty")
            if not lo <= v <= hi:
                raise ParameterError(
                    f"bound {name} = [{lo:g}, {hi:g}] is not allowed: it excludes the "
                    f"initial value {name} = {v:g}"
                )
            kind = kinds[name]
            if kind == "inverse" and lo < 0 < hi:
                raise ParameterError(
                    f"bound {name} = [{lo:g}, {hi:g}] is not allowed: a beta bound "
                    "must not contain 0 (leave beta unbounded to let it change sign)"
                )
            if kind == "log" and lo <= 0:
                raise ParameterError(f"bound {name} = [{lo:g}, {hi:g}]: must be > 0")
            if kind == "softplus" and lo < 0:
                raise ParameterError(f"bound {name} = [{lo:g}, {hi:g}]: must be >= 0")
            if kind == "alpha" and not (0.5 < lo and hi <= 1):
                raise ParameterError(
                    f"bound {name} = [{lo:g}, {hi:g}]: must lie in (1/2, 1]"
                )
        frozen_names = set(freeze) | {
            n for n in names if kinds[n] == "alpha" and init[n] >= 1.0
        }
        trainable = tuple(n for n in names if n not in frozen_names)
        frozen = {n: float(init[n]) for n in names if n in frozen_names}
        return cls(trainable, frozen, bounds, float(beta_abs_min), kinds, make)

    def _interval(self, name):
        """Bounds in the transformed coordinate, or None."""
        if name not in self.bounds:
            if self.kinds[name] == "inverse" and self.beta_abs_min > 0:
                r = math.asinh(1.0 / self.beta_abs_min)
                return (-r, r)
            return None
        kind = self.kinds[name]
        a, b = (_fwd(kind, x) for x in self.bounds[name])
        return (min(a, b), max(a, b))

    def to_raw(self, values: dict[str, float]) -> dict[str, jax.Array]:
        """Raw (unconstrained) parameters of the trainable gains."""
        raw = {}
        for name in self.trainable:
            kind = self.kinds[name]
            c = _fwd(kind, float(values[name]))
            iv = self._interval(name)
            if iv is not None:
                p = (c - iv[0]) / (iv[1] - iv[0])
                p = min(max(p, 1e-9), 1 - 1e-9)
                r = math.log(p / (1 - p))
            elif kind == "softplus":
                r = math.log(math.expm1(max(c, 1e-9)))
            elif kind == "alpha":
                p = min(max((c - 1e-6) / (1 - 2e-6), 1e-12), 1 - 1e-12)
                r = math.log(p / (1 - p))
            else:
                r = c
            raw[name] = jnp.asarray(r, dtype=float)
        return raw

    def to_gains(self, raw: dict[str, jax.Array]):
        """The legal parameter set (`Gains` for the paper's law) from raw parameters
        (jittable, differentiable)."""
        vals = {}
        for name in self.trainable:
            kind, r = self.kinds[name], raw[name]
            iv = self._interval(name)
            if iv is not None:
                c = iv[0] + (iv[1] - iv[0]) * jax.nn.sigmoid(r)
            elif kind == "softplus":
                c = jax.nn.softplus(r)
            elif kind == "alpha":  # keep clear of the open end alpha = 1/2
                c = 1e-6 + (1 - 2e-6) * jax.nn.sigmoid(r)
            else:
                c = r
            vals[name] = _inv(kind, c)
        vals.update(self.frozen)
        return self.make(**vals)


def gains_to_dict(g, names: tuple[str, ...] = GAIN_NAMES) -> dict[str, float]:
    """A parameter set's values as plain floats (the gains.json layout)."""
    return {n: float(getattr(g, n)) for n in names}
