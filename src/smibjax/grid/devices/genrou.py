"""GENROU: PSS/E's round-rotor machine (field and one damper winding on the d axis,
two damper windings on the q axis, subtransient X''d = X''q), with saturation of the
air-gap flux.

We follow ANDES's `GENROU` (andes/models/synchronous/genrou.py with `GENBase` and
`Flux0` of genbase.py, ANDES 2.0) equation for equation, in its state variables:
x = (delta, omega, e1q, e1d, e2d, e2q), where e1q = E'q, e1d = E'd, e2d is the d-axis
damper flux (PSS/E's psi_kd) and e2q the q-axis damper flux (PSS/E's psi_kq, in
ANDES's q-axis sign). With

    gd1 = (X''d - Xl)/(X'd - Xl),  gq1 = (X''q - Xl)/(X'q - Xl),
    gd2 = (X'd - X''d)/(X'd - Xl)^2,  gq2 = (X'q - X''q)/(X'q - Xl)^2,
    gqd = (Xq - Xl)/(Xd - Xl),

the subtransient (air-gap) flux and its saturation are

    psi2d = gd1 e1q + (1 - gd1) e2d,      psi2q = gq1 e1d + (1 - gq1) e2q,
    psi2 = |psi2d + j psi2q|,             Se = Se(psi2)     (`saturation.py`)

and the rotor

    XadIfd = e1q + (Xd - X'd)(gd1 Id - gd2 e2d + gd2 e1q) + Se psi2d
    XaqI1q = e1d + (Xq - X'q)(gq2 e1d - gq2 e2q - gq1 Iq) + gqd Se psi2q
    T'do  d e1q/dt = Efd - XadIfd
    T'qo  d e1d/dt = -XaqI1q
    T''do d e2d/dt = -e2d + e1q - (X'd - Xl) Id
    T''qo d e2q/dt = -e2q + e1d + (X'q - Xl) Iq

so saturation enters the d axis as Se psi2d and the q axis as gqd Se psi2q (PSS/E's
GENROU: the q axis saturates in the ratio (Xq - Xl)/(Xd - Xl)). The stator is
algebraic with no speed factor (ANDES `Flux0`): psid = psi2d - X''d Id = vq + Ra Iq,
psiq = -X''q Iq - psi2q = -(vd + Ra Id), i.e. in the rotor frame (`_dq`)

    vd + j vq = (psi2q + j psi2d) - (Ra + j X'') (Id + j Iq)     (X'' = X''d = X''q)

which is the Norton source of the network interface: E'' = psi2q + j psi2d, rotated
into the network frame by delta, behind Ra + j X''. Electrical torque
Te = psid Iq - psiq Id = psi2q Id + psi2d Iq (= Pe + Ra |I|^2), and PSS/E's swing
equation: d delta/dt = omega_b omega, 2 H d omega/dt = (Pm - D omega)/(1 + omega) - Te
(omega the per-unit speed deviation; `_dq.swing` with its speed factor: the turbine's
power Pm is a torque Pm/(1 + omega) at the rotor's speed).

Differences from ANDES: ANDES's swing equation has no speed factor, 2 H d omega/dt =
Pm - Te - D omega (omega - 1 in its notation, M = 2H); PSS/E's own results for this
model follow the speed factor (a line trip: 7.9e-4 rad from PSS/E without it, 6.5e-5
with it; docs/validation-psse.md). S10 = 0 is no saturation in both (PSS/E's
convention). `saturation="exponential"` (Se = S10 psi^n) is PSS/E's GENROE
(`GENROE`: this class with that fit). X''q is not a separate dyr parameter (PSS/E's
GENROU takes X''d for both); a different `xqpp` is refused with one line.

Initialisation is closed form, so it is jittable and differentiable without Newton
steps: |E''| = |V + (Ra + j X'') I| is frame-invariant, so Se is known; at rest
psi2q (1 + gqd Se) = (Xq - X'') Iq, which puts W = (1 + gqd Se) E'' + j (Xq - X'') I on
the q axis: delta = arg W (ANDES's delta0 formula). The rotor fluxes follow linearly.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete, require
from ._dq import from_dq, swing, to_dq
from .base import AbstractMachine, f64, i64
from .saturation import check_saturation, saturation_factor

__all__ = ["GENROU"]


class GENROU(AbstractMachine):
    gen: np.ndarray = eqx.field(converter=i64)
    mbase: np.ndarray = eqx.field(converter=f64)  # machine base (MVA)
    H: np.ndarray = eqx.field(converter=f64)  # inertia constant (s, machine base)
    D: np.ndarray = eqx.field(converter=f64)  # damping (pu power / pu speed)
    Tdop: np.ndarray = eqx.field(converter=f64)  # T'do (s)
    Tdopp: np.ndarray = eqx.field(converter=f64)  # T''do (s)
    Tqop: np.ndarray = eqx.field(converter=f64)  # T'qo (s)
    Tqopp: np.ndarray = eqx.field(converter=f64)  # T''qo (s)
    xd: np.ndarray = eqx.field(converter=f64)  # Xd (pu machine base)
    xq: np.ndarray = eqx.field(converter=f64)  # Xq (pu machine base)
    xdp: np.ndarray = eqx.field(converter=f64)  # X'd (pu machine base)
    xqp: np.ndarray = eqx.field(converter=f64)  # X'q (pu machine base)
    xdpp: np.ndarray = eqx.field(converter=f64)  # X''d = X''q (pu machine base)
    xl: np.ndarray = eqx.field(converter=f64)  # leakage reactance Xl (pu machine base)
    ra: np.ndarray = eqx.field(converter=f64)  # armature resistance (pu machine base)
    S10: np.ndarray = eqx.field(converter=f64, default=0.0)  # Se(1.0)
    S12: np.ndarray = eqx.field(converter=f64, default=0.0)  # Se(1.2)
    # X''q: None takes X''d (PSS/E); any other value must equal X''d
    xqpp: np.ndarray | None = eqx.field(default=None)
    saturation: str = eqx.field(static=True, default="quadratic")  # Se's fit
    f_base: float = eqx.field(static=True, default=60.0)  # frequency (Hz)
    # PSS/E's swing equation, Tm = (Pm - D omega)/(1 + omega) (`_dq.swing`); False:
    # ANDES's, Tm = Pm - D omega (for comparisons with ANDES)
    speed_factor: bool = eqx.field(static=True, default=True)

    @classmethod
    def from_params(cls, gen, params, *, mbase, zsource, f_base=60.0):
        """From dyr records (PSS/E names, `psse.DYR_MODELS["GENROU"]`) and the raw
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
            Tqop=col("Tqo_p"),
            Tqopp=col("Tqo_pp"),
            xd=col("Xd"),
            xq=col("Xq"),
            xdp=col("Xd_p"),
            xqp=col("Xq_p"),
            xdpp=col("Xd_pp"),
            xl=col("Xl"),
            ra=np.real(zsource),
            S10=col("S10"),
            S12=col("S12"),
            f_base=f_base,
        )

    state_names = ("delta", "omega", "e1q", "e1d", "e2d", "e2q")

    def __check_init__(self):
        me = type(self).__name__  # GENROU or GENROE
        check_saturation(me, self.saturation, self.S10, self.S12)
        names = "mbase H D Tdop Tdopp Tqop Tqopp xd xq xdp xqp xdpp xl ra".split()
        vals = {k: getattr(self, k) for k in names}
        if not is_concrete(*vals.values(), self.xqpp):
            return
        v = {k: np.asarray(a, float) for k, a in vals.items()}
        for k in names:
            require(np.isfinite(v[k]), me, k, v[k], "must be finite")
        for k in ("mbase", "H", "Tdop", "Tdopp", "Tqop", "Tqopp"):
            require(v[k] > 0, me, k, v[k], "must be > 0")
        for k in ("D", "ra", "xl"):
            require(v[k] >= 0, me, k, v[k], "must be >= 0")
        order = (
            ("xdpp", "xl", "must be >= xl = {}"),
            ("xdp", "xdpp", "must be >= xdpp = {}"),
            ("xqp", "xdpp", "must be >= xdpp = {} (X''q = X''d)"),
            ("xd", "xdp", "must be >= xdp = {}"),
            ("xq", "xqp", "must be >= xqp = {}"),
        )
        for k, lo, allowed in order:
            require(v[k] >= v[lo], me, k, v[k], allowed, v[lo])
        for k in ("xdp", "xqp"):
            require(v[k] > v["xl"], me, k, v[k], "must be > xl = {}", v["xl"])
        if self.xqpp is not None:
            q = np.asarray(self.xqpp, float)
            if not np.allclose(q, v["xdpp"], rtol=0, atol=1e-12):
                raise ParameterError(
                    f"{me}.xqpp = {q} is not allowed: {me} assumes X''q = X''d "
                    f"= {v['xdpp']} (PSS/E's dyr record has one X''d)"
                )

    # -- the model ---------------------------------------------------------------

    def _z(self):
        return self.ra + 1j * self.xdpp

    def _gammas(self):
        gd1 = (self.xdpp - self.xl) / (self.xdp - self.xl)
        gq1 = (self.xdpp - self.xl) / (self.xqp - self.xl)
        gd2 = (self.xdp - self.xdpp) / (self.xdp - self.xl) ** 2
        gq2 = (self.xqp - self.xdpp) / (self.xqp - self.xl) ** 2
        gqd = (self.xq - self.xl) / (self.xd - self.xl)
        return gd1, gq1, gd2, gq2, gqd

    def _psi2(self, x):
        """(psi2d, psi2q): the subtransient (air-gap) flux in the rotor frame (pu)."""
        gd1, gq1, _, _, _ = self._gammas()
        psi2d = gd1 * x[2] + (1 - gd1) * x[4]
        psi2q = gq1 * x[3] + (1 - gq1) * x[5]
        return psi2d, psi2q

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

    def _xad_ifd(self, x, i_d, se, psi2d):
        """XadIfd: the field current on the Xad base (pu), the d-axis rotor circuit's
        drive in T'do de1q/dt = Efd - XadIfd (equal to Efd at rest)."""
        e1q, e2d = x[2], x[4]
        gd1, _, gd2, _, _ = self._gammas()
        xad_ifd = e1q + (self.xd - self.xdp) * (gd1 * i_d - gd2 * e2d + gd2 * e1q)
        return xad_ifd + se * psi2d

    def measure(self, x, v, held, s_base):
        e = self._emf(x)
        i = (e - v) / self._z()  # machine base
        s = v * jnp.conj(i)
        psi2d, psi2q = self._psi2(x)
        i_d, _ = to_dq(i, x[0])
        se = self._se(jnp.sqrt(psi2d**2 + psi2q**2))
        return {
            "delta": x[0],
            "omega": x[1],
            "Pe": jnp.real(s),
            "Qe": jnp.imag(s),
            "Vt": jnp.abs(v),
            "It": jnp.abs(i),
            "Te": jnp.real(e * jnp.conj(i)),
            "XadIfd": self._xad_ifd(x, i_d, se, psi2d),
        }

    def rhs(self, x, v, cmd, held, s_base):
        delta, omega, e1q, e1d, e2d, e2q = x
        gd1, gq1, gd2, gq2, gqd = self._gammas()
        psi2d, psi2q = self._psi2(x)
        e = from_dq(psi2q, psi2d, delta)
        i = (e - v) / self._z()
        i_d, i_q = to_dq(i, delta)
        se = self._se(jnp.sqrt(psi2d**2 + psi2q**2))
        xad_ifd = self._xad_ifd(x, i_d, se, psi2d)
        xaq_i1q = e1d + (self.xq - self.xqp) * (gq2 * e1d - gq2 * e2q - gq1 * i_q)
        xaq_i1q = xaq_i1q + gqd * se * psi2q
        te = psi2q * i_d + psi2d * i_q
        d_delta, d_omega = swing(
            omega, te, cmd["Pm"], self.H, self.D, self.f_base, self.speed_factor
        )
        return jnp.stack(
            [
                d_delta,
                d_omega,
                (cmd["Efd"] - xad_ifd) / self.Tdop,
                -xaq_i1q / self.Tqop,
                (-e2d + e1q - (self.xdp - self.xl) * i_d) / self.Tdopp,
                (-e2q + e1d + (self.xqp - self.xl) * i_q) / self.Tqopp,
            ]
        )

    def init(self, v, s, s_base):
        _, _, _, _, gqd = self._gammas()
        i = jnp.conj(s / v) * (s_base / self.mbase)  # machine base
        e = v + self._z() * i  # E'' (network frame)
        se = self._se(jnp.abs(e))
        w = (1 + gqd * se) * e + 1j * (self.xq - self.xdpp) * i
        delta = jnp.angle(w)
        psi2q, psi2d = to_dq(e, delta)
        i_d, i_q = to_dq(i, delta)
        e1d = (self.xq - self.xqp) * i_q - gqd * se * psi2q
        e2q = e1d + (self.xqp - self.xl) * i_q
        e1q = psi2d + (self.xdp - self.xdpp) * i_d
        e2d = e1q - (self.xdp - self.xl) * i_d
        efd = e1q + (self.xd - self.xdp) * i_d + se * psi2d
        x0 = jnp.stack([delta, jnp.zeros_like(delta), e1q, e1d, e2d, e2q])
        return x0, {"Efd": efd, "Pm": psi2q * i_d + psi2d * i_q}
