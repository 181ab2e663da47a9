"""GENSAE: PSS/E's salient-pole machine with exponential saturation. The states,
the network interface, the torque and the swing equation are GENSAL's (`gensal.py`);
saturation differs in its fit and in where it acts (PSS/E Model Library, GENSAE;
OpenIPSL's PSSE.GENSAE, validated against PSS/E, writes the same): the factor is the
exponential fit Se(psi'') = S10 psi''^n, n = ln(S12 / S10) / ln 1.2 (`saturation.py`),
of the subtransient flux magnitude psi'' = |psi2d + j e2q| (= |E''|), not of E'q, and
it acts on both axes, as GENROU's:

    XadIfd = (GENSAL's linear terms) + Se(psi'') psi2d
    T''qo d e2q/dt = -e2q + (Xq - X''d) Iq - gqd Se(psi'') e2q,  gqd = (Xq - Xl)/(Xd - Xl)

S10 = 0 is no saturation (then GENSAE is GENSAL). PSS/E's own results for GENSAE
(tests/data/psse/GENSAE) start 2 degrees from GENSAL's rest angle and follow these
equations (docs/validation-psse.md); a d-axis-only Se(E'q) E'q (GENSAL's form with
the exponential fit, this module before, and PowerSimulationsDynamics.jl's
SalientPoleExponential) misses them by 0.035 rad.

Initialisation (closed form): I = conj(s / v) (machine base), E'' = V + (Ra + j X'')
I, Se = Se(|E''|) (|E''| is frame-invariant); at rest e2q (1 + gqd Se) = (Xq - X'') Iq,
so E'' + j Xs I with Xs = (Xq - X'') / (1 + gqd Se) lies on the q axis: delta = its
angle. Then e2q, psi2d = the rotor-frame components of E'', e1q = psi2d + (X'd - X'')
Id, e2d = e1q - (X'd - Xl) Id, Efd = e1q + (Xd - X'd) Id + Se psi2d, Pm = Te.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ._dq import to_dq
from .gensal import GENSAL

__all__ = ["GENSAE"]


class GENSAE(GENSAL):
    saturation: str = eqx.field(static=True, default="exponential")  # Se's fit

    def _gqd(self):
        return (self.xq - self.xl) / (self.xd - self.xl)

    def _se_psi(self, x):
        """Se(psi''): the saturation factor at the subtransient flux magnitude."""
        psi2d, psi2q = self._psi2(x)
        return self._se(jnp.sqrt(psi2d**2 + psi2q**2))

    def _sat_d(self, x):
        """The d-axis saturation term of XadIfd: Se(psi'') psi2d."""
        return self._se_psi(x) * self._psi2(x)[0]

    def _sat_q(self, x):
        """The q-axis saturation term of T''qo d e2q/dt: -gqd Se(psi'') e2q."""
        return -self._gqd() * self._se_psi(x) * x[4]

    def init(self, v, s, s_base):
        i = jnp.conj(s / v) * (s_base / self.mbase)  # machine base
        e = v + self._z() * i  # E'' (network frame)
        se = self._se(jnp.abs(e))
        xs = (self.xq - self.xdpp) / (1.0 + self._gqd() * se)
        delta = jnp.angle(e + 1j * xs * i)
        psi2q, psi2d = to_dq(e, delta)
        i_d, i_q = to_dq(i, delta)
        e1q = psi2d + (self.xdp - self.xdpp) * i_d
        e2d = e1q - (self.xdp - self.xl) * i_d
        efd = e1q + (self.xd - self.xdp) * i_d + se * psi2d
        x0 = jnp.stack([delta, jnp.zeros_like(delta), e1q, e2d, psi2q])
        return x0, {"Efd": efd, "Pm": psi2q * i_d + psi2d * i_q}
