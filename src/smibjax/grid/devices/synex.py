"""SYNEX: the paper's synergetic excitation law as a decentralized exciter (a
smibjax-specific model, not a PSS/E record; dyr record 'SYNEX' with the CONs of
`psse.DYR_MODELS["SYNEX"]`).

Each device computes its machine's field voltage from local measurements only: the
speed deviation omega (pu), the active and reactive power Pe, Qe out of the terminal
and the terminal voltage magnitude Vt (pu, machine base; a PMU at the terminal). The
rest of the network is, to this device, an infinite bus behind a reactance XE
(pu, machine base): the local SMIB equivalent of docs/model.md section 1 with the
machine's EMF E' behind X'd = XDP, no transformer (it is part of XE) and no SVC.

Local equivalent, in the frame of the terminal voltage (Vt on the real axis):

    I     = (Pe - j Qe) / Vt                      stator current (machine base)
    E'    = Vt + j XDP I                           the one-axis machine's EMF
    V_inf = Vt - j XE I                            the equivalent's source voltage
    x1    = arg(E' / V_inf),   E = |E'|,   V = |V_inf|

so that Pe = E V sin(x1) / Xs with Xs = XDP + XE holds exactly at every instant
(lossless machine and equivalent); V_inf is re-estimated at every instant from the
terminal phasors, so the equivalent follows the network's angle as it drifts (the
device never reads an absolute rotor angle). XE is fixed: the case variant
`kundur_synex.dyr` uses the Thevenin reactance of the network seen from each
terminal at the power flow (`thevenin_reactance`), the other machines as their
Norton admittances and the loads as constant impedances.

The law is the field-voltage channel of the paper's law (`controllers.synergetic.law`,
eq. 21) with no SVC (B = B0 = 0, so x4 = Psvc = 0) and the adaptation frozen at the
operating point (th1 = -D/omega_b, th2 = Pm0: the estimates the paper's oracle
adaptation converges to when Pm does not change; this network has no SVC for phi2 to
act on, and the paper's update law would integrate phi2 = e1 + e2, which the field
channel does not drive to zero):

    x2 = omega_b omega (rad/s),  x3 = Pe_law = E V sin(x1) / Xs,  M = 2 H / omega_b
    f3 = V cos(x1)/Xs (E x2 + (XD - XDP) V sin(x1)/(Xs TDOP)) - Xds/(Xs TDOP) x3,
         Xds = XD + XE
    g31 = V sin(x1) / Xs
    phi = C (x1 - x1_0) + x2 + BETA (x3 - x3_0)
    xdot2_hat = (x3_0 - D/omega_b x2 - x3) / M
    u_f = -TDOP (BETA f3 + C x2 + xdot2_hat - spow(-phi/T1, ALPHA)) / (BETA g31)
    Efd = clip(u_f + Efd0 - u_f0, EMIN, EMAX)

with (x1_0, x3_0) the equivalent's angle and power at the operating point and u_f0
the law's value there. For a one-axis machine (GENTRA, Xq = X'd) without armature
resistance or saturation u_f0 equals the machine's Efd0 exactly (the offset is 0 and
the device is the paper's law on the equivalent); on other machines (GENROU: E'
reconstructed behind X'd is an approximation of its flux state) the offset makes the
operating point an exact equilibrium. g31 is floored at 1e-6 in magnitude (x1 at 0 or
pi, where the law is singular). ALPHA = 5/7 is the paper's AFTSC, ALPHA = 1 the ASC;
C = 1 is the paper's macro-variable. The paper's BETA = 50 makes the sliding manifold
a saddle (docs/model.md section 2); BETA < 0 makes it stable.

States: none (the law is algebraic in the measurements).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ...controllers.synergetic.law import evolution
from ..psse import DYR_MODELS
from ._blocks import build_group, check, ordered, positive, require_at_rest, v
from .base import AbstractController, f64, i64

__all__ = ["SYNEX", "G31_FLOOR"]

G31_FLOOR = 1e-6  # smallest |g31| the law divides by (pu power / rad)


class SYNEX(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    XE: np.ndarray = eqx.field(converter=f64)  # equivalent's reactance (pu mach. base)
    XD: np.ndarray = eqx.field(converter=f64)  # machine's Xd (pu machine base)
    XDP: np.ndarray = eqx.field(converter=f64)  # machine's X'd (pu machine base)
    TDOP: np.ndarray = eqx.field(converter=f64)  # machine's T'do (s)
    H: np.ndarray = eqx.field(converter=f64)  # machine's inertia constant (s)
    D: np.ndarray = eqx.field(converter=f64)  # machine's damping (pu power/pu speed)
    BETA: np.ndarray = eqx.field(converter=f64)  # macro-variable weight of e3
    T1: np.ndarray = eqx.field(converter=f64)  # evolution-law time constant (s)
    ALPHA: np.ndarray = eqx.field(converter=f64)  # evolution-law power, (1/2, 1]
    C: np.ndarray = eqx.field(converter=f64)  # macro-variable weight of e1 (1: paper)
    EMIN: np.ndarray = eqx.field(converter=f64)  # field voltage limits (pu)
    EMAX: np.ndarray = eqx.field(converter=f64)
    f_base: float = eqx.field(static=True, default=60.0)  # frequency (Hz)

    inputs = ("omega", "Pe", "Qe", "Vt")
    output = "Efd"
    state_names = ()
    con_names = DYR_MODELS["SYNEX"]

    def __check_init__(self):
        check(
            self,
            [
                *positive("XE", "XDP", "TDOP", "H", "T1", "C"),
                ("XD", lambda o: v(o, "XD") >= v(o, "XDP"), "must be >= XDP"),
                ("D", lambda o: v(o, "D") >= 0, "must be >= 0"),
                ("BETA", lambda o: v(o, "BETA") != 0, "must be nonzero"),
                (
                    "ALPHA",
                    lambda o: (v(o, "ALPHA") > 0.5) & (v(o, "ALPHA") <= 1.0),
                    "must be in (1/2, 1] (5/7: the paper's AFTSC, 1: ASC)",
                ),
                ordered("EMIN", "EMAX"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        return build_group(cls, gen_positions, params, cls.con_names)

    def equivalent(self, meas):
        """(x1, E, V, x3): the local SMIB equivalent's rotor angle (rad), EMF and
        source voltage (pu) and electrical power (pu machine base) from the
        terminal measurements (see the module docstring)."""
        vt = meas["Vt"]
        i = (meas["Pe"] - 1j * meas["Qe"]) / vt
        e = vt + 1j * self.XDP * i
        vinf = vt - 1j * self.XE * i
        x1 = jnp.angle(e / vinf)
        E, V = jnp.abs(e), jnp.abs(vinf)
        x3 = E * V * jnp.sin(x1) / (self.XDP + self.XE)
        return x1, E, V, x3

    def law(self, meas, x1_0, x3_0):
        """u_f (pu): the paper's field-voltage law on the local equivalent, around
        the equivalent's operating point (x1_0 rad, x3_0 pu machine base)."""
        wb = 2 * math.pi * self.f_base
        x1, E, V, x3 = self.equivalent(meas)
        x2 = wb * meas["omega"]
        xs = self.XDP + self.XE
        xds = self.XD + self.XE
        sin1, cos1 = jnp.sin(x1), jnp.cos(x1)
        f3 = (
            V
            * cos1
            / xs
            * (E * x2 + (self.XD - self.XDP) * V * sin1 / (xs * self.TDOP))
        )
        f3 = f3 - xds / (xs * self.TDOP) * x3
        g31 = V * sin1 / xs
        g31 = jnp.where(
            jnp.abs(g31) >= G31_FLOOR, g31, jnp.where(g31 < 0, -G31_FLOOR, G31_FLOOR)
        )
        M = 2 * self.H / wb
        phi = self.C * (x1 - x1_0) + x2 + self.BETA * (x3 - x3_0)
        xdot2_hat = (x3_0 - self.D / wb * x2 - x3) / M
        v1 = -(
            self.BETA * f3
            + self.C * x2
            + xdot2_hat
            - evolution(phi, self.T1, self.ALPHA)
        ) / (self.BETA * g31)
        return self.TDOP * v1

    def init(self, y0, meas):
        """ref = (x1_0, x3_0, Efd0 - u_f0): Efd = Efd0 at rest, exactly."""
        require_at_rest(
            (y0 >= self.EMIN) & (y0 <= self.EMAX),
            "SYNEX",
            "Efd0",
            y0,
            "the operating point's field voltage must lie within [EMIN, EMAX]",
        )
        x1_0, _, _, x3_0 = self.equivalent(meas)
        require_at_rest(
            (x1_0 > 0) & (x1_0 < math.pi),
            "SYNEX",
            "x1_0",
            x1_0,
            "the equivalent's angle at the operating point must lie in (0, pi) "
            "(a generating machine; the law is singular at 0 and pi)",
        )
        uf0 = self.law(meas, x1_0, x3_0)
        return jnp.zeros((0,) + jnp.shape(y0)), jnp.stack([x1_0, x3_0, y0 - uf0])

    def rhs(self, x, meas, ref):
        return x

    def out(self, x, meas, ref):
        uf = self.law(meas, ref[0], ref[1])
        return jnp.clip(uf + ref[2], self.EMIN, self.EMAX)


def thevenin_reactance(case, op) -> np.ndarray:
    """The Thevenin reactance (pu, each machine's base) of the network seen from every
    generator's terminal at the operating point `op`, over all generators: the
    pre-event network with the loads as constant impedances, the infinite buses held,
    every other machine as its Norton admittance and the generator's own admittance
    removed. (The real part, the equivalent's resistance, is dropped: the law's
    equivalent is lossless.)"""
    from ..network import stage_configs, stage_matrices

    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    A = np.asarray(mats.A[0])
    ports = {int(b): k for k, b in enumerate(case.layout.ports)}
    gen_bus = case.layout.gen_bus
    y_gen = np.asarray(op.grid.gen_y)
    mbase = np.asarray(case.system.generators.mbase, dtype=float)
    out = np.full(len(gen_bus), np.nan)
    for g, b in enumerate(gen_bus):
        if b not in ports:
            continue
        z_kk = A[ports[b], ports[b]]
        z_th = 1.0 / (1.0 / z_kk - y_gen[g])
        out[g] = np.imag(z_th) * mbase[g] / case.system.s_base
    return out
