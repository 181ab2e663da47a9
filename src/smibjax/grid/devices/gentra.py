"""GENTRA: the one-axis (flux-decay) machine, PSS/E's transient-level model without
damper windings: the transient EMF E'q on the q axis behind X'd, no q-axis rotor
circuit, and the swing equation of GENCLS.

States x = (delta, omega, e1q):

    d delta/dt = omega_b omega
    2 H d omega/dt = Pm - Te - D omega,        Te = e1q Iq          (pu machine base)
    T'do d e1q/dt = Efd - e1q - (Xd - X'd) Id - Se(e1q) e1q

with (Id, Iq) the stator current in the rotor frame (`_dq`: q axis at delta), omega
the per-unit speed deviation, omega_b = 2 pi f_base, and Se the saturation factor of
the dyr's S(1.0), S(1.2) (`saturation.py`; "quadratic" by default) taken on e1q, the
one d-axis rotor flux this model has. The stator is algebraic and speed effects on the
stator voltage are ignored (ANDES's `Flux0` choice):

    vd = -Ra Id + Xq Iq,     vq = e1q - Ra Iq - X'd Id.

Network interface. With Xq = X'd the stator is the source E' = e1q e^{j delta} behind
Ra + j X'd, exactly, and the machine is that Norton source at its terminal bus. With
Xq != X'd (transient saliency) the stator adds (Xq - X'd) Iq on the d axis, a term in
the current that no complex (rotation-invariant) admittance represents; PSS/E treats
it as an extra current injection iterated with the network solution, which the
machine interface (`norton(x)` before the network solve) has no place for. This model
refuses Xq != X'd with one line rather than approximate it.

Against the paper (docs/model.md section 1, T0 = T'do): with Xq = X'd, Ra = 0, Se = 0 and
the terminal tied to an infinite bus V through a reactance X, Id = (e1q - V cos delta)
/ Xs with Xs = X'd + X, so T'do d e1q/dt = Efd - (Xd + X)/Xs e1q + (Xd - X'd)/Xs V cos
delta: the paper's dE/dt with Xds = Xd + X and u_f = Efd (tests/test_machines.py).
The paper's D (pu power per rad/s) is this D / omega_b.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete, require
from ._dq import from_dq, swing, to_dq
from .base import AbstractMachine, f64, i64
from .saturation import check_saturation, saturation_factor

__all__ = ["GENTRA"]


class GENTRA(AbstractMachine):
    gen: np.ndarray = eqx.field(converter=i64)
    mbase: np.ndarray = eqx.field(converter=f64)  # machine base (MVA)
    H: np.ndarray = eqx.field(converter=f64)  # inertia constant (s, machine base)
    D: np.ndarray = eqx.field(converter=f64)  # damping (pu power / pu speed)
    Tdop: np.ndarray = eqx.field(converter=f64)  # T'do: d-axis open-circuit (s)
    xd: np.ndarray = eqx.field(converter=f64)  # Xd (pu machine base)
    xq: np.ndarray = eqx.field(converter=f64)  # Xq (pu machine base), must equal X'd
    xdp: np.ndarray = eqx.field(converter=f64)  # X'd (pu machine base)
    ra: np.ndarray = eqx.field(converter=f64)  # armature resistance (pu machine base)
    S10: np.ndarray = eqx.field(converter=f64, default=0.0)  # Se(1.0)
    S12: np.ndarray = eqx.field(converter=f64, default=0.0)  # Se(1.2)
    saturation: str = eqx.field(static=True, default="quadratic")  # Se's fit
    f_base: float = eqx.field(static=True, default=60.0)  # frequency (Hz)

    @classmethod
    def from_params(cls, gen, params, *, mbase, zsource, f_base=60.0):
        """From dyr records (PSS/E names, `psse.DYR_MODELS["GENTRA"]`) and the raw
        file's ZR (armature resistance, machine base)."""

        def col(name):
            return [p[name] for p in params]

        return cls(
            gen=gen,
            mbase=mbase,
            H=col("H"),
            D=col("D"),
            Tdop=col("Tdo_p"),
            xd=col("Xd"),
            xq=col("Xq"),
            xdp=col("Xd_p"),
            ra=np.real(zsource),
            S10=col("S10"),
            S12=col("S12"),
            f_base=f_base,
        )

    state_names = ("delta", "omega", "e1q")

    def __check_init__(self):
        check_saturation("GENTRA", self.saturation, self.S10, self.S12)
        vals = [self.mbase, self.H, self.D, self.Tdop, self.xd, self.xq, self.xdp]
        if not is_concrete(*vals, self.ra):
            return
        n = lambda v: np.asarray(v, float)  # noqa: E731
        for name in ("mbase", "H", "Tdop", "xdp"):
            v = n(getattr(self, name))
            require(np.isfinite(v) & (v > 0), "GENTRA", name, v, "must be > 0")
        for name in ("D", "ra"):
            v = n(getattr(self, name))
            require(np.isfinite(v) & (v >= 0), "GENTRA", name, v, "must be >= 0")
        require(
            np.isfinite(n(self.xd)) & (n(self.xd) >= n(self.xdp)),
            "GENTRA",
            "xd",
            self.xd,
            "must be >= xdp = {}",
            self.xdp,
        )
        if not np.allclose(n(self.xq), n(self.xdp), rtol=0, atol=1e-12):
            raise ParameterError(
                f"GENTRA.xq = {np.asarray(self.xq)} is not allowed: transient "
                f"saliency (Xq != X'd = {np.asarray(self.xdp)}) is not modelled; "
                "set Xq = X'd"
            )

    def _z(self):
        return self.ra + 1j * self.xdp

    def _emf(self, x):
        """E' in the network frame (pu): e1q on the q axis."""
        return from_dq(0.0, x[2], x[0])

    def norton(self, x, held, s_base):
        y_m = 1.0 / self._z()
        scale = self.mbase / s_base
        return self._emf(x) * y_m * scale, y_m * scale

    def measure(self, x, v, held, s_base):
        i = (self._emf(x) - v) / self._z()  # machine base
        s = v * jnp.conj(i)
        _, iq = to_dq(i, x[0])
        return {
            "delta": x[0],
            "omega": x[1],
            "Pe": jnp.real(s),
            "Qe": jnp.imag(s),
            "Vt": jnp.abs(v),
            "It": jnp.abs(i),
            "Te": x[2] * iq,
            "XadIfd": self._xad_ifd(x, to_dq(i, x[0])[0]),
        }

    def _xad_ifd(self, x, i_d):
        """XadIfd: the field current on the Xad base (pu), T'do de1q/dt = Efd -
        XadIfd (equal to Efd at rest)."""
        e1q = x[2]
        return e1q + (self.xd - self.xdp) * i_d + self._se(e1q) * e1q

    def _se(self, psi):
        return saturation_factor(psi, self.S10, self.S12, self.saturation)

    def rhs(self, x, v, cmd, held, s_base):
        i = (self._emf(x) - v) / self._z()
        i_d, i_q = to_dq(i, x[0])
        e1q = x[2]
        d_delta, d_omega = swing(
            x[1], e1q * i_q, cmd["Pm"], self.H, self.D, self.f_base
        )
        sat = self._se(e1q) * e1q
        d_e1q = (cmd["Efd"] - e1q - (self.xd - self.xdp) * i_d - sat) / self.Tdop
        return jnp.stack([d_delta, d_omega, d_e1q])

    def init(self, v, s, s_base):
        i = jnp.conj(s / v) * (s_base / self.mbase)  # machine base
        e = v + self._z() * i
        delta = jnp.angle(e)
        e1q = jnp.abs(e)
        i_d, i_q = to_dq(i, delta)
        efd = e1q + (self.xd - self.xdp) * i_d + self._se(e1q) * e1q
        x0 = jnp.stack([delta, jnp.zeros_like(delta), e1q])
        return x0, {"Efd": efd, "Pm": e1q * i_q}
