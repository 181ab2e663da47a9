"""GENCLS: the classical machine, a constant EMF E' behind the transient reactance
X'd (PSS/E record `GENCLS`: H, D).

    d delta/dt = omega_b omega
    2 H d omega/dt = Pm - Pe - D omega,    Pe = Re(E' conj(I)) (pu machine base)

with omega the speed deviation (pu), omega_b = 2 pi f_base, I = (E' - V) / (Ra + j X'd)
the stator current; E' = |E'| e^{j delta} in the network frame. X'd and Ra come from
the raw file's generator record (ZX, ZR, on the machine base), as PSS/E takes them.
Torque and power are equal in per unit (no speed factor), as in ANDES.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._validate import MAX_MAGNITUDE, is_concrete, require
from .base import AbstractMachine, f64, i64

__all__ = ["GENCLS"]


class GENCLS(AbstractMachine):
    gen: np.ndarray = eqx.field(converter=i64)
    mbase: np.ndarray = eqx.field(converter=f64)  # machine base (MVA)
    H: np.ndarray = eqx.field(converter=f64)  # inertia constant (s, machine base)
    D: np.ndarray = eqx.field(converter=f64)  # damping (pu power / pu speed)
    xdp: np.ndarray = eqx.field(converter=f64)  # X'd (pu machine base)
    ra: np.ndarray = eqx.field(converter=f64)  # armature resistance (pu machine base)
    f_base: float = eqx.field(static=True, default=60.0)

    state_names = ("delta", "omega")

    def __check_init__(self):
        names = ("mbase", "H", "D", "xdp", "ra")
        vals = {k: getattr(self, k) for k in names}
        if not is_concrete(*vals.values()):
            return
        v = {k: np.asarray(a, float) for k, a in vals.items()}
        big = f"must be finite and at most {MAX_MAGNITUDE:g}"
        for k in names:
            require(
                np.isfinite(v[k]) & (np.abs(v[k]) <= MAX_MAGNITUDE),
                "GENCLS",
                k,
                v[k],
                big,
            )
        for k in ("mbase", "H"):  # H = 0 is an infinite bus, not a machine
            require(v[k] > 0, "GENCLS", k, v[k], "must be > 0")
        require(v["D"] >= 0, "GENCLS", "D", v["D"], "must be >= 0")
        require(
            v["ra"] >= 0, "GENCLS", "ra", v["ra"], "must be >= 0 (the raw file's ZR)"
        )
        require(
            v["xdp"] > 0,
            "GENCLS",
            "xdp",
            v["xdp"],
            "must be > 0 (the raw file's ZX: X'd)",
        )

    @classmethod
    def from_params(cls, gen, params, *, mbase, zsource, f_base=60.0):
        """From dyr records (H, D) and the raw file's source impedance (X'd = ZX,
        Ra = ZR on the machine base)."""
        return cls(
            gen=gen,
            mbase=mbase,
            H=[p["H"] for p in params],
            D=[p["D"] for p in params],
            xdp=np.imag(zsource),
            ra=np.real(zsource),
            f_base=f_base,
        )

    def _z(self):
        return self.ra + 1j * self.xdp

    def norton(self, x, held, s_base):
        y_m = 1.0 / self._z()
        e = held["Efd"] * jnp.exp(1j * x[0])
        scale = self.mbase / s_base
        return e * y_m * scale, y_m * scale

    def measure(self, x, v, held, s_base):
        e = held["Efd"] * jnp.exp(1j * x[0])  # |E'| is constant: held["Efd"]
        i = (e - v) / self._z()  # machine base: v and e in pu voltage
        s = v * jnp.conj(i)
        return {
            "delta": x[0],
            "omega": x[1],
            "Pe": jnp.real(s),
            "Qe": jnp.imag(s),
            "Vt": jnp.abs(v),
            "It": jnp.abs(i),
            "Te": jnp.real(e * jnp.conj(i)),
            # no field circuit: the constant |E'| stands for the field current on the
            # Xad base (what XadIfd is at rest on the other machines)
            "XadIfd": held["Efd"],
        }

    def rhs(self, x, v, cmd, held, s_base):
        m = self.measure(x, v, held, s_base)
        wb = 2 * np.pi * self.f_base
        d_delta = wb * x[1]
        d_omega = (cmd["Pm"] - m["Te"] - self.D * x[1]) / (2 * self.H)
        return jnp.stack([d_delta, d_omega])

    def init(self, v, s, s_base):
        i = jnp.conj(s / v) * (s_base / self.mbase)  # machine base
        e = v + self._z() * i
        x0 = jnp.stack([jnp.angle(e), jnp.zeros_like(jnp.real(e))])
        pm = jnp.real(e * jnp.conj(i))
        return x0, {"Pm": pm, "Efd": jnp.abs(e)}
