"""SCRX: the bus-fed or solid-fed static exciter (PSS/E `SCRX`, CONs TA/TB, TB, K,
TE, EMIN, EMAX, CSWITCH, rc/rfd; OpenIPSL `PSSE.ES.SCRX`; ANDES reads SCRX records
as SEXS, dropping the last two CONs).

    Vi  = Vref - Vc + Vs                                  error (pu)
    x_ll: TB dx_ll/dt = Vi - x_ll,  y = x_ll + (TA/TB)(Vi - x_ll)   lead-lag
    Ex: TE dEx/dt = K y - Ex                              non-windup [EMIN, EMAX]
    Ed  = Ex Vt   (CSWITCH = 0, bus fed)  |  Ex  (CSWITCH = 1, solid fed)
    Efd = Ed                     where rc/rfd = 0 (negative field current allowed)
          Ed if XadIfd >= 0, else -rc/rfd XadIfd     where rc/rfd > 0 (crowbar)

with TA = TA/TB x TB, Vc the regulated voltage, Vt the terminal voltage and XadIfd
the field current (pu on the Xad base). The limits are non-windup (drawn on the K/(1
+ s TE) block); TE = 0 makes that block algebraic (Ex = clip(K y)), TB = 0 drops
the lead-lag. rc/rfd = 0 means an exciter that can carry negative field current
(PSS/E: "0 with negative field current capability, EX = EFD"); OpenIPSL's
negative-current logic instead outputs 0 for negative field current when rc/rfd =
0, which smibjax does not follow.

At rest (XadIfd0 >= 0): Ex0 = Efd0/Vt0 (bus fed) or Efd0, y = Ex0/K, Vref = Vc0 -
Vs0 + Ex0/K (returned as `ref`).
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

__all__ = ["SCRX"]


class SCRX(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    TA_TB: np.ndarray = eqx.field(converter=f64)  # TA/TB (-)
    TB: np.ndarray = eqx.field(converter=f64)  # lead-lag lag time constant (s)
    K: np.ndarray = eqx.field(converter=f64)  # gain (pu/pu)
    TE: np.ndarray = eqx.field(converter=f64)  # bridge time constant (s)
    EMIN: np.ndarray = eqx.field(converter=f64)  # bridge output limits (pu)
    EMAX: np.ndarray = eqx.field(converter=f64)
    CSWITCH: np.ndarray = eqx.field(converter=f64)  # 0 bus fed, 1 solid fed
    rc_rfd: np.ndarray = eqx.field(converter=f64)  # crowbar / field resistance (-)

    inputs = ("Vt", "Vs", "XadIfd")
    output = "Efd"
    state_names = ("x_ll", "Ex")
    con_names = DYR_MODELS["SCRX"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("TA_TB", "TB", "TE", "rc_rfd"),
                ("K", lambda o: v(o, "K") > 0, "must be > 0"),
                ordered("EMIN", "EMAX"),
                (
                    "CSWITCH",
                    lambda o: (v(o, "CSWITCH") == 0) | (v(o, "CSWITCH") == 1),
                    "must be 0 (bus fed) or 1 (solid fed)",
                ),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _supply(self, meas):
        return jnp.where(self.CSWITCH == 0, meas["Vt"], 1.0)

    def init(self, y0, meas):
        ex0 = y0 / self._supply(meas)
        require_at_rest(
            (ex0 >= self.EMIN)
            & (ex0 <= self.EMAX)
            & ((self.rc_rfd == 0) | (meas["XadIfd"] >= 0)),
            "SCRX",
            "Efd0",
            y0,
            "the operating point needs Efd0 (over Vt0 where bus fed) within [EMIN, "
            "EMAX] and a field current >= 0 where rc/rfd > 0",
        )
        ref = regulated(meas) - meas["Vs"] + ex0 / self.K
        vi0 = ref - regulated(meas) + meas["Vs"]  # as rhs computes it
        return jnp.stack([vi0, self.K * vi0]), ref

    def _chain(self, x, meas, ref):
        vi = ref - regulated(meas) + meas["Vs"]
        y, dll = leadlag(x[0], vi, self.TA_TB * self.TB, self.TB)
        ex, dex = lag_nonwindup(x[1], y, self.K, self.TE, self.EMIN, self.EMAX)
        ed = ex * self._supply(meas)
        crowbar = (self.rc_rfd > 0) & (meas["XadIfd"] < 0)
        efd = jnp.where(crowbar, -self.rc_rfd * meas["XadIfd"], ed)
        return efd, jnp.stack([dll, dex])

    def rhs(self, x, meas, ref):
        return self._chain(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._chain(x, meas, ref)[0]
