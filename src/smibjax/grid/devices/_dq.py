"""The rotor (d-q) frame and the swing equation shared by the detailed machines.

The q axis leads by the rotor angle delta from the network's real axis and the d axis
lags the q axis by 90 degrees (ANDES's and PSS/E's convention: vd = |V| sin(delta - a),
vq = |V| cos(delta - a) for V = |V| e^{j a}). A phasor X of the network frame has
rotor-frame components X_dq = Xd + j Xq = j e^{-j delta} X, and back
X = -j e^{j delta} X_dq.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np


def to_dq(z, delta):
    """(d, q) components of network-frame phasors z in the rotor frame at angle delta."""
    w = 1j * jnp.exp(-1j * delta) * z
    return jnp.real(w), jnp.imag(w)


def from_dq(d, q, delta):
    """The network-frame phasor with rotor-frame components (d, q) at angle delta."""
    return -1j * jnp.exp(1j * delta) * (d + 1j * q)


def swing(omega, te, pm, h, d, f_base, speed_factor: bool = False):
    """(d delta/dt, d omega/dt) of the swing equation d delta/dt = omega_b omega and

        2 H d omega/dt = (Pm - D omega) / (1 + omega) - Te   (speed_factor True)
        2 H d omega/dt = Pm - Te - D omega                    (speed_factor False)

    (omega the per-unit speed deviation, Pm and Te in pu on the machine base,
    omega_b = 2 pi f_base rad/s). With `speed_factor`, PSS/E's: the turbine's power
    becomes a torque at the rotor's speed, Tm = (Pm - D omega)/(1 + omega), against
    the air-gap torque Te (GENROU, GENROE, GENSAL, GENSAE; OpenIPSL's PSSE machines
    write the same; checked against PSS/E's own results, docs/validation-psse.md).
    Without it, ANDES's (GENCLS, GENTRA: the SMIB's closed form)."""
    tm = (pm - d * omega) / (1.0 + omega) if speed_factor else pm - d * omega
    return 2 * np.pi * f_base * omega, (tm - te) / (2 * h)
