"""The paper's gains: the parameter set of the adaptive synergetic law
(docs/model.md section 2), validated when built from concrete numbers."""

from __future__ import annotations

from typing import Literal

import equinox as eqx
import numpy as np

from ..._parameters import (
    ParameterError,
    Scalar,
    _f,
    _field,
    _names,
    _values,
    require,
    require_finite,
)

__all__ = ["Gains", "GAIN_NAMES", "GAIN_FIELDS"]


GAIN_FIELDS = (
    "beta1",
    "beta2",
    "T1",
    "T2",
    "alpha",
    "gamma1",
    "gamma2",
    "k1",
    "k2",
)  # the nine gains of the law: finite, whatever else a gain set carries


class Gains(eqx.Module):
    """Controller gains of the adaptive synergetic law (docs/model.md section 2).

    `alpha = r/p` in (1/2, 1]: alpha < 1 is the finite-time controller (AFTSC, paper
    alpha = 5/7), alpha = 1 the asymptotic baseline (ASC). Paper defaults; k1, k2 are
    not given in the paper and default to 1; c1 = c2 = 1 is the paper's macro-variable
    (other values weight e1 against e2 and move the manifold's speed ceiling to about
    -c_i 1/s).
    """

    beta1: Scalar = _field(50.0)  # macro-variable weight of e3 (phi1)
    beta2: Scalar = _field(50.0)  # macro-variable weight of e4 (phi2)
    T1: Scalar = _field(0.005)  # phi1 time constant (s)
    T2: Scalar = _field(1.0)  # phi2 time constant (s)
    alpha: Scalar = _field(5.0 / 7.0)  # evolution-law power r/p
    gamma1: Scalar = _field(5.0)  # adaptation gain of th1 (estimate of -D)
    gamma2: Scalar = _field(5.0)  # adaptation gain of th2 (estimate of Pm)
    k1: Scalar = _field(1.0)  # oracle term weight of th1
    k2: Scalar = _field(1.0)  # oracle term weight of th2
    # Weights of e1 in the macro-variables, phi_i = c_i e1 + e2 + beta_i e_(i+2)
    # (docs/model.md section 2, "A ceiling on the manifold's speed"): 1 is the paper's form.
    c1: Scalar = _field(1.0)
    c2: Scalar = _field(1.0)

    def __check_init__(self):
        p = _values(self)
        if p is None:
            return
        o = "Gains"
        require_finite(p, o, GAIN_FIELDS, bound=None)
        for name in ("c1", "c2"):
            v = getattr(p, name)
            require((v > 0) & np.isfinite(v), o, name, v, "must be > 0 (1: the paper)")
        for name in ("beta1", "beta2"):
            v = getattr(p, name)
            require(
                (v != 0) & np.isfinite(v), o, name, v, "must be finite and non-zero"
            )
        for name in ("T1", "T2", "gamma1", "gamma2"):
            v = getattr(p, name)
            require((v > 0) & np.isfinite(v), o, name, v, "must be > 0")
        for name in ("k1", "k2"):
            v = getattr(p, name)
            require((v >= 0) & np.isfinite(v), o, name, v, "must be >= 0")
        require(
            (p.alpha > 0.5) & (p.alpha <= 1.0),
            o,
            "alpha",
            p.alpha,
            "must be in (1/2, 1]",
        )

    @classmethod
    def paper(cls, controller: Literal["aftsc", "asc"] = "aftsc", **overrides):
        """The paper's gains for AFTSC (alpha = 5/7) or ASC (alpha = 1)."""
        if controller not in ("aftsc", "asc"):
            raise ParameterError(
                f"controller = {controller!r} is not allowed: must be 'aftsc' or 'asc'"
            )
        alpha = 5.0 / 7.0 if controller == "aftsc" else 1.0
        return cls(**{"alpha": alpha, **overrides})

    def realizable(self) -> Gains:
        """The same gains with the oracle terms removed (k1 = k2 = 0)."""
        return eqx.tree_at(lambda g: (g.k1, g.k2), self, (_f(0.0), _f(0.0)))


GAIN_NAMES: tuple[str, ...] = _names(Gains)
