"""REECB1: the electrical control of a photovoltaic plant (PSS/E `REECB1`, WECC
`REEC_B`; ICONs BUSR, PFFLAG, VFLAG, QFLAG, PQFLAG, CONs Vdip, Vup, Trv, dbd1, dbd2,
Kqv, Iqh1, Iql1, Vref0, Tp, Qmax, Qmin, Vmax, Vmin, Kqp, Kqi, Kvp, Kvi, Tiq, dPmax,
dPmin, Pmax, Pmin, Imax, Tpord). It turns the plant controller's (or the operating
point's) active power reference Pref and reactive command Qext into the current
commands Ipcmd, Iqcmd of its converter (`regca1`). All on the machine base.

    Vt_filt: Trv dVt_filt/dt = |V| - Vt_filt
    Pe_filt: Tp dPe_filt/dt = Pe - Pe_filt
    dip    = |V| < Vdip or |V| > Vup               voltage dip: the PI integrators,
                                                   the Tiq lag and Pord freeze
    Q      = clip(PFFLAG ? Pe_filt tan(pfaref) : Qext, Qmin, Qmax)
    xQ:    PI Kqp + Kqi/s on Q - Qe, non-windup [Vmin, Vmax]  (QFLAG = 1, VFLAG = 1)
    Vsel   = VFLAG ? (Q PI output) : clip(Vref0, Vmin, Vmax)
    xV:    PI Kvp + Kvi/s on Vsel - Vt_filt, non-windup [-Iqmax, Iqmax]  (QFLAG = 1)
    xIq:   Tiq dxIq/dt = Q / max(Vt_filt, 0.01) - xIq                   (QFLAG = 0)
    Iqinj  = clip(Kqv deadband(Vref0 - Vt_filt, dbd1, dbd2), Iql1, Iqh1)
    Iqcmd  = clip((QFLAG ? V PI output : xIq) + Iqinj, -Iqmax, Iqmax)
    Pord:  Tpord dPord/dt = Pref - Pord, rate within [dPmin, dPmax] pu/s,
           non-windup [Pmin, Pmax]
    Ipcmd  = clip(Pord / max(Vt_filt, 0.01), 0, Ipmax)
    current limit logic: PQFLAG = 0 (Q priority): Iqmax = Imax, Ipmax =
    sqrt(Imax^2 - Iqcmd^2); PQFLAG = 1 (P priority): Ipmax = Imax, Iqmax =
    sqrt(Imax^2 - Ipcmd^2)

Vref0 = 0 means the operating point's voltage (PSS/E). The structure follows the
WECC REEC_B diagram as OpenIPSL's REECB1 (verified against PSS/E) draws it: VFLAG
= 0 makes the local voltage loop regulate Vref0 and ignores Qext.
Deviations: a remote regulated bus (BUSR != 0) is refused; the Q and V PI limits
are non-windup (PowerSimulationsDynamics.jl's Q PI; its V PI has no limits).

At rest (`init`), for the converter's commands Ipcmd0, Iqcmd0: Vt_filt = V0,
Pe_filt = Pord = Pref = P0, xIq = Iqcmd0 - Iqinj0, xV = Iqcmd0 - Iqinj0, xQ = V0,
and the reactive command the plant controller must hold, Qext0 = xIq V0 (QFLAG =
0) or Q0 (QFLAG = 1); with PFFLAG = 1 the power factor angle pfaref = atan2(Q,
P0). An operating point outside the limits is refused (one line).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import _safe, check, lag, nonneg, require_at_rest, v
from ._ibr import columns, deadband, pi_nonwindup
from .base import f64

__all__ = ["REECB1"]

_FLAGS = ("PFFLAG", "VFLAG", "QFLAG", "PQFLAG")


def _flag(name):
    return (name, lambda o: np.isin(v(o, name), (0.0, 1.0)), "must be 0 or 1")


class REECB1(eqx.Module):
    BUSR: np.ndarray = eqx.field(converter=f64)  # remote bus (0: own terminal)
    PFFLAG: np.ndarray = eqx.field(converter=f64)  # 1: power factor control
    VFLAG: np.ndarray = eqx.field(converter=f64)  # 1: Q control, 0: voltage Vref0
    QFLAG: np.ndarray = eqx.field(converter=f64)  # 1: V/Q loops, 0: Q/V lag
    PQFLAG: np.ndarray = eqx.field(converter=f64)  # 1: P priority, 0: Q priority
    Vdip: np.ndarray = eqx.field(converter=f64)  # dip thresholds (pu)
    Vup: np.ndarray = eqx.field(converter=f64)
    Trv: np.ndarray = eqx.field(converter=f64)  # voltage filter (s)
    dbd1: np.ndarray = eqx.field(converter=f64)  # voltage error deadband (pu)
    dbd2: np.ndarray = eqx.field(converter=f64)
    Kqv: np.ndarray = eqx.field(converter=f64)  # reactive injection gain (pu/pu)
    Iqh1: np.ndarray = eqx.field(converter=f64)  # Iqinj limits (pu)
    Iql1: np.ndarray = eqx.field(converter=f64)
    Vref0: np.ndarray = eqx.field(converter=f64)  # voltage reference (0: V0)
    Tp: np.ndarray = eqx.field(converter=f64)  # electrical power filter (s)
    Qmax: np.ndarray = eqx.field(converter=f64)  # reactive command limits (pu)
    Qmin: np.ndarray = eqx.field(converter=f64)
    Vmax: np.ndarray = eqx.field(converter=f64)  # voltage command limits (pu)
    Vmin: np.ndarray = eqx.field(converter=f64)
    Kqp: np.ndarray = eqx.field(converter=f64)  # Q PI (pu V / pu Q, per s)
    Kqi: np.ndarray = eqx.field(converter=f64)
    Kvp: np.ndarray = eqx.field(converter=f64)  # V PI (pu I / pu V, per s)
    Kvi: np.ndarray = eqx.field(converter=f64)
    Tiq: np.ndarray = eqx.field(converter=f64)  # Q/V lag (s)
    dPmax: np.ndarray = eqx.field(converter=f64)  # Pord rate limits (pu/s)
    dPmin: np.ndarray = eqx.field(converter=f64)
    Pmax: np.ndarray = eqx.field(converter=f64)  # Pord limits (pu)
    Pmin: np.ndarray = eqx.field(converter=f64)
    Imax: np.ndarray = eqx.field(converter=f64)  # converter current limit (pu)
    Tpord: np.ndarray = eqx.field(converter=f64)  # power order lag (s)

    state_names = ("Vt_filt", "Pe_filt", "xQ", "xV", "xIq", "Pord")
    con_names = DYR_MODELS["REECB1"]

    def __check_init__(self):
        check(
            self,
            [
                *(_flag(f) for f in _FLAGS),
                (
                    "BUSR",
                    lambda o: v(o, "BUSR") == 0,
                    "must be 0 (a remote regulated bus is not supported)",
                ),
                *nonneg("Trv", "Tp", "Tiq", "Tpord"),
                ("Imax", lambda o: v(o, "Imax") > 0, "must be > 0"),
                ("Qmax", lambda o: v(o, "Qmax") >= v(o, "Qmin"), "must be >= Qmin"),
                ("Vmax", lambda o: v(o, "Vmax") >= v(o, "Vmin"), "must be >= Vmin"),
                ("Pmax", lambda o: v(o, "Pmax") >= v(o, "Pmin"), "must be >= Pmin"),
                ("Iqh1", lambda o: v(o, "Iqh1") >= v(o, "Iql1"), "must be >= Iql1"),
                ("dbd2", lambda o: v(o, "dbd2") >= v(o, "dbd1"), "must be >= dbd1"),
                ("dPmax", lambda o: v(o, "dPmax") > v(o, "dPmin"), "must be > dPmin"),
            ],
        )

    @classmethod
    def from_params(cls, params):
        """The group from dyr parameter dicts (`psse.DYR_MODELS` names)."""
        return cls(**columns(cls, params, cls.con_names))

    def control(self, x, vm, pe, qe, pref, qext, ref):
        """(Ipcmd, Iqcmd, dx/dt, signals) at |V| = vm with the converter's output pe,
        qe and the commands pref, qext (pu machine base). `signals`: the current
        limits Ipmax, Iqmax and the dip flag (1.0 during a dip)."""
        on = lambda f: f > 0.5  # noqa: E731
        dip = (vm < self.Vdip) | (vm > self.Vup)
        vf, dvf = lag(x[0], vm, 1.0, self.Trv)
        pef, dpef = lag(x[1], pe, 1.0, self.Tp)
        vsafe = jnp.maximum(vf, 0.01)
        qsrc = jnp.where(on(self.PFFLAG), pef * jnp.tan(ref["pfaref"]), qext)
        q = jnp.clip(qsrc, self.Qmin, self.Qmax)
        vref0 = ref["Vref0"]
        iqinj = jnp.clip(
            self.Kqv * deadband(vref0 - vf, self.dbd1, self.dbd2), self.Iql1, self.Iqh1
        )
        # power order
        tp = self.Tpord > 0
        fp = jnp.clip((pref - x[5]) / _safe(self.Tpord), self.dPmin, self.dPmax)
        pinned = ((x[5] >= self.Pmax) & (fp > 0)) | ((x[5] <= self.Pmin) & (fp < 0))
        dpord = jnp.where(tp & ~pinned & ~dip, fp, 0.0)
        pord = jnp.clip(jnp.where(tp, x[5], pref), self.Pmin, self.Pmax)
        ip_raw = pord / vsafe
        # current limit logic (PQFLAG): Iqmax first for P priority
        imax = self.Imax
        ip_p = jnp.clip(ip_raw, 0.0, imax)
        iqmax_p = jnp.sqrt(jnp.maximum(imax**2 - ip_p**2, 1e-12))
        iqmax = jnp.where(on(self.PQFLAG), iqmax_p, imax)
        # reactive loops
        vfl, qfl = on(self.VFLAG), on(self.QFLAG)
        yq, dxq = pi_nonwindup(
            x[2], q - qe, self.Kqp, self.Kqi, self.Vmin, self.Vmax, freeze=dip
        )
        dxq = jnp.where(vfl & qfl, dxq, 0.0)
        vsel = jnp.where(vfl, yq, jnp.clip(vref0, self.Vmin, self.Vmax))
        yv, dxv = pi_nonwindup(
            x[3], vsel - vf, self.Kvp, self.Kvi, -iqmax, iqmax, freeze=dip
        )
        dxv = jnp.where(qfl, dxv, 0.0)
        yiq, dxiq = lag(x[4], q / vsafe, 1.0, self.Tiq)
        dxiq = jnp.where(dip, 0.0, dxiq)
        iqcmd = jnp.clip(jnp.where(qfl, yv, yiq) + iqinj, -iqmax, iqmax)
        ipmax_q = jnp.sqrt(jnp.maximum(imax**2 - iqcmd**2, 1e-12))
        ipmax = jnp.where(on(self.PQFLAG), imax, ipmax_q)
        ipcmd = jnp.clip(ip_raw, 0.0, ipmax)
        dx = jnp.stack([dvf, dpef, dxq, dxv, dxiq, dpord])
        sig = {"Ipmax": ipmax, "Iqmax": iqmax, "dip": dip * 1.0}
        return ipcmd, iqcmd, dx, sig

    def init(self, vm, p0, q0, ipcmd0, iqcmd0):
        """(x0, Pref0, Qext0, ref) at |V| = vm, output p0 + j q0 (pu machine base)
        and the converter's commands at rest."""
        vref0 = jnp.where(self.Vref0 == 0, vm, self.Vref0)
        iqinj0 = jnp.clip(
            self.Kqv * deadband(vref0 - vm, self.dbd1, self.dbd2), self.Iql1, self.Iqh1
        )
        xiq = iqcmd0 - iqinj0
        qfl = self.QFLAG > 0.5
        q_cmd0 = jnp.where(qfl, q0, xiq * vm)
        pfaref = jnp.arctan2(q_cmd0, p0)
        require_at_rest(
            (q_cmd0 >= self.Qmin) & (q_cmd0 <= self.Qmax),
            "REECB1",
            "Qmax",
            self.Qmax,
            "the operating point's reactive command must lie within [Qmin, Qmax]",
        )
        require_at_rest(
            (p0 >= self.Pmin) & (p0 <= self.Pmax),
            "REECB1",
            "Pmax",
            self.Pmax,
            "the operating point's active power must lie within [Pmin, Pmax]",
        )
        require_at_rest(
            ipcmd0**2 + iqcmd0**2 <= self.Imax**2 * (1 + 1e-9),
            "REECB1",
            "Imax",
            self.Imax,
            "must be >= the operating point's current |Ipcmd + j Iqcmd|",
        )
        require_at_rest(
            ~(qfl & (self.VFLAG < 0.5))
            | (jnp.abs(jnp.clip(vref0, self.Vmin, self.Vmax) - vm) < 1e-6),
            "REECB1",
            "Vref0",
            self.Vref0,
            "with QFLAG = 1 and VFLAG = 0 the voltage loop regulates Vref0: it must "
            "be 0 or the operating point's voltage, within [Vmin, Vmax]",
        )
        require_at_rest(
            (self.PFFLAG < 0.5) | (p0 != 0),
            "REECB1",
            "PFFLAG",
            self.PFFLAG,
            "power factor control (1) needs P0 != 0",
        )
        z = 0.0 * vm
        x0 = jnp.stack([vm + z, p0 + z, vm + z, xiq + z, xiq + z, p0 + z])
        ref = {"Vref0": vref0 + z, "pfaref": pfaref + z}
        qext0 = q_cmd0
        return x0, p0 + z, qext0, ref
