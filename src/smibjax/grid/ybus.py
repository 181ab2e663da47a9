"""The bus admittance matrix Y (pu, system base) of a `System`, and the loads as
constant admittances.

Y is dense (n_bus, n_bus) complex and built by scatter-adds from the branch and shunt
arrays, so it is jittable, differentiable in every branch and shunt parameter and
vmappable over the branch statuses (an outage is `status = 0`) and over an extra
diagonal admittance (a fault, an SVC). Each branch adds its two-port

    [I_fr]   [ (y + j b/2) / tap^2    -y / conj(a) ] [V_fr]
    [I_to] = [ -y / a                  y + j b/2   ] [V_to],

    y = 1 / (r + j x),  a = tap e^{j shift}

(the convention of `Branches`: the off-nominal ratio and the phase shift on the from
side, the from-end voltage divided by a; PSS/E and MATPOWER), scaled by its status;
each fixed shunt adds g + j b to its bus's diagonal. Loads are not in Y: the power
flow treats them as constant power, the dynamic network as the constant admittances
of `load_admittance`.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Complex, Float

from .system import System

__all__ = ["ybus", "branch_admittances", "load_admittance"]


def branch_admittances(
    system: System, branch_status: Float[Array, " n_br"] | None = None
) -> tuple[Complex[Array, " n_br"], ...]:
    """(y_ff, y_ft, y_tf, y_tt): each branch's two-port entries (pu, system base),
    times its status (`branch_status` in [0, 1] if given, else `Branches.status`), so
    that I_fr = y_ff V_fr + y_ft V_to and I_to = y_tf V_fr + y_tt V_to."""
    br = system.branches
    status = br.status if branch_status is None else branch_status
    status = jnp.asarray(status, dtype=jnp.float64)
    y = status / (jnp.asarray(br.r) + 1j * jnp.asarray(br.x))
    half_b = 0.5j * status * jnp.asarray(br.b)
    a = jnp.asarray(br.tap) * jnp.exp(1j * jnp.asarray(br.shift))
    y_tt = y + half_b
    y_ff = y_tt / jnp.asarray(br.tap) ** 2
    y_ft = -y / jnp.conj(a)
    y_tf = -y / a
    return y_ff, y_ft, y_tf, y_tt


def ybus(
    system: System,
    branch_status: Float[Array, " n_br"] | None = None,
    bus_shunt: Complex[Array, " n_bus"] | None = None,
) -> Complex[Array, "n_bus n_bus"]:
    """The bus admittance matrix (pu, system base): the branches (series impedance,
    charging, taps and phase shifts) with status `branch_status` (n_br,) in [0, 1]
    (default: `Branches.status`), the fixed shunts, and `bus_shunt` (n_bus,) complex
    (pu) added on the diagonal. Loads are not included (`load_admittance`)."""
    n = system.n_bus
    br = system.branches
    fr = jnp.asarray(br.fr)
    to = jnp.asarray(br.to)
    y_ff, y_ft, y_tf, y_tt = branch_admittances(system, branch_status)
    Y = jnp.zeros((n, n), dtype=jnp.complex128)
    Y = Y.at[fr, fr].add(y_ff).at[fr, to].add(y_ft)
    Y = Y.at[to, fr].add(y_tf).at[to, to].add(y_tt)
    sh = system.shunts
    diag = jnp.zeros(n, dtype=jnp.complex128)
    diag = diag.at[jnp.asarray(sh.bus)].add(jnp.asarray(sh.g) + 1j * jnp.asarray(sh.b))
    if bus_shunt is not None:
        diag = diag + bus_shunt
    return Y + jnp.diag(diag)


def load_admittance(
    system: System, vm: Float[Array, " n_bus"]
) -> Complex[Array, " n_bus"]:
    """The loads as constant admittances at the bus voltage magnitudes vm (pu):
    y = (p - j q) / vm^2 for each load, summed per bus (pu, system base), so that the
    admittance draws the load's p + j q at that voltage."""
    ld = system.loads
    bus = jnp.asarray(ld.bus)
    y = (jnp.asarray(ld.p) - 1j * jnp.asarray(ld.q)) / jnp.asarray(vm)[bus] ** 2
    return jnp.zeros(system.n_bus, dtype=jnp.complex128).at[bus].add(y)
