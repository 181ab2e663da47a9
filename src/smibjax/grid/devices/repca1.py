"""REPCA1: the renewable plant controller (PSS/E `REPCA1`, WECC `REPC_A`; ICONs
IREG, BRCH_FROM, BRCH_TO, CKT, VCFlag, RefFlag, Fflag, CONs Tfltr, Kp, Ki, Tft,
Tfv, Vfrz, Rc, Xc, Kc, emax, emin, dbd1, dbd2, Qmax, Qmin, Kpg, Kig, Tp, fdbd1,
fdbd2, femax, femin, Pmax, Pmin, Tlag, Ddn, Dup). It writes the active power
reference Pref and the reactive command Qext of its electrical controller
(`reecb1`). All on the machine base; the plant's output is its generator's (the
branch fields must be 0).

    Vc     = VCFlag ? |V - (Rc + j Xc) I| : |V| + Kc Qe      compensated voltage
    Mflt:  Tfltr dMflt/dt = (RefFlag ? Vc : Qe) - Mflt
    e      = clip(deadband((RefFlag ? Vref : Qref) - Mflt, dbd1, dbd2), emin, emax)
    xQp:   PI Kp + Ki/s on e, non-windup [Qmin, Qmax]; frozen while |V| < Vfrz
    xLL:   Qext = (1 + s Tft)/(1 + s Tfv) (PI output)
    f      = the bus frequency deviation (pu): a first-order phase tracker,
             TF dtheta_f/dt = arg(V e^{-j theta_f}), f = arg(V e^{-j theta_f}) /
             (TF 2 pi f_base), TF = 0.02 s
    ferr   = deadband(-f, fdbd1, fdbd2)
    Pflt:  Tp dPflt/dt = Pe - Pflt
    xPp:   PI Kpg + Kig/s on clip(Pref0 + min(Ddn ferr, 0) + max(Dup ferr, 0) -
           Pflt, femin, femax), non-windup [Pmin, Pmax]
    Plag:  Tlag dPlag/dt = (PI output) - Plag;  Pref = Fflag ? Plag : Pref0

Deviations: the plant output is measured at the generator's terminal (IREG,
BRCH_FROM, BRCH_TO must be 0: a remote regulated bus or a branch flow is refused);
PSS/E's bus frequency (the network angle's filtered derivative) is the phase
tracker above.

At rest (`init`), for the electrical controller's Pref0, Qext0: Mflt = Qe0 (Qref
= Qe0) or Vc0 (Vref = Vc0), xQp = xLL = Qext0, Pflt = xPp = Plag = Pref0,
theta_f = arg V0; Qext0 outside [Qmin, Qmax] or Pref0 outside [Pmin, Pmax] is
refused (one line).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..psse import DYR_MODELS
from ._blocks import check, lag, leadlag, nonneg, proper, require_at_rest, v
from ._ibr import columns, deadband, pi_nonwindup
from .base import f64

__all__ = ["REPCA1", "TF_FREQ"]

TF_FREQ = 0.02  # the phase tracker's time constant (s)


def _flag(name):
    return (name, lambda o: np.isin(v(o, name), (0.0, 1.0)), "must be 0 or 1")


class REPCA1(eqx.Module):
    IREG: np.ndarray = eqx.field(converter=f64)  # regulated bus (0: own)
    BRCH_FROM: np.ndarray = eqx.field(converter=f64)  # measured branch (0: own)
    BRCH_TO: np.ndarray = eqx.field(converter=f64)
    VCFlag: np.ndarray = eqx.field(converter=f64)  # 1: line drop comp., 0: droop
    RefFlag: np.ndarray = eqx.field(converter=f64)  # 1: voltage, 0: Q control
    Fflag: np.ndarray = eqx.field(converter=f64)  # 1: P/frequency control on
    Tfltr: np.ndarray = eqx.field(converter=f64)  # V/Q filter (s)
    Kp: np.ndarray = eqx.field(converter=f64)  # V/Q PI
    Ki: np.ndarray = eqx.field(converter=f64)
    Tft: np.ndarray = eqx.field(converter=f64)  # lead (s)
    Tfv: np.ndarray = eqx.field(converter=f64)  # lag (s)
    Vfrz: np.ndarray = eqx.field(converter=f64)  # freeze below this voltage (pu)
    Rc: np.ndarray = eqx.field(converter=f64)  # line drop compensation (pu)
    Xc: np.ndarray = eqx.field(converter=f64)
    Kc: np.ndarray = eqx.field(converter=f64)  # reactive droop (pu V / pu Q)
    emax: np.ndarray = eqx.field(converter=f64)  # error limits (pu)
    emin: np.ndarray = eqx.field(converter=f64)
    dbd1: np.ndarray = eqx.field(converter=f64)  # error deadband (pu)
    dbd2: np.ndarray = eqx.field(converter=f64)
    Qmax: np.ndarray = eqx.field(converter=f64)  # Qext limits (pu)
    Qmin: np.ndarray = eqx.field(converter=f64)
    Kpg: np.ndarray = eqx.field(converter=f64)  # P PI
    Kig: np.ndarray = eqx.field(converter=f64)
    Tp: np.ndarray = eqx.field(converter=f64)  # P filter (s)
    fdbd1: np.ndarray = eqx.field(converter=f64)  # frequency deadband (pu)
    fdbd2: np.ndarray = eqx.field(converter=f64)
    femax: np.ndarray = eqx.field(converter=f64)  # P error limits (pu)
    femin: np.ndarray = eqx.field(converter=f64)
    Pmax: np.ndarray = eqx.field(converter=f64)  # Pref limits (pu)
    Pmin: np.ndarray = eqx.field(converter=f64)
    Tlag: np.ndarray = eqx.field(converter=f64)  # Pref lag (s)
    Ddn: np.ndarray = eqx.field(converter=f64)  # over-frequency droop (pu/pu)
    Dup: np.ndarray = eqx.field(converter=f64)  # under-frequency droop (pu/pu)
    f_base: float = eqx.field(static=True, default=60.0)

    state_names = ("theta_f", "Mflt", "xQp", "xLL", "Pflt", "xPp", "Plag")
    con_names = DYR_MODELS["REPCA1"]

    def __check_init__(self):
        remote = "must be 0 (a remote bus or branch measurement is not supported)"
        check(
            self,
            [
                *(_flag(f) for f in ("VCFlag", "RefFlag", "Fflag")),
                *(
                    (n, lambda o, n=n: v(o, n) == 0, remote)
                    for n in ("IREG", "BRCH_FROM", "BRCH_TO")
                ),
                *nonneg("Tfltr", "Tp", "Tlag"),
                proper("Tft", "Tfv"),
                ("Qmax", lambda o: v(o, "Qmax") >= v(o, "Qmin"), "must be >= Qmin"),
                ("Pmax", lambda o: v(o, "Pmax") >= v(o, "Pmin"), "must be >= Pmin"),
                ("emax", lambda o: v(o, "emax") >= v(o, "emin"), "must be >= emin"),
                ("femax", lambda o: v(o, "femax") >= v(o, "femin"), "must be >= femin"),
                ("dbd2", lambda o: v(o, "dbd2") >= v(o, "dbd1"), "must be >= dbd1"),
                ("fdbd2", lambda o: v(o, "fdbd2") >= v(o, "fdbd1"), "must be >= fdbd1"),
            ],
        )

    @classmethod
    def from_params(cls, params, f_base: float = 60.0):
        """The group from dyr parameter dicts (`psse.DYR_MODELS` names; the circuit
        id CKT is text and not kept)."""
        return cls(**columns(cls, params, cls.con_names, text=("CKT",)), f_base=f_base)

    def _vc(self, v_, i, qe):
        vm = jnp.abs(v_)
        drop = jnp.abs(v_ - (self.Rc + 1j * self.Xc) * i)
        return jnp.where(self.VCFlag > 0.5, drop, vm + self.Kc * qe)

    def control(self, x, v_, i, pe, qe, ref):
        """(Pref, Qext, dx/dt, signals) for the terminal voltage v_ (pu, network
        frame), the injected current i and output pe, qe (pu machine base).
        `signals`: the frequency deviation "freq" (pu)."""
        vm = jnp.abs(v_)
        e_th = jnp.angle(v_ * jnp.exp(-1j * x[0]))
        dth = e_th / TF_FREQ
        freq = dth / (2 * jnp.pi * self.f_base)
        volt = self.RefFlag > 0.5
        meas = jnp.where(volt, self._vc(v_, i, qe), qe)
        mflt, dm = lag(x[1], meas, 1.0, self.Tfltr)
        err = jnp.clip(
            deadband(ref["Xref"] - mflt, self.dbd1, self.dbd2), self.emin, self.emax
        )
        yq, dxq = pi_nonwindup(
            x[2], err, self.Kp, self.Ki, self.Qmin, self.Qmax, freeze=vm < self.Vfrz
        )
        qext, dll = leadlag(x[3], yq, self.Tft, self.Tfv)
        pflt, dpf = lag(x[4], pe, 1.0, self.Tp)
        ferr = deadband(-freq, self.fdbd1, self.fdbd2)
        droop = jnp.minimum(self.Ddn * ferr, 0.0) + jnp.maximum(self.Dup * ferr, 0.0)
        perr = jnp.clip(ref["Pref0"] + droop - pflt, self.femin, self.femax)
        yp, dxp = pi_nonwindup(x[5], perr, self.Kpg, self.Kig, self.Pmin, self.Pmax)
        plag, dpl = lag(x[6], yp, 1.0, self.Tlag)
        fon = self.Fflag > 0.5
        pref = jnp.where(fon, plag, ref["Pref0"])
        dx = jnp.stack(
            [dth, dm, dxq, dll, dpf, jnp.where(fon, dxp, 0.0), jnp.where(fon, dpl, 0.0)]
        )
        return pref, qext, dx, {"freq": freq}

    def init(self, v_, i, pe, qe, pref0, qext0):
        """(x0, ref) for the electrical controller's Pref0, Qext0 at rest."""
        require_at_rest(
            (qext0 >= self.Qmin) & (qext0 <= self.Qmax),
            "REPCA1",
            "Qmax",
            self.Qmax,
            "the operating point's reactive command Qext0 must lie within [Qmin, Qmax]",
        )
        require_at_rest(
            (self.Fflag < 0.5) | ((pref0 >= self.Pmin) & (pref0 <= self.Pmax)),
            "REPCA1",
            "Pmax",
            self.Pmax,
            "the operating point's active power must lie within [Pmin, Pmax]",
        )
        meas0 = jnp.where(self.RefFlag > 0.5, self._vc(v_, i, qe), qe)
        z = 0.0 * pe
        x0 = jnp.stack(
            [
                jnp.angle(v_) + z,
                meas0 + z,
                qext0 + z,
                qext0 + z,
                pe + z,
                pref0 + z,
                pref0 + z,
            ]
        )
        return x0, {"Xref": meas0 + z, "Pref0": pref0 + z}
