"""GENROE: PSS/E's round-rotor machine with exponential saturation. The equations,
states, network interface and initialisation are GENROU's (`genrou.py`); only the
saturation factor of the air-gap flux differs: Se(psi2) = S10 psi2^n with
n = ln(S12 / S10) / ln 1.2 (`saturation.py`; PSS/E Model Library, GENROE; OpenIPSL's
PSSE.GENROE), again on the d axis as Se psi2d and on the q axis as
(Xq - Xl)/(Xd - Xl) Se psi2q. S10 = 0 is no saturation."""

from __future__ import annotations

import equinox as eqx

from .genrou import GENROU

__all__ = ["GENROE"]


class GENROE(GENROU):
    saturation: str = eqx.field(static=True, default="exponential")  # Se's fit
