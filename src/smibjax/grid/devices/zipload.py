"""ZIPLoad: loads as PSS/E models them in dynamic simulation, a current injector
(`AbstractInjector`, source "load") at bus positions `bus` for the loads at
positions `load` of `System.loads`.

Each load consumes, at bus voltage V (pu, magnitude v = |V|),

    S(V) = kP(v) S_P  +  kI(v) v C_I  +  v^2 conj(y_Z)               (pu, system base)

a constant power part S_P, a constant current part (its magnitude C_I at 1 pu,
current in phase with the voltage as the power factor says: P = Re C_I v, PSS/E's
IP, IQ) and a constant admittance part y_Z (a shunt of the linear network,
`admittance`). The current it injects into the network is
I = -conj(S_P kP(v) / V) - conj(C_I) kI(v) V / v.

Low-voltage treatment (PSS/E's PQBRAK for constant power, a break at `ibrak` for
constant current; docs/loads-events.md):

    kP(v) = 2 (v / b)^2                   v < b/2          (b = PQBRAK, PSS/E's
          = 1 - 2 ((v - b) / b)^2         b/2 <= v < b      default 0.7)
          = 1                             v >= b
    kI(v) = (v / c)(2 - v / c)            v < c            (c = ibrak, 0.5)
          = 1                             v >= c

kP is OpenIPSL's `characteristic = 1` of its PSS/E load (continuous with a
continuous slope; the constant power part behaves like an impedance, P ~ v^2, near
v = 0); kI makes the constant current part impedance-like (I ~ v) near v = 0 with
the same smoothness. b = 0 (c = 0) turns the treatment off: pure constant power
(current); the current magnitude then uses max(v, 1e-3) to stay finite.

`share` (6, k): the parts of the load's power-flow power s0 (consumed, -s0
injected) as fractions, rows (P_P, P_I, P_Z, Q_P, Q_I, Q_Z), each triple summing
to 1 (`init` refuses otherwise). At rest (`init`): S_P = (P_P P0 + j Q_P Q0) /
kP(v0), C_I = (P_I P0 + j Q_I Q0) / (v0 kI(v0)), y_Z = (P_Z P0 - j Q_Z Q0) / v0^2,
so the load consumes exactly P0 + j Q0 at the power-flow voltage v0. `ref` is the
complex array (3, k): rows S_P, C_I, y_Z. No states.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .base import AbstractInjector, f64, i64

__all__ = ["ZIPLoad", "k_power", "k_current"]

V_FLOOR = 1e-3  # the voltage magnitude below which the currents stop growing (pu)


def k_power(v, b):
    """PSS/E's constant-power reduction below PQBRAK = b (OpenIPSL's characteristic
    1): the factor on the constant power part at voltage magnitude v (pu)."""
    bs = jnp.where(b > 0, b, 1.0)
    x = v / bs
    low = jnp.where(x < 0.5, 2 * x**2, 1 - 2 * (x - 1) ** 2)
    return jnp.where((b > 0) & (x < 1), low, 1.0)


def k_current(v, c):
    """The constant-current reduction below c (pu): (v/c)(2 - v/c), 1 above."""
    cs = jnp.where(c > 0, c, 1.0)
    x = v / cs
    return jnp.where((c > 0) & (x < 1), x * (2 - x), 1.0)


class ZIPLoad(AbstractInjector):
    bus: np.ndarray = eqx.field(converter=i64)
    load: np.ndarray = eqx.field(converter=i64)
    share: np.ndarray = eqx.field(converter=f64)  # (6, k) fractions
    pqbrak: np.ndarray = eqx.field(converter=f64)  # (k,) pu voltage
    ibrak: np.ndarray = eqx.field(converter=f64)  # (k,) pu voltage

    state_names = ()
    source = "load"

    def init(self, v0, s0, s_base):
        p0, q0 = -jnp.real(s0), -jnp.imag(s0)
        sh = jnp.asarray(self.share)
        m = jnp.abs(v0)
        sp = (sh[0] * p0 + 1j * sh[3] * q0) / k_power(m, self.pqbrak)
        ci = (sh[1] * p0 + 1j * sh[4] * q0) / (m * k_current(m, self.ibrak))
        yz = (sh[2] * p0 - 1j * sh[5] * q0) / m**2
        x0 = jnp.zeros((0, len(self.bus)))
        return x0, jnp.stack([sp, ci, yz])

    def current(self, x, v, ref, s_base):
        m = jnp.sqrt(jnp.maximum(jnp.real(v) ** 2 + jnp.imag(v) ** 2, V_FLOOR**2))
        u = v / m
        kp = k_power(m, self.pqbrak)
        ki = k_current(m, self.ibrak)
        return -(jnp.conj(ref[0]) * kp / m + jnp.conj(ref[1]) * ki) * u

    def admittance(self, ref, s_base):
        return ref[2]
