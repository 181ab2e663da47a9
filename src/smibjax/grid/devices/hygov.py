"""HYGOV: the hydro turbine-governor (PSS/E `HYGOV`, CONs R, r, Tr, Tf, Tg, VELM,
GMAX, GMIN, TW, At, Dturb, qNL; ANDES `HYGOV`).

    e_in = nref - omega - R c                            speed error with permanent droop R
    e:   Tf de/dt = e_in - e                             filter 1/(1 + s Tf)
    c:   dc/dt = clip((e + Tr de/dt)/(r Tr), -VELM, VELM)   governor (1 + s Tr)/(r Tr s):
                                                         gate velocity limit VELM, non-windup
                                                         gate limits [GMIN, GMAX] on c
    g:   Tg dg/dt = c - g                                gate servo
    q:   TW dq/dt = 1 - h,  h = (q/g)^2                  penstock (water inertia, unit head)
    Pm = At h (q - qNL) - Dturb omega g                  turbine (pu machine base)

with omega the speed deviation (pu), c the desired gate, g the gate, q the water
flow and h the head at the turbine (pu). The velocity limit acts on the output rate
of the proportional-integral governor, as PSS/E draws it (a rate limiter before the
gate integrator, OpenIPSL's PSS/E HYGOV). Tf, Tg, TW, r, Tr must be > 0.

At rest (h = 1): q0 = Pm0/At + qNL, g0 = c0 = q0, e0 = 0 and nref = R c0 + omega0
(PSS/E's speed reference), returned as `ref`.

ANDES 2.0's HYGOV integrates the filtered error with gain 1 (dc/dt = e + (1/r)
de/dt): its integral gain is 1 where PSS/E's is 1/(r Tr), the same only when
r Tr = 1.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    lag,
    nonneg,
    nonwindup,
    ordered,
    positive,
    require_at_rest,
)
from .base import AbstractController, f64, i64

__all__ = ["HYGOV"]


class HYGOV(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    R: np.ndarray = eqx.field(converter=f64)  # permanent droop (pu/pu)
    r: np.ndarray = eqx.field(converter=f64)  # temporary droop (pu/pu)
    Tr: np.ndarray = eqx.field(converter=f64)  # governor time constant (s)
    Tf: np.ndarray = eqx.field(converter=f64)  # filter time constant (s)
    Tg: np.ndarray = eqx.field(converter=f64)  # gate servo time constant (s)
    VELM: np.ndarray = eqx.field(converter=f64)  # gate velocity limit (pu/s)
    GMAX: np.ndarray = eqx.field(converter=f64)  # gate limits (pu)
    GMIN: np.ndarray = eqx.field(converter=f64)
    TW: np.ndarray = eqx.field(converter=f64)  # water time constant (s)
    At: np.ndarray = eqx.field(converter=f64)  # turbine gain (pu/pu)
    Dturb: np.ndarray = eqx.field(converter=f64)  # turbine damping (pu/pu)
    qNL: np.ndarray = eqx.field(converter=f64)  # no-load flow (pu)

    inputs = ("omega",)
    output = "Pm"
    state_names = ("e", "c", "g", "q")
    con_names = DYR_MODELS["HYGOV"]

    def __check_init__(self):
        check(
            self,
            [
                *nonneg("R", "VELM", "Dturb", "qNL"),
                *positive("r", "Tr", "Tf", "Tg", "TW", "At"),
                ordered("GMIN", "GMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def _f(self, x, meas, ref):
        w = meas["omega"]
        e, c, g, q = x
        e_in = ref - w - self.R * c
        de = (e_in - e) / self.Tf
        rate = jnp.clip((e + self.Tr * de) / (self.r * self.Tr), -self.VELM, self.VELM)
        dc = nonwindup(c, rate, self.GMIN, self.GMAX)
        _, dg = lag(g, c, 1.0, self.Tg)
        h = (q / g) ** 2
        dq = (1.0 - h) / self.TW
        pm = self.At * h * (q - self.qNL) - self.Dturb * w * g
        return pm, jnp.stack([de, dc, dg, dq])

    def init(self, y0, meas):
        w = meas["omega"]
        # Pm0 = At (q0 - qNL) - Dturb w g0 with g0 = q0 (h = 1)
        q0 = (y0 + self.At * self.qNL) / (self.At - self.Dturb * w)
        require_at_rest(
            (q0 >= self.GMIN) & (q0 <= self.GMAX) & (q0 > 0),
            "HYGOV",
            "Pm0",
            y0,
            "the operating point's gate Pm0/At + qNL must lie within [GMIN, GMAX] "
            "and be > 0",
        )
        zero = 0.0 * q0
        ref = w + self.R * q0
        return jnp.stack([zero, q0, q0, q0]), ref

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
