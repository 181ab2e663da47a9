"""Inverter-based resources: a renewable plant as one current injector per
generator, the WECC second-generation chain REPCA1 (plant controller) -> REECB1
(electrical controller) -> REGCA1 (converter), as PSS/E links them: REPCA1 writes
Pref and Qext, REECB1 turns them into the current commands Ipcmd and Iqcmd, REGCA1
injects the currents (`regca1`, `reecb1`, `repca1` give each model's equations).

A plant's generator record in the raw file gives its operating point and its
machine base MBASE (every quantity of the three models is in pu on MBASE); its dyr
records name that generator's bus and id: REGCA1 (required: it is the generator's
machine record), REECB1 and REPCA1 (each optional: without REECB1 the converter's
commands stay at the operating point's, without REPCA1 the electrical
controller's Pref and Qext do). One group holds every plant of a case: devices
without an electrical or plant controller carry neutral placeholder parameters
(`has_reec`, `has_repc` = 0 select the constant commands; their states stay at
rest).

The group is an `AbstractInjector` (`base`): the current it injects depends on its
bus voltage (the converter's current is aligned with it), so the closed loop
solves the network with it by Newton's method. A tripped generator injects nothing
and its states freeze (the loop).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .base import AbstractInjector, f64, i64
from .reecb1 import REECB1
from .regca1 import REGCA1
from .repca1 import REPCA1

__all__ = ["Renewable", "REECB1_NEUTRAL", "REPCA1_NEUTRAL"]

# parameters of a controller that is absent (never used: `has_reec`/`has_repc` 0)
REECB1_NEUTRAL = {n: 0.0 for n in REECB1.con_names} | {
    "Vdip": -99.0,
    "Vup": 99.0,
    "Iqh1": 1.0,
    "Iql1": -1.0,
    "Qmax": 99.0,
    "Qmin": -99.0,
    "Vmax": 99.0,
    "Vmin": -99.0,
    "dPmax": 99.0,
    "dPmin": -99.0,
    "Pmax": 99.0,
    "Pmin": -99.0,
    "Imax": 99.0,
}
REPCA1_NEUTRAL = {n: 0.0 for n in REPCA1.con_names} | {
    "CKT": "0",
    "emax": 99.0,
    "emin": -99.0,
    "Qmax": 99.0,
    "Qmin": -99.0,
    "femax": 99.0,
    "femin": -99.0,
    "Pmax": 99.0,
    "Pmin": -99.0,
}

_NG, _NE = len(REGCA1.state_names), len(REECB1.state_names)


def _vm(v):
    """|v| (pu), smoothed at 0 so that the current and its derivatives stay finite
    at a bolted fault."""
    return jnp.sqrt(jnp.real(v) ** 2 + jnp.imag(v) ** 2 + 1e-12)


class Renewable(AbstractInjector):
    gen: np.ndarray = eqx.field(converter=i64)  # positions in System.generators
    bus: np.ndarray = eqx.field(converter=i64)  # positions in System.buses
    mbase: np.ndarray = eqx.field(converter=f64)  # machine base (MVA)
    regc: REGCA1
    reec: REECB1
    repc: REPCA1
    has_reec: np.ndarray = eqx.field(converter=f64)  # 1: REECB1 present
    has_repc: np.ndarray = eqx.field(converter=f64)  # 1: REPCA1 present

    state_names = REGCA1.state_names + REECB1.state_names + REPCA1.state_names
    source = "gen"
    # the sub-models by their PSS/E names (parameters REGCA1[BUS:ID].Tg, ...)
    parts = {"REGCA1": "regc", "REECB1": "reec", "REPCA1": "repc"}

    @classmethod
    def from_params(cls, gen, bus, mbase, regc, reec, repc, f_base=60.0):
        """The group for generators at positions `gen` (buses `bus`, bases `mbase`
        MVA) from dyr parameter dicts: `regc[i]` REGCA1's, `reec[i]` REECB1's or
        None, `repc[i]` REPCA1's or None."""
        return cls(
            gen=gen,
            bus=bus,
            mbase=mbase,
            regc=REGCA1.from_params(regc),
            reec=REECB1.from_params([r or REECB1_NEUTRAL for r in reec]),
            repc=REPCA1.from_params([r or REPCA1_NEUTRAL for r in repc], f_base=f_base),
            has_reec=[r is not None for r in reec],
            has_repc=[r is not None for r in repc],
        )

    def _split(self, x):
        return x[:_NG], x[_NG : _NG + _NE], x[_NG + _NE :]

    def signals(self, x, v, ref):
        """Every signal of the chain at bus voltages v (pu): a dict of (k,) arrays,
        "Ip", "Iq" (the injected currents), "Ipcmd", "Iqcmd", "LVPL", "Ipmax",
        "Iqmax", "Pe", "Qe", "Pref", "Qext" (pu machine base), "Vt" (pu), "freq"
        (pu), "dip" (1 during a voltage dip), "i" (complex current, pu machine
        base) and "dx" (n_states, k)."""
        xg, xe, xr = self._split(x)
        vm = _vm(v)
        ip, iq, lvpl = self.regc.outputs(xg, vm)
        i_m = (ip - 1j * iq) * v / vm
        pe, qe = vm * ip, vm * iq
        pref_r, qext_r, dxr, sig_r = self.repc.control(xr, v, i_m, pe, qe, ref["repc"])
        on_r = self.has_repc > 0.5
        pref = jnp.where(on_r, pref_r, ref["Pref0"])
        qext = jnp.where(on_r, qext_r, ref["Qext0"])
        ipc, iqc, dxe, sig_e = self.reec.control(
            xe, vm, pe, qe, pref, qext, ref["reec"]
        )
        on_e = self.has_reec > 0.5
        ipcmd = jnp.where(on_e, ipc, ref["Ipcmd0"])
        iqcmd = jnp.where(on_e, iqc, ref["Iqcmd0"])
        dxg = self.regc.rhs(xg, vm, ipcmd, iqcmd, ref["q0_sign"])
        dx = jnp.concatenate([dxg, dxe * on_e, dxr * on_r])
        return {
            "Ip": ip,
            "Iq": iq,
            "Ipcmd": ipcmd,
            "Iqcmd": iqcmd,
            "LVPL": lvpl,
            "Ipmax": jnp.where(on_e, sig_e["Ipmax"], jnp.nan),
            "Iqmax": jnp.where(on_e, sig_e["Iqmax"], jnp.nan),
            "Pe": pe,
            "Qe": qe,
            "Pref": pref,
            "Qext": qext,
            "Vt": vm,
            "freq": sig_r["freq"],
            "dip": sig_e["dip"] * on_e,
            "i": i_m,
            "dx": dx,
        }

    def current(self, x, v, ref, s_base):
        xg = x[:_NG]
        vm = _vm(v)
        ip, iq, _ = self.regc.outputs(xg, vm)
        return (ip - 1j * iq) * (v / vm) * (self.mbase / s_base)

    def rhs(self, x, v, ref, s_base):
        return self.signals(x, v, ref)["dx"]

    def measure(self, x, v, ref, s_base):
        """The recorded signals (`signals` without the state derivatives)."""
        out = self.signals(x, v, ref)
        out.pop("dx")
        out.pop("i")
        return out

    def init(self, v0, s0, s_base):
        s = s0 * (s_base / self.mbase)
        p0, q0 = jnp.real(s), jnp.imag(s)
        vm0 = jnp.abs(v0)
        xg, ipcmd0, iqcmd0 = self.regc.init(vm0, p0, q0)
        xe, pref0, qext0, ref_e = self.reec.init(vm0, p0, q0, ipcmd0, iqcmd0)
        i0 = jnp.conj(s / v0)
        xr, ref_r = self.repc.init(v0, i0, p0, q0, pref0, qext0)
        ref = {
            "reec": ref_e,
            "repc": ref_r,
            "Ipcmd0": ipcmd0,
            "Iqcmd0": iqcmd0,
            "Pref0": pref0,
            "Qext0": qext0,
            "q0_sign": jnp.sign(q0),
        }
        return jnp.concatenate([xg, xe, xr]), ref
