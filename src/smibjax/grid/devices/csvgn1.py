"""CSVGN1: the static var compensator (PSS/E `CSVGN1`, "static shunt compensator",
CONs K, T1, T2, T3, T4, T5, RMIN, VMAX, VMIN, CBASE), a shunt device at bus
positions `bus`.

The SVC is a fixed capacitor of CBASE MVAr beside a thyristor-controlled reactor
whose rating is the device's MBASE (MVA, the raw file's machine base of the SVC's
generator record; PSS/E wants MBASE about Qmax - Qmin and CBASE about Qmax). The
regulator drives the reactor's admittance Y (pu of MBASE):

    e   = K (V - Vref)                                  voltage error (PSS/E sums VREF
                                                        - V and negates it)
    x_1: T3 dx_1/dt = e - x_1,    y_1 = x_1 + (T1/T3)(e - x_1)     (1 + s T1)/(1 + s T3)
    x_2: T4 dx_2/dt = y_1 - x_2,  y_2 = x_2 + (T2/T4)(y_1 - x_2)   (1 + s T2)/(1 + s T4)
    r   = clip(Y0 + y_2 - u, VMIN, VMAX)                regulator output (windup: an
                                                        algebraic clip; u the command)
    Y:   T5 dY/dt = r - Y                               thyristor lag, non-windup limits
                                                        [RMIN/MBASE, 1]
    B   = (CBASE - MBASE Y) / SBASE                     net susceptance (pu system
                                                        base, capacitive positive)

The structure (the limiter VMIN/VMAX after the lead-lags, the lag 1/(1 + s T5) held
within [RMIN/MBASE, 1], B = CBASE/SBASE - (MBASE/SBASE) Y) is the PSS/E block
diagram as OpenIPSL's CSVGN1 implements it (verified there against PSS/E); ANDES
has no CSVGN1. Deviations: the lead-lag states are kept as deviations from rest
(x = 0 at rest) and the operating point's regulator output Y0 is added after
them, which is PSS/E's loop with VREF_psse = Vref - Y0/K but stays defined at K = 0;
and u, an external command (pu susceptance on MBASE, capacitive positive: it
lowers the reactor's admittance), is added to the regulator's output before the
VMIN/VMAX limiter (PSS/E's VOTHSG enters at the voltage error instead).

With K = 0 and T1 = T2 = T3 = T4 = 0 this is the paper's SVC (docs/model.md section 1)
on the device base: with Bm = CBASE/MBASE - Y, T5 dBm/dt = -(Bm - Bm0) + u inside
the limits, and with VMAX = Y0 - u_min, VMIN = Y0 - u_max the limiter is exactly
the paper's clip of u to [u_min, u_max] (`DirectSVC`): T5 dBm/dt = -(Bm - Bm0) +
clip(u, u_min, u_max).

At rest (`init`): B0 = q/|V|^2 from the power flow's reactive injection q (pu
system base), Y0 = (CBASE - B0 SBASE)/MBASE (refused outside [RMIN/MBASE, 1] or
[VMIN, VMAX]), x_1 = x_2 = 0, Vref = |V0|. `ref` is the array (2, k): row 0 Vref,
row 1 Y0. T5 must be > 0 (the susceptance is a state).
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
    ordered,
    positive,
    proper,
    require_at_rest,
)
from .base import AbstractShuntDevice, f64, i64

__all__ = ["CSVGN1"]


class CSVGN1(AbstractShuntDevice):
    bus: np.ndarray = eqx.field(converter=i64)
    K: np.ndarray = eqx.field(converter=f64)  # regulator gain (pu Y / pu V)
    T1: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 lead (s)
    T2: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 lead (s)
    T3: np.ndarray = eqx.field(converter=f64)  # lead-lag 1 lag (s)
    T4: np.ndarray = eqx.field(converter=f64)  # lead-lag 2 lag (s)
    T5: np.ndarray = eqx.field(converter=f64)  # thyristor lag (s)
    RMIN: np.ndarray = eqx.field(converter=f64)  # reactor minimum (MVAr)
    VMAX: np.ndarray = eqx.field(converter=f64)  # regulator output limits (pu MBASE)
    VMIN: np.ndarray = eqx.field(converter=f64)
    CBASE: np.ndarray = eqx.field(converter=f64)  # capacitor (MVAr)
    MBASE: np.ndarray = eqx.field(converter=f64)  # reactor rating (MVA)

    state_names = ("x_1", "x_2", "Y")
    con_names = DYR_MODELS["CSVGN1"]

    def __check_init__(self):
        check(
            self,
            [
                *positive("T5", "MBASE"),
                proper("T1", "T3"),
                proper("T2", "T4"),
                ordered("VMIN", "VMAX"),
                (
                    "RMIN",
                    lambda o: np.asarray(o.RMIN) <= np.asarray(o.MBASE),
                    "must be <= MBASE (the reactor's range is [RMIN/MBASE, 1])",
                ),
            ],
        )

    @classmethod
    def from_params(cls, bus_positions, params):
        """`params[i]` holds the CONs and MBASE (MVA, from the raw file)."""
        return build_group(
            cls, bus_positions, params, (*cls.con_names, "MBASE"), pos_field="bus"
        )

    def _ylim(self):
        return self.RMIN / self.MBASE, jnp.ones_like(self.MBASE)

    def regulator(self, x, vm, cmd, ref):
        """(r, dx_1, dx_2): the limited regulator output (pu Y on MBASE)."""
        e = self.K * (vm - ref[0])
        y1, d1 = leadlag(x[0], e, self.T1, self.T3)
        y2, d2 = leadlag(x[1], y1, self.T2, self.T4)
        return jnp.clip(ref[1] + y2 - cmd, self.VMIN, self.VMAX), d1, d2

    def susceptance(self, x, s_base):
        """B (pu on the system base `s_base` MVA, capacitive positive)."""
        lo, hi = self._ylim()
        return (self.CBASE - self.MBASE * jnp.clip(x[2], lo, hi)) / s_base

    def admittance(self, x, s_base):
        return 1j * self.susceptance(x, s_base)

    def rhs(self, x, vm, cmd, ref):
        r, d1, d2 = self.regulator(x, vm, cmd, ref)
        lo, hi = self._ylim()
        _, dy = lag_nonwindup(x[2], r, 1.0, self.T5, lo, hi)
        return jnp.stack([d1, d2, dy])

    def init(self, v, q, s_base):
        vm = jnp.abs(v)
        b0 = q / vm**2
        y0 = (self.CBASE - b0 * s_base) / self.MBASE
        lo, hi = self._ylim()
        require_at_rest(
            (y0 >= lo) & (y0 <= hi) & (y0 >= self.VMIN) & (y0 <= self.VMAX),
            "CSVGN1",
            "Y0",
            y0,
            "the operating point's reactor admittance (CBASE - B0 SBASE)/MBASE must "
            "lie within [RMIN/MBASE, 1] and [VMIN, VMAX]",
        )
        zero = 0.0 * y0
        return jnp.stack([zero, zero, y0]), jnp.stack([vm + zero, y0])
