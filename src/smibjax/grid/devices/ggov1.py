"""GGOV1: GE's general governor-turbine model (PSS/E `GGOV1`, ICONs Rselect, Flag;
CONs R, Tpelec, maxerr, minerr, Kpgov, Kigov, Kdgov, Tdgov, Vmax, Vmin, Tact, Kturb,
Wfnl, Tb, Tc, Teng, Tfload, Kpload, Kiload, Ldref, Dm, Ropen, Rclose, Kimw, Aset, Ka,
Ta, Trate, db, Tsa, Tsb, Rup, Rdown; PSS/E Model Library, GGOV1; IEEE PES-TR1 (2013)
section 3.1.2.3). ANDES 2.0 has no GGOV1.

Powers are in pu of the turbine rating Trate (MW; Trate = 0: the machine's MBASE):
the electrical power read is Pe MBASE / Trate, the mechanical power written Pm_T
Trate / MBASE. With omega the speed deviation (pu) and fsr the fuel stroke reference
(the low-value gate's output):

    pe:    Tpelec dpe/dt = Pe_T - pe                      electrical power transducer
    x_mw:  dx_mw/dt = Kimw (Pmwset - pe)                  supervisory load controller,
                                                          non-windup [-1.1 R, 1.1 R]
    err  = Pref + x_mw - omega - R fb                     fb (Rselect): 1 pe, 0 none
                                                          (isochronous), -1 the
                                                          requested stroke fsr_d, -2
                                                          the valve stroke
    e    = clip(dz(err), minerr, maxerr)                  deadband db, error limits
    x_d:   Tdgov dx_d/dt = e - x_d                        derivative Kdgov s/(1 + s Tdgov)
    fsrn = Kpgov e + x_i + (Kdgov/Tdgov)(e - x_d)         governor PID
    x_i:   dx_i/dt = (Kigov/Kpgov)(fsr - x_i)             its integrator, reset from the
                                                          gate output (Kpgov = 0:
                                                          dx_i/dt = Kigov e)
    x_w:   Ta dx_w/dt = omega - x_w                       acceleration (omega - x_w)/Ta
    fsra = fsr_d + Ka DELT (Aset - (omega - x_w)/Ta)      acceleration limiter (Ka = 0:
                                                          none)
    fsr_d: DELT dfsr_d/dt = fsr - fsr_d                   the gate output one step back
    texm   = 1/(1 + s Tfload) (1 + s Tsa)/(1 + s Tsb) wf (1 + omega)^min(Dm, 0)
                                                          exhaust temperature
                                                          (states x_ts, texm)
    fsrt = min(x_l + Kpload (Ldref/Kturb + Wfnl - texm), 1)   load limiter
    x_l:   dx_l/dt = clip((Kiload/Kpload)(fsr - x_l), Rdown, Rup)   its integrator
    fsr  = clip(min(fsrn, fsrt, fsra), Vmin, Vmax)        low-value gate, valve limits
    stroke: dstroke/dt = clip((fsr - stroke)/Tact, Rclose, Ropen)   actuator
    wf   = stroke (1 + omega) (Flag = 1) or stroke (Flag = 0)       fuel flow
    x_tb:  (1 + s Tc)/(1 + s Tb) on Kturb (wf - Wfnl)     turbine (state x_tb)
    Pm_T = x_tb output - Dm omega (Dm > 0)                mechanical power (pu Trate)

dz is the deadband: 0 within [-db, db], err -+ db outside (continuous, no jump).

The two proportional-integral controllers (the governor's, the load limiter's) are
GE's reset form: each integrator is a lag of the gate's output fsr, so that the one
in control integrates its error (dx_i/dt = Kigov e + ...) and the others follow fsr
instead of winding up. PSS/E computes the acceleration limiter as fsra(t) = fsr(t -
DELT) + Ka DELT (Aset - accel) with DELT its time step, and uses the previous step's
fsr where Rselect = -1 feeds the requested stroke back; in continuous time fsr_d is
fsr through a lag of DELT = 1/120 s (PSS/E's half-cycle step at 60 Hz): an explicit
Euler step of DELT reproduces PSS/E's recursion, and in control the limiter
integrates d fsr/dt = Ka (Aset - accel) as PSS/E's does.

At rest (omega0 the operating point's speed deviation): Pm_T0 = Pm0 MBASE / Trate,
wf0 = (Pm_T0 + Dm omega0 [Dm > 0]) / Kturb + Wfnl, every stroke state wf0 / (1 +
omega0 [Flag]), texm0 = wf0 (1 + omega0)^min(Dm, 0), pe0 = Pmwset = Pe_T0, x_mw0 =
0, e0 = 0, and Pref = omega0 + R fb0 (PSS/E's speed-load reference). The governor
must be the gate's lowest input at rest: where the operating point's stroke lies
beyond Vmax, Vmin or the load limiter's ceiling 1, or its exhaust temperature above
the load reference Ldref/Kturb + Wfnl, that limit is moved to the operating point
(the unit starts on it; PowerWorld's "adjust limits at initialization", GridPACK's
option) instead of starting off equilibrium as PSS/E does after reporting it:
ACTIVSg2000's units at 5423 and 4083 start 0.6% and 0.05% above Vmax = 1. `ref`
holds (Pref, Pmwset, Vmin, Vmax, the ceiling, the load reference) in force.

Deviations from PSS/E: the limits moved at rest (above); the engine's transport
delay Teng is not modelled (only Teng = 0 is read; ACTIVSg2000's 367 GGOV1 all
have 0); DELT is the fixed 1/120 s above, not the run's step; the deadband is the
continuous one; Rup and Rdown bound the load limiter integrator's rate (our reading
of "maximum rate of load limit increase/decrease"). Rselect -1 is the requested
stroke (the gate output) and -2 the valve stroke, as PSS/E's CON table says
(OpenIPSL's and GridPACK's code swap them).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete
from ..psse import DYR_MODELS
from ._blocks import (
    build_group,
    check,
    lag,
    leadlag,
    nonneg,
    nonwindup,
    ordered,
    positive,
    proper,
    require_at_rest,
    v,
    washout,
)
from .base import AbstractController, f64, i64

__all__ = ["GGOV1", "DELT"]

DELT = 1.0 / 120.0
"""PSS/E's time step in GGOV1's acceleration limiter and Rselect = -1 feedback (s):
half a cycle at 60 Hz, the step PSS/E's users run."""

