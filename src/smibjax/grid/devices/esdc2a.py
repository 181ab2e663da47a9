"""ESDC2A and ESDC1A: the IEEE 421.5-2005 types DC2A and DC1A DC commutator
exciters (ESDC1A: constant regulator limits [VRMIN, VRMAX], IEEEX1's diagram; PSS/E
`ESDC1A`, the same CONs). ESDC2A has a bus-fed
regulator (PSS/E `ESDC2A`, CONs TR, KA, TA, TB, TC, VRMAX, VRMIN, KE, TE, KF, TF1,
Switch, E1, SE(E1), E2, SE(E2); ANDES `ESDC2A`).

The block diagram is EXDC2's (`ieeex1`): sensing lag on the regulated voltage Vc,
lead-lag (1 + s TC)/(1 + s TB), regulator KA/(1 + s TA) with non-windup limits
[VRMIN Vt, VRMAX Vt] (proportional to the terminal voltage Vt, swept along as the
terminal voltage moves), exciter TE dEfd/dt = VR - (KE + SE(Efd)) Efd with the
quadratic saturation through (E1, SE1), (E2, SE2), and rate feedback s KF/(1 + s
TF1) from Efd. The under-excitation limiter's HV gate has no input (no UEL model).

What differs from EXDC2 is PSS/E's initialization of the DC exciters' data (PSS/E
Program Application Guide, DC exciters; as OpenIPSL's PSSE library implements it
in `calculate_dc_exciter_params`):

    VRMAX = 0: VRMAX = (KE + SE(E2)) E2 (KE <= 0: SE(E2) E2), and VRMIN = -VRMAX
    KE = 0:    KE = VRMAX/(10 Efd0) - SE(Efd0), so that VR0 = VRMAX/10

(OpenIPSL writes SE(E2) + KE for the KE > 0 case, without the factor E2; smibjax
takes the ceiling that holds Efd = E2 at rest, (KE + SE(E2)) E2, and the two agree
for KE <= 0, the case the public data use.) ANDES 2.0 instead keeps KE = 0 as
given and reads VRMAX = 0 as no ceiling (999).

At rest: VR0 = (KE + SE(Efd0)) Efd0, Vref = Vc0 - Vs0 + VR0/KA. `ref` is (4, k):
Vref, and the KE, VRMAX, VRMIN in force.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ..psse import DYR_MODELS
from .ieeex1 import _DCExciter

__all__ = ["ESDC2A", "ESDC1A", "dc_constants"]


def dc_constants(VRMAX, VRMIN, KE, E2, SE2, efd0, se0):
    """(KE, VRMAX, VRMIN) in force for PSS/E's DC exciters (ESDC1A, ESDC2A, IEEET1,
    IEEET2): VRMAX = 0 becomes (max(KE, 0) + SE2) E2 with VRMIN = -VRMAX; KE = 0
    becomes VRMAX/(10 efd0) - se0 (se0 = SE(efd0)), so that VR0 = VRMAX/10."""
    auto = VRMAX == 0
    vrmax = jnp.where(auto, (jnp.maximum(KE, 0.0) + SE2) * E2, VRMAX)
    vrmin = jnp.where(auto, -vrmax, VRMIN)
    safe = jnp.where(efd0 != 0, efd0, 1.0)
    ke = jnp.where(KE == 0, vrmax / (10.0 * safe) - se0, KE)
    return ke, vrmax, vrmin


class ESDC2A(_DCExciter):
    """PSS/E ESDC2A (IEEE 421.5 DC2A): EXDC2's diagram with PSS/E's DC-exciter
    initialization (KE = 0, VRMAX = 0 computed at rest)."""

    con_names = DYR_MODELS["ESDC2A"]
    vt_limits: ClassVar[bool] = True
    ref_limits: ClassVar[bool] = True

    def _constants(self, y0):
        return dc_constants(
            self.VRMAX, self.VRMIN, self.KE, self.E2, self.SE2, y0, self.se(y0)
        )


class ESDC1A(_DCExciter):
    """PSS/E ESDC1A (IEEE 421.5 DC1A): IEEEX1's diagram (constant regulator limits
    [VRMIN, VRMAX], non-windup) with PSS/E's DC-exciter initialization (KE = 0,
    VRMAX = 0 computed at rest, `dc_constants`)."""

    con_names = DYR_MODELS["ESDC1A"]
    vt_limits: ClassVar[bool] = False
    ref_limits: ClassVar[bool] = True

    def _constants(self, y0):
        return dc_constants(
            self.VRMAX, self.VRMIN, self.KE, self.E2, self.SE2, y0, self.se(y0)
        )
