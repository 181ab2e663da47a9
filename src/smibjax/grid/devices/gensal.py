"""GENSAL: PSS/E's salient-pole machine (field and one damper winding on the d axis,
one damper winding on the q axis, subtransient X''d = X''q), with saturation of the
d axis only, as a function of E'q.

States x = (delta, omega, e1q, e2d, e2q) in GENROU's names (`genrou.py`): e1q = E'q,
e2d = PSS/E's psi_kd (the d-axis damper flux) and e2q = PSS/E's psi''q (the q-axis
subtransient flux, in the sign of GENROU's psi2q: the d-axis component of the source
E''). With

    gd1 = (X''d - Xl)/(X'd - Xl),  gd2 = (X'd - X''d)/(X'd - Xl)^2

the d-axis subtransient flux is psi2d = gd1 e1q + (1 - gd1) e2d, and (PSS/E Model
Library, GENSAL; OpenIPSL's PSSE.GENSAL and PowerSimulationsDynamics.jl's
SalientPoleQuadratic write the same equations)

    XadIfd = e1q + (Xd - X'd)(gd1 Id - gd2 e2d + gd2 e1q) + Se(e1q) e1q
    T'do  d e1q/dt = Efd - XadIfd
    T''do d e2d/dt = -e2d + e1q - (X'd - Xl) Id
    T''qo d e2q/dt = -e2q + (Xq - X''d) Iq

(XadIfd written as GENROU's; PSS/E's K1d (e1q - e2d - (X'd - Xl) Id) + (Xd - X'd) Id
+ (1 + Se) e1q is the same, since 1 - gd2 (X'd - Xl) = gd1). Saturation is the d-axis
term Se(e1q) e1q only: the quadratic fit for GENSAL, the exponential one for GENSAE
(`gensae.py`, `saturation.py`). The stator, the network interface (E'' = e2q + j psi2d
of the rotor frame behind Ra + j X''d), the torque Te = e2q Id + psi2d Iq and the
swing equation are GENROU's (PSS/E's speed factor on the mechanical power,
docs/machines.md).

Limit: with Se = 0, GENROU with X'q = X''d and T'qo = GENSAL's T''qo is this model
(GENROU's e1d is then GENSAL's e2q, and GENROU's q-axis damper e2q drops out of the
flux); tests/test_machines.py checks it.

Initialisation (closed form): I = conj(s / v) (machine base), E'' = V + (Ra + j X'')
I; at rest e2q = (Xq - X'') Iq, so E'' + j (Xq - X'') I = V + (Ra + j Xq) I lies on
the q axis: delta = its angle. Then e2q, psi2d = the rotor-frame components of E'',
e1q = psi2d + (X'd - X'') Id, e2d = e1q - (X'd - Xl) Id, Efd = (1 + Se(e1q)) e1q +
(Xd - X'd) Id, Pm = Te.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import is_concrete, require
from ._dq import from_dq, swing, to_dq
from .base import AbstractMachine, f64, i64
from .saturation import check_saturation, saturation_factor

__all__ = ["GENSAL"]


class GENSAL(AbstractMachine):
    gen: np.ndarray = eqx.field(converter=i64)
    mbase: np.ndarray = eqx.field(converter=f64)  # machine base (MVA)
    H: np.ndarray = eqx.field(converter=f64)  # inertia constant (s, machine base)
    D: np.ndarray = eqx.field(converter=f64)  # damping (pu power / pu speed)
    Tdop: np.ndarray = eqx.field(converter=f64)  # T'do (s)
    Tdopp: np.ndarray = eqx.field(converter=f64)  # T''do (s)
    Tqopp: np.ndarray = eqx.field(converter=f64)  # T''qo (s)
    xd: np.ndarray = eqx.field(converter=f64)  # Xd (pu machine base)
    xq: np.ndarray = eqx.field(converter=f64)  # Xq (pu machine base)
    xdp: np.ndarray = eqx.field(converter=f64)  # X'd (pu machine base)
    xdpp: np.ndarray = eqx.field(converter=f64)  # X''d = X''q (pu machine base)
    xl: np.ndarray = eqx.field(converter=f64)  # leakage reactance Xl (pu machine base)
    ra: np.ndarray = eqx.field(converter=f64)  # armature resistance (pu machine base)
    S10: np.ndarray = eqx.field(converter=f64, default=0.0)  # Se(1.0)
    S12: np.ndarray = eqx.field(converter=f64, default=0.0)  # Se(1.2)
    saturation: str = eqx.field(static=True, default="quadratic")  # Se's fit
    f_base: float = eqx.field(static=True, default=60.0)  # frequency (Hz)
    # PSS/E's swing equation, Tm = (Pm - D omega)/(1 + omega) (`_dq.swing`); False:
    # ANDES's, Tm = Pm - D omega (for comparisons with ANDES)
    speed_factor: bool = eqx.field(static=True, default=True)

    @classmethod
    def from_params(cls, gen, params, *, mbase, zsource, f_base=60.0):
        """From dyr records (PSS/E names, `psse.DYR_MODELS["GENSAL"]`) and the raw
        file's ZR (armature resistance, machine base)."""

        def col(name):
            return [p[name] for p in params]

        return cls(
            gen=gen,
            mbase=mbase,
            H=col("H"),
            D=col("D"),
            Tdop=col("Tdo_p"),
            Tdopp=col("Tdo_pp"),
            Tqopp=col("Tqo_pp"),
            xd=col("Xd"),
            xq=col("Xq"),
            xdp=col("Xd_p"),
            xdpp=col("Xd_pp"),
            xl=col("Xl"),
            ra=np.real(zsource),
            S10=col("S10"),
            S12=col("S12"),
            f_base=f_base,
        )

    state_names = ("delta", "omega", "e1q", "e2d", "e2q")

    def __check_init__(self):
        me = type(self).__name__  # GENSAL or GENSAE
        check_saturation(me, self.saturation, self.S10, self.S12)
        names = "mbase H D Tdop Tdopp Tqopp xd xq xdp xdpp xl ra".split()
        vals = {k: getattr(self, k) for k in names}
        if not is_concrete(*vals.values()):
            return
        v = {k: np.asarray(a, float) for k, a in vals.items()}
        for k in names:
            require(np.isfinite(v[k]), me, k, v[k], "must be finite")
        for k in ("mbase", "H", "Tdop", "Tdopp", "Tqopp"):
            require(v[k] > 0, me, k, v[k], "must be > 0")
        for k in ("D", "ra", "xl"):
            require(v[k] >= 0, me, k, v[k], "must be >= 0")
        order = (
            ("xdpp", "xl", "must be >= xl = {}"),
            ("xdp", "xdpp", "must be >= xdpp = {}"),
            ("xd", "xdp", "must be >= xdp = {}"),
            ("xq", "xdpp", "must be >= xdpp = {} (X''q = X''d)"),
        )
        for k, lo, allowed in order:
            require(v[k] >= v[lo], me, k, v[k], allowed, v[lo])
        require(v["xdp"] > v["xl"], me, "xdp", v["xdp"], "must be > xl = {}", v["xl"])

    # -- the model ---------------------------------------------------------------

    def _z(self):
        return self.ra + 1j * self.xdpp

    def _gammas(self):
        gd1 = (self.xdpp - self.xl) / (self.xdp - self.xl)
        gd2 = (self.xdp - self.xdpp) / (self.xdp - self.xl) ** 2
        return gd1, gd2

    def _psi2(self, x):
        """(psi2d, psi2q): the subtransient (air-gap) flux in the rotor frame (pu)."""
        gd1, _ = self._gammas()
        return gd1 * x[2] + (1 - gd1) * x[3], x[4]

    def _emf(self, x):
        """E'' = psi2q + j psi2d of the rotor frame, in the network frame (pu)."""
        psi2d, psi2q = self._psi2(x)
        return from_dq(psi2q, psi2d, x[0])

    def _se(self, psi):
        return saturation_factor(psi, self.S10, self.S12, self.saturation)

    def norton(self, x, held, s_base):
        y_m = 1.0 / self._z()
        scale = self.mbase / s_base
        return self._emf(x) * y_m * scale, y_m * scale

    def _xad_ifd(self, x, i_d):
        """XadIfd: the field current on the Xad base (pu), the d-axis rotor circuit's
        drive in T'do de1q/dt = Efd - XadIfd (equal to Efd at rest)."""
        e1q, e2d = x[2], x[3]
        gd1, gd2 = self._gammas()
        xad_ifd = e1q + (self.xd - self.xdp) * (gd1 * i_d - gd2 * e2d + gd2 * e1q)
        return xad_ifd + self._sat_d(x)

    def _sat_d(self, x):
        """The d-axis saturation term of XadIfd: Se(e1q) e1q (GENSAL)."""
        return self._se(x[2]) * x[2]

    def _sat_q(self, x):
        """The saturation term of T''qo d e2q/dt: none (GENSAL)."""
        return jnp.zeros_like(x[4])

    def measure(self, x, v, held, s_base):
        e = self._emf(x)
        i = (e - v) / self._z()  # machine base
        s = v * jnp.conj(i)
        i_d, _ = to_dq(i, x[0])
        return {
            "delta": x[0],
            "omega": x[1],
            "Pe": jnp.real(s),
            "Qe": jnp.imag(s),
            "Vt": jnp.abs(v),
            "It": jnp.abs(i),
            "Te": jnp.real(e * jnp.conj(i)),
            "XadIfd": self._xad_ifd(x, i_d),
        }

    def rhs(self, x, v, cmd, held, s_base):
        delta, omega, e1q, e2d, e2q = x
        psi2d, psi2q = self._psi2(x)
        e = from_dq(psi2q, psi2d, delta)
        i = (e - v) / self._z()
        i_d, i_q = to_dq(i, delta)
        te = psi2q * i_d + psi2d * i_q
        d_delta, d_omega = swing(
            omega, te, cmd["Pm"], self.H, self.D, self.f_base, self.speed_factor
        )
        return jnp.stack(
            [
                d_delta,
                d_omega,
                (cmd["Efd"] - self._xad_ifd(x, i_d)) / self.Tdop,
                (-e2d + e1q - (self.xdp - self.xl) * i_d) / self.Tdopp,
                (-e2q + (self.xq - self.xdpp) * i_q + self._sat_q(x)) / self.Tqopp,
            ]
        )

    def init(self, v, s, s_base):
        i = jnp.conj(s / v) * (s_base / self.mbase)  # machine base
        e = v + self._z() * i  # E'' (network frame)
        delta = jnp.angle(e + 1j * (self.xq - self.xdpp) * i)
        psi2q, psi2d = to_dq(e, delta)
        i_d, i_q = to_dq(i, delta)
        e1q = psi2d + (self.xdp - self.xdpp) * i_d
        e2d = e1q - (self.xdp - self.xl) * i_d
        efd = e1q + (self.xd - self.xdp) * i_d + self._se(e1q) * e1q
        x0 = jnp.stack([delta, jnp.zeros_like(delta), e1q, e2d, psi2q])
        return x0, {"Efd": efd, "Pm": psi2q * i_d + psi2d * i_q}
