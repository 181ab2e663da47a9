"""GENSAE: PSS/E's salient-pole machine with exponential saturation. The equations,
states, network interface and initialisation are GENSAL's (`gensal.py`); only the
saturation factor differs: Se(e1q) = S10 e1q^n with n = ln(S12 / S10) / ln 1.2
(`saturation.py`; PSS/E Model Library, GENSAE; OpenIPSL's PSSE.GENSAE,
PowerSimulationsDynamics.jl's SalientPoleExponential), on the d axis only as
Se(e1q) e1q in the field current. S10 = 0 is no saturation."""

from __future__ import annotations

import equinox as eqx

from .gensal import GENSAL

__all__ = ["GENSAE"]


class GENSAE(GENSAL):
    saturation: str = eqx.field(static=True, default="exponential")  # Se's fit
