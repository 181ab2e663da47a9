"""SEXS: the simplified excitation system (PSS/E `SEXS`, CONs TA/TB, TB, K, TE,
EMIN, EMAX; ANDES `SEXS`).

    Vi  = Vref - Vt + Vs                                 error (pu)
    x1: TB dx1/dt = Vi - x1,     y1 = x1 + (TA/TB)(Vi - x1)   lead-lag (1 + s TA)/(1 + s TB)
    x2: TE dx2/dt = K y1 - x2,   Efd = x2                 K / (1 + s TE), non-windup
                                                          limits [EMIN, EMAX]

with TA = TA_TB * TB. Vt is the terminal voltage (pu, the compensated voltage of
PSS/E with no compensator), Vs the stabilizer's signal (pu), Efd the field voltage
(pu). The limits are non-windup (drawn on the K/(1 + s TE) block in PSS/E; ANDES
`LagAntiWindup`): x2 is held at EMIN or EMAX while K y1 pushes outwards. TE = 0
makes the regulator algebraic, Efd = clip(K y1, EMIN, EMAX); TB = 0 (with TA_TB
any value: TA = 0) drops the lead-lag.

At rest (`init`): Efd = Efd0, so y1 = Vi = Efd0/K and Vref = Vt0 - Vs0 + Efd0/K,
returned as `ref`.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    lag_nonwindup,
    leadlag,
    nonneg,
    ordered,
    regulated,
    require_at_rest,
    v,
)
from .base import AbstractController, f64, i64

__all__ = ["SEXS"]


class SEXS(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TA_TB: np.ndarray = eqx.field(converter=f64)  # TA/TB (-)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag time constant (s)
    K: np.ndarray = eqx.field(converter=f64)  # gain (pu/pu)
    TE: np.ndarray = eqx.field(converter=f64)  # exciter time constant (s)
    EMIN: np.ndarray = eqx.field(converter=f64)  # field voltage limits (pu)
    EMAX: np.ndarray = eqx.field(converter=f64)

    inputs = ("Vt", "Vs")
    output = "Efd"
    state_names = ("x_ll", "Efd")
    con_names = DYR_MODELS["SEXS"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TA_TB", "TB", "TE"),
                ("K", lambda o: v(o, "K") != 0, "must be nonzero"),
                ordered("EMIN", "EMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _chain(self, x, meas, ref):
        vi = ref - regulated(meas) + meas["Vs"]
        y1, dx1 = leadlag(x[0], vi, self.TA_TB * self.TB, self.TB)
        efd, dx2 = lag_nonwindup(x[1], y1, self.K, self.TE, self.EMIN, self.EMAX)
        return efd, jnp.stack([dx1, dx2])

    def init(self, y0, meas):
        require_at_rest(
            (y0 >= self.EMIN) & (y0 <= self.EMAX),
            "SEXS",
            "Efd0",
            y0,
            "the operating point's field voltage must lie within [EMIN, EMAX]",
        )
        ref = regulated(meas) - meas["Vs"] + y0 / self.K
        vi0 = (
            ref - regulated(meas) + meas["Vs"]
        )  # as rhs computes it: dx/dt = 0 exactly
        return jnp.stack([vi0, self.K * vi0]), ref

    def rhs(self, x, meas, ref):
        return self._chain(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._chain(x, meas, ref)[0]