_CONS = DYR_MODELS["GGOV1"][2:]  # the CONs after the ICONs Rselect, Flag


def _ok_codes(name, codes):
    return (
        name,
        lambda o: np.isin(np.asarray(getattr(o, name)), codes),
        f"must be one of {', '.join(str(c) for c in codes)}",
    )


class GGOV1(AbstractController):
    gen: np.ndarray = eqx.field(converter=i64)
    mbase: np.ndarray = eqx.field(converter=f64)  # the machine's MVA base
    Rselect: np.ndarray = eqx.field(converter=i64)  # droop feedback: 1, 0, -1, -2
    Flag: np.ndarray = eqx.field(converter=i64)  # 1: fuel flow times speed
    R: np.ndarray = eqx.field(converter=f64)  # permanent droop (pu)
    Tpelec: np.ndarray = eqx.field(converter=f64)  # power transducer (s)
    maxerr: np.ndarray = eqx.field(converter=f64)  # speed error limits (pu)
    minerr: np.ndarray = eqx.field(converter=f64)
    Kpgov: np.ndarray = eqx.field(converter=f64)  # PID gains
    Kigov: np.ndarray = eqx.field(converter=f64)
    Kdgov: np.ndarray = eqx.field(converter=f64)
    Tdgov: np.ndarray = eqx.field(converter=f64)  # derivative filter (s)
    Vmax: np.ndarray = eqx.field(converter=f64)  # valve position limits (pu)
    Vmin: np.ndarray = eqx.field(converter=f64)
    Tact: np.ndarray = eqx.field(converter=f64)  # actuator (s)
    Kturb: np.ndarray = eqx.field(converter=f64)  # turbine gain
    Wfnl: np.ndarray = eqx.field(converter=f64)  # no-load fuel flow (pu)
    Tb: np.ndarray = eqx.field(converter=f64)  # turbine lag (s)
    Tc: np.ndarray = eqx.field(converter=f64)  # turbine lead (s)
    Teng: np.ndarray = eqx.field(converter=f64)  # engine transport delay (s; 0 only)
    Tfload: np.ndarray = eqx.field(converter=f64)  # load limiter measurement (s)
    Kpload: np.ndarray = eqx.field(converter=f64)  # load limiter PI gains
    Kiload: np.ndarray = eqx.field(converter=f64)
    Ldref: np.ndarray = eqx.field(converter=f64)  # load limiter reference (pu Trate)
    Dm: np.ndarray = eqx.field(converter=f64)  # speed sensitivity
    Ropen: np.ndarray = eqx.field(converter=f64)  # valve rate limits (pu/s)
    Rclose: np.ndarray = eqx.field(converter=f64)
    Kimw: np.ndarray = eqx.field(converter=f64)  # supervisory load controller gain
    Aset: np.ndarray = eqx.field(converter=f64)  # acceleration set point (pu/s)
    Ka: np.ndarray = eqx.field(converter=f64)  # acceleration limiter gain
    Ta: np.ndarray = eqx.field(converter=f64)  # acceleration filter (s)
    Trate: np.ndarray = eqx.field(converter=f64)  # turbine rating (MW; 0: MBASE)
    db: np.ndarray = eqx.field(converter=f64)  # speed deadband (pu)
    Tsa: np.ndarray = eqx.field(converter=f64)  # temperature lead (s)
    Tsb: np.ndarray = eqx.field(converter=f64)  # temperature lag (s)
    Rup: np.ndarray = eqx.field(converter=f64)  # load limit rate limits (pu/s)
    Rdown: np.ndarray = eqx.field(converter=f64)

    inputs = ("omega", "Pe")
    output = "Pm"
    state_names = (
        "pe",
        "x_mw",
        "x_d",
        "x_i",
        "fsr_d",
        "x_w",
        "stroke",
        "x_tb",
        "x_ts",
        "texm",
        "x_l",
    )
    con_names = _CONS
    needs_mbase: ClassVar[bool] = True  # case.build_case adds MBASE to the records

    def __check_init__(self):
        if is_concrete(self.Teng):
            te = np.asarray(self.Teng)
            if (te != 0).any():
                raise ParameterError(
                    f"GGOV1.Teng = {float(te[te != 0][0])!r} is not supported: only 0 "
                    "(the engine's transport delay is not modelled)"
                )
        check(
            self,
            [
                _ok_codes("Rselect", (1, 0, -1, -2)),
                _ok_codes("Flag", (0, 1)),
                *positive("mbase", "Tact", "Kturb", "Kpload"),
                *nonneg("R", "Tpelec", "Kpgov", "Kigov", "Kdgov", "Tdgov"),
                *nonneg("Tfload", "Kiload", "Kimw", "Ka", "Ta", "Trate", "db", "Aset"),
                proper("Tc", "Tb"),
                proper("Tsa", "Tsb"),
                (
                    "Tdgov",
                    lambda o: (v(o, "Kdgov") == 0) | (v(o, "Tdgov") > 0),
                    "must be > 0 where Kdgov != 0",
                ),
                (
                    "Ta",
                    lambda o: (v(o, "Ka") == 0) | (v(o, "Ta") > 0),
                    "must be > 0 where Ka != 0",
                ),
                ordered("minerr", "maxerr"),
                ordered("Vmin", "Vmax"),
                (
                    "Ropen",
                    lambda o: v(o, "Ropen") >= 0,
                    "must be >= 0 (an opening rate)",
                ),
                (
                    "Rclose",
                    lambda o: v(o, "Rclose") <= 0,
                    "must be <= 0 (a closing rate)",
                ),
                ("Rup", lambda o: v(o, "Rup") >= 0, "must be >= 0"),
                ("Rdown", lambda o: v(o, "Rdown") <= 0, "must be <= 0"),
            ],
        )

    @classmethod
    def from_params(cls, gen_positions, params):
        """`params[i]` holds Rselect and Flag (the ICONs), the CONs and MBASE (the
        machine's MVA base, added by `case.build_case`)."""
        return build_group(
            cls,
            gen_positions,
            [{**p, "mbase": p.get("MBASE", p.get("mbase"))} for p in params],
            ("mbase", "Rselect", "Flag", *cls.con_names),
        )

    # --- the pieces, in pu of Trate ------------------------------------------
    def _k(self):
        """MBASE / Trate (Trate = 0: 1)."""
        on = self.Trate > 0
        return jnp.where(on, self.mbase / jnp.where(on, self.Trate, 1.0), 1.0)

    def _speed_factor(self, w):
        return jnp.where(self.Flag == 1, 1.0 + w, 1.0)

    def _temp_factor(self, w):
        dm = jnp.minimum(self.Dm, 0.0)
        return jnp.where(self.Dm < 0, jnp.power(1.0 + w, dm), 1.0)

    def _f(self, x, meas, ref):
        w = meas["omega"]
        pe_t = meas["Pe"] * self._k()
        pref, pmwset, vmin, vmax, ceiling, ld = ref
        (pe_x, x_mw, x_d, x_i, fsr_d, x_w, stroke, x_tb, x_ts, texm, x_l) = x
        pe, d_pe = lag(pe_x, pe_t, 1.0, self.Tpelec)
        d_mw = nonwindup(x_mw, self.Kimw * (pmwset - pe), -1.1 * self.R, 1.1 * self.R)
        fb = jnp.select(
            [self.Rselect == 1, self.Rselect == -1, self.Rselect == -2],
            [pe, fsr_d, stroke],
            0.0 * pe,
        )
        err = pref + x_mw - w - self.R * fb
        dz = jnp.where(
            err > self.db, err - self.db, jnp.where(err < -self.db, err + self.db, 0.0)
        )
        e = jnp.clip(dz, self.minerr, self.maxerr)
        y_d, d_d = washout(x_d, e, self.Kdgov, self.Tdgov)
        fsrn = self.Kpgov * e + x_i + y_d
        # acceleration limiter
        ta_on = self.Ta > 0
        accel = jnp.where(ta_on, (w - x_w) / jnp.where(ta_on, self.Ta, 1.0), 0.0)
        d_w = accel  # s/(1 + s Ta): Ta dx_w/dt = omega - x_w, output (omega - x_w)/Ta
        fsra = jnp.where(
            self.Ka > 0, fsr_d + self.Ka * DELT * (self.Aset - accel), jnp.inf
        )
        # load limiter on the exhaust temperature
        wf = stroke * self._speed_factor(w)
        y_ts, d_ts = leadlag(x_ts, wf * self._temp_factor(w), self.Tsa, self.Tsb)
        t_out, d_tf = lag(texm, y_ts, 1.0, self.Tfload)
        fsrt = jnp.minimum(x_l + self.Kpload * (ld - t_out), ceiling)
        fsr = jnp.clip(jnp.minimum(jnp.minimum(fsrn, fsrt), fsra), vmin, vmax)
        kp_on = self.Kpgov > 0
        d_i = jnp.where(
            kp_on,
            self.Kigov / jnp.where(kp_on, self.Kpgov, 1.0) * (fsr - x_i),
            self.Kigov * e,
        )
        d_l = jnp.clip(self.Kiload / self.Kpload * (fsr - x_l), self.Rdown, self.Rup)
        d_fsr = (fsr - fsr_d) / DELT
        d_stroke = jnp.clip((fsr - stroke) / self.Tact, self.Rclose, self.Ropen)
        # turbine
        y_tb, d_tb = leadlag(x_tb, self.Kturb * (wf - self.Wfnl), self.Tc, self.Tb)
        pm_t = y_tb - jnp.where(self.Dm > 0, self.Dm * w, 0.0)
        dx = jnp.stack(
            [d_pe, d_mw, d_d, d_i, d_fsr, d_w, d_stroke, d_tb, d_ts, d_tf, d_l]
        )
        return pm_t / self._k(), dx

    def init(self, y0, meas):
        w = meas["omega"]
        k = self._k()
        pe_t = meas["Pe"] * k
        pt0 = y0 * k + jnp.where(self.Dm > 0, self.Dm * w, 0.0)
        wf0 = pt0 / self.Kturb + self.Wfnl
        s0 = wf0 / self._speed_factor(w)
        t0 = wf0 * self._temp_factor(w)
        require_at_rest(
            s0 > 0,
            "GGOV1",
            "Pm0",
            y0,
            "the operating point's valve stroke (Pm0 MBASE/Trate)/Kturb + Wfnl must "
            "be > 0",
        )
        fb0 = jnp.select(
            [self.Rselect == 1, self.Rselect == -1, self.Rselect == -2],
            [pe_t, s0, s0],
            0.0 * s0,
        )
        zero = 0.0 * s0
        x0 = jnp.stack(
            [
                pe_t,  # pe
                zero,  # x_mw
                zero,  # x_d
                s0,  # x_i
                s0,  # fsr_d
                w + zero,  # x_w
                s0,  # stroke
                self.Kturb * (wf0 - self.Wfnl),  # x_tb
                t0,  # x_ts
                t0,  # texm
                s0,  # x_l
            ]
        )
        # limits the operating point lies beyond move to it (the unit starts on them)
        ref = jnp.stack(
            [
                w + self.R * fb0,  # Pref
                pe_t,  # Pmwset
                jnp.minimum(self.Vmin, s0),
                jnp.maximum(self.Vmax, s0),
                jnp.maximum(1.0, s0),  # the load limiter's ceiling
                jnp.maximum(self.Ldref / self.Kturb + self.Wfnl, t0),  # its reference
            ]
        )
        return x0, ref

    def rhs(self, x, meas, ref):
        return self._f(x, meas, ref)[1]

    def out(self, x, meas, ref):
        return self._f(x, meas, ref)[0]
