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


def swing(omega, te, pm, h, d, f_base):
    """(d delta/dt, d omega/dt) of the swing equation d delta/dt = omega_b omega,
    2 H d omega/dt = Pm - Te - D omega (omega the per-unit speed deviation, Pm and Te
    in pu on the machine base, omega_b = 2 pi f_base rad/s; no speed factor on the
    torques, as ANDES)."""
    return 2 * np.pi * f_base * omega, (pm - te - d * omega) / (2 * h)
