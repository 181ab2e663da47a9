"""REGCA1: the renewable generator/converter model (PSS/E `REGCA1`, WECC `REGC_A`;
ICON LVPLSW, CONs Tg, Rrpwr, Brkpt, Zerox, Lvpl1, Volim, Lvpnt1, Lvpnt0, Iolim,
Tfltr, Khv, Iqrmax, Iqrmin, Accel): a current source at its generator's bus driven
by the current commands Ipcmd (active) and Iqcmd (reactive, positive: capacitive,
injecting vars) of its electrical controller (`reecb1`), all on the machine base.

    Ip:    Tg dIp/dt = Ipcmd - Ip, rising at most Rrpwr pu/s, non-windup upper limit
           LVPL(Vmeas) (LVPL active when LVPLSW = 1)
    Iq:    Tg dIq/dt = Iqcmd - Iq, rate within [Iqrmin, Iqrmax] pu/s (the rising limit
           where the operating point's Q0 > 0, the falling one where Q0 < 0, as ANDES
           and PowerSimulationsDynamics.jl read PSS/E's manual)
    Vmeas: Tfltr dVmeas/dt = |V| - Vmeas            voltage filter of the LVPL
    LVPL(V) = 0 (V <= Zerox), Lvpl1 (V - Zerox)/(Brkpt - Zerox) (Zerox < V < Brkpt),
              no limit (V >= Brkpt)                 low-voltage power logic
    G_lv(V) = clip((V - Lvpnt0)/(Lvpnt1 - Lvpnt0), 0, 1)   low-voltage active current
                                                    management, on the unfiltered |V|
    Ip_out = G_lv(|V|) min(Ip, LVPL)
    Iq_out = max(Iq - Khv max(|V| - Volim, 0), Iolim)      high-voltage reactive
                                                    current management
    I      = (Ip_out - j Iq_out) V/|V|              injected current (pu machine base):
                                                    P = |V| Ip_out, Q = |V| Iq_out

The converter is an ideal current source aligned with the terminal voltage at every
instant (as ANDES's REGCA1; PSS/E's Accel, a numerical acceleration factor of its
network solution, has no meaning here and is read but unused).

At rest (`init`): Ip = Ipcmd = P0/V0, Iq = Iqcmd = Q0/V0 + Khv max(V0 - Volim, 0),
Vmeas = V0; refused (one line) where the operating point needs a limit to act
(V0 below Lvpnt1, Ip0 above LVPL(V0), Iq_out below Iolim).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import _safe, check, lag, positive, require_at_rest, v
from ._ibr import columns
from .base import f64

__all__ = ["REGCA1", "NO_LIMIT"]

NO_LIMIT = 1e6  # an absent current limit (pu): finite, so gradients stay finite


class REGCA1(eqx.Module):
    LVPLSW: np.ndarray = eqx.field(converter=f64)  # 1: LVPL on, 0: off
    Tg: np.ndarray = eqx.field(converter=f64)  # converter current lag (s)
    Rrpwr: np.ndarray = eqx.field(converter=f64)  # Ip rising rate limit (pu/s)
    Brkpt: np.ndarray = eqx.field(converter=f64)  # LVPL breakpoint voltage (pu)
    Zerox: np.ndarray = eqx.field(converter=f64)  # LVPL zero crossing voltage (pu)
    Lvpl1: np.ndarray = eqx.field(converter=f64)  # LVPL at Brkpt (pu current)
    Volim: np.ndarray = eqx.field(converter=f64)  # HV reactive management onset (pu)
    Lvpnt1: np.ndarray = eqx.field(converter=f64)  # LV active management: full (pu)
    Lvpnt0: np.ndarray = eqx.field(converter=f64)  # LV active management: zero (pu)
    Iolim: np.ndarray = eqx.field(converter=f64)  # Iq floor under HV management (pu)
    Tfltr: np.ndarray = eqx.field(converter=f64)  # LVPL voltage filter (s)
    Khv: np.ndarray = eqx.field(converter=f64)  # HV management gain (pu/pu)
    Iqrmax: np.ndarray = eqx.field(converter=f64)  # Iq rising rate limit (pu/s)
    Iqrmin: np.ndarray = eqx.field(converter=f64)  # Iq falling rate limit (pu/s)
    Accel: np.ndarray = eqx.field(converter=f64)  # PSS/E's acceleration (unused)

    state_names = ("Ip", "Iq", "Vmeas")
    con_names = DYR_MODELS["REGCA1"]

    def __check_init__(self):
        check(
            self,
            [
                *positive("Tg"),
                ("Tfltr", lambda o: v(o, "Tfltr") >= 0, "must be >= 0"),
                ("Rrpwr", lambda o: v(o, "Rrpwr") > 0, "must be > 0 (pu/s)"),
                ("Brkpt", lambda o: v(o, "Brkpt") > v(o, "Zerox"), "must be > Zerox"),
                (
                    "Lvpnt1",
                    lambda o: v(o, "Lvpnt1") > v(o, "Lvpnt0"),
                    "must be > Lvpnt0",
                ),
                ("Iolim", lambda o: v(o, "Iolim") <= 0, "must be <= 0"),
                ("Iqrmax", lambda o: v(o, "Iqrmax") > 0, "must be > 0 (pu/s)"),
                ("Iqrmin", lambda o: v(o, "Iqrmin") < 0, "must be < 0 (pu/s)"),
                (
                    "LVPLSW",
                    lambda o: np.isin(v(o, "LVPLSW"), (0.0, 1.0)),
                    "must be 0 or 1",
                ),
            ],
        )

    @classmethod
    def from_params(cls, params):
        """The group from dyr parameter dicts (`psse.DYR_MODELS` names)."""
        return cls(**columns(cls, params, cls.con_names))

    def lvpl(self, vmeas):
        """The LVPL limit on Ip (pu machine base) at the filtered voltage vmeas."""
        ramp = self.Lvpl1 * (vmeas - self.Zerox) / _safe(self.Brkpt - self.Zerox)
        lim = jnp.where(vmeas >= self.Brkpt, NO_LIMIT, jnp.maximum(ramp, 0.0))
        return jnp.where(self.LVPLSW > 0, lim, NO_LIMIT)

    def g_lv(self, vm):
        """The low-voltage active current management gain (0..1) at |V| = vm."""
        return jnp.clip((vm - self.Lvpnt0) / _safe(self.Lvpnt1 - self.Lvpnt0), 0, 1)

    def outputs(self, x, vm):
        """(Ip_out, Iq_out, LVPL): the currents injected (pu machine base) and the
        LVPL limit in force."""
        lim = self.lvpl(x[2])
        ip = self.g_lv(vm) * jnp.minimum(x[0], lim)
        iq = jnp.maximum(
            x[1] - self.Khv * jnp.maximum(vm - self.Volim, 0.0), self.Iolim
        )
        return ip, iq, lim

    def rhs(self, x, vm, ipcmd, iqcmd, q0_sign):
        """dx/dt for the commands ipcmd, iqcmd (pu) at |V| = vm; q0_sign: the sign of
        the operating point's reactive output (which Iq rate limit is active)."""
        lim = self.lvpl(x[2])
        tg = _safe(self.Tg)
        f = jnp.minimum((ipcmd - x[0]) / tg, self.Rrpwr)
        # the LVPL moves with Vmeas: the state is swept down with it (`sweeping`)
        tau = tg / 30.0
        dip = jnp.minimum(f, (lim - x[0]) / tau)
        fq = (iqcmd - x[1]) / tg
        up = jnp.where(q0_sign > 0, self.Iqrmax, jnp.inf)
        dn = jnp.where(q0_sign < 0, self.Iqrmin, -jnp.inf)
        diq = jnp.clip(fq, dn, up)
        _, dv = lag(x[2], vm, 1.0, self.Tfltr)
        return jnp.stack([dip, diq, dv])

    def init(self, vm, p0, q0):
        """(x0, Ipcmd0, Iqcmd0) for |V| = vm and output p0 + j q0 (pu machine
        base)."""
        ip0 = p0 / vm
        iq_out = q0 / vm
        iq0 = iq_out + self.Khv * jnp.maximum(vm - self.Volim, 0.0)
        require_at_rest(
            vm >= self.Lvpnt1,
            "REGCA1",
            "Lvpnt1",
            self.Lvpnt1,
            "must be <= the operating point's voltage (the low-voltage active "
            "current management would act at rest)",
        )
        require_at_rest(
            ip0 <= self.lvpl(vm),
            "REGCA1",
            "Lvpl1",
            self.Lvpl1,
            "the LVPL limit at the operating point's voltage must be >= P0/V0",
        )
        require_at_rest(
            iq_out >= self.Iolim,
            "REGCA1",
            "Iolim",
            self.Iolim,
            "must be <= the operating point's reactive current Q0/V0",
        )
        return jnp.stack([ip0, iq0, vm + 0.0 * ip0]), ip0, iq0
