"""The SMIB + SVC plant in physical coordinates (docs/model.md section 1).

State z = (delta, domega, E, B): rotor angle (rad), speed deviation (rad/s), transient
EMF E' (pu) and SVC net susceptance (pu). Inputs u = (u_f, u_r): field voltage and SVC
command (pu), after the plant's input limits.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._network import Stage, prefault_stage
from ._parameters import OperatingPoint, Plant

__all__ = [
    "Trig",
    "sincos",
    "effective_reactance",
    "electrical_power",
    "terminal_voltage",
    "plant_vector_field",
    "apply_limits",
    "equilibrium_state",
    "operating_field_voltage",
]

Scalar = Float[Array, ""]
State = Float[Array, "4"]
# (sin delta, cos delta) of the rotor angle, computed once per evaluation (`sincos`)
Trig = tuple[Scalar, Scalar]


@jax.custom_jvp
def sincos(delta: Scalar) -> Trig:
    """(sin delta, cos delta), computed once and kept for every consumer.

    A closed-loop field evaluation needs sin and cos of the rotor angle in the
    controller's coordinate map and drift and in the plant. Written where each is
    used, XLA's CPU fusion evaluated them again inside every fused consumer: five
    float64 sines and three cosines per evaluation, about half the cost of a Monte
    Carlo run (README "Numerics"). Here they leave a reduction (sin + 0 delta: exact
    for finite delta; the closed loop only evaluates finite states), which XLA
    computes once and does not copy into its consumers (`lax.optimization_barrier` does
    not do this on CPU: it is removed before fusion).
    `tests/test_controller.py::test_the_field_computes_one_sine_and_one_cosine` counts
    them in the compiled field. Differentiable (its derivative reuses the two values)
    and vmappable; works for any shape of `delta`.
    """
    zero = 0 * delta
    pair = jnp.stack(
        [jnp.stack([jnp.sin(delta), zero]), jnp.stack([jnp.cos(delta), zero])]
    )
    kept = jnp.sum(pair, axis=1)
    return kept[0], kept[1]


@sincos.defjvp
def _sincos_jvp(primals, tangents):
    (delta,), (t,) = primals, tangents
    s, c = sincos(delta)
    return (s, c), (c * t, -s * t)


def _trig(delta: Scalar, trig: Trig | None) -> Trig:
    """`trig`, or sin and cos of `delta` where the caller has none (under jit the
    one not used is dropped)."""
    return (jnp.sin(delta), jnp.cos(delta)) if trig is None else trig


def effective_reactance(B: Scalar, stage: Stage, plant: Plant) -> Scalar:
    """Xs - X1 X2 (B + Bf): the transfer reactance seen by E' (pu), Xs = X1 + X2."""
    xs = plant.X1 + stage.X2
    return xs - plant.X1 * stage.X2 * (B + stage.Bf)


def electrical_power(
    delta: Scalar,
    E: Scalar,
    B: Scalar,
    stage: Stage,
    plant: Plant,
    trig: Trig | None = None,
) -> Scalar:
    """Total electrical power P = E V sin(delta) / (Xs - X1 X2 (B + Bf)) (pu).
    `trig`: (sin delta, cos delta) if already computed (`sincos`)."""
    sin_d = _trig(delta, trig)[0]
    return E * plant.V * sin_d / effective_reactance(B, stage, plant)


def terminal_voltage(
    delta: Scalar,
    E: Scalar,
    B: Scalar,
    stage: Stage,
    plant: Plant,
    trig: Trig | None = None,
) -> Scalar:
    """SVC-bus voltage magnitude Vt (pu), from the phasor solution of the bus:
    sqrt((X2 E)^2 + (X1 V)^2 + 2 X1 X2 E V cos delta) / (Xs - X1 X2 (B + Bf)).
    `trig`: (sin delta, cos delta) if already computed (`sincos`)."""
    x1, x2, v = plant.X1, stage.X2, plant.V
    cos_d = _trig(delta, trig)[1]
    num = (x2 * E) ** 2 + (x1 * v) ** 2 + 2 * x1 * x2 * E * v * cos_d
    return jnp.sqrt(jnp.maximum(num, 0.0)) / effective_reactance(B, stage, plant)


def _soft_clip(u: Scalar, lo: Scalar, hi: Scalar, width: float) -> Scalar:
    """lo + w softplus((u - lo)/w), then hi - w softplus((hi - y)/w): equal to u to
    within w exp(-distance/w) inside [lo, hi], smooth, and with a non-zero gradient
    beyond the limits. Infinite limits are no limits."""
    fin_lo, fin_hi = jnp.isfinite(lo), jnp.isfinite(hi)
    lo0, hi0 = jnp.where(fin_lo, lo, 0.0), jnp.where(fin_hi, hi, 0.0)
    y = jnp.where(fin_lo, lo0 + width * jax.nn.softplus((u - lo0) / width), u)
    return jnp.where(fin_hi, hi0 - width * jax.nn.softplus((hi0 - y) / width), y)


def apply_limits(
    u_f: Scalar, u_r: Scalar, plant: Plant, smoothing: float = 0.0
) -> tuple[Scalar, Scalar]:
    """Limit the inputs to [uf_min, uf_max] and [ur_min, ur_max]: a hard clip
    (`smoothing = 0`, the physical limiter, used for reports) or, for training losses,
    a soft clip of width `smoothing` (pu), whose gradient beyond the limits is small
    but not zero."""
    if smoothing > 0:
        return (
            _soft_clip(u_f, plant.uf_min, plant.uf_max, smoothing),
            _soft_clip(u_r, plant.ur_min, plant.ur_max, smoothing),
        )
    return (
        jnp.clip(u_f, plant.uf_min, plant.uf_max),
        jnp.clip(u_r, plant.ur_min, plant.ur_max),
    )


def plant_vector_field(
    z: State,
    u_f: Scalar,
    u_r: Scalar,
    stage: Stage,
    plant: Plant,
    trig: Trig | None = None,
) -> State:
    """dz/dt of the plant on network `stage` (swing equation, flux decay, SVC lag):

        d delta/dt  = domega
        d domega/dt = (Pm - D domega - P) / M
        dE/dt       = -Xds/(Xs T0) E + (Xd - X'd)/(Xs T0) V cos(delta) + u_f/T0
        dB/dt       = (-(B - B0) + u_r) / Tr
    with Xs = X1 + X2 and Xds = Xd + XT + X2 of the stage. `trig`: (sin delta,
    cos delta) if already computed (`sincos`).
    """
    delta, domega, E, B = z[0], z[1], z[2], z[3]
    p = plant
    trig = _trig(delta, trig)
    xs = p.X1 + stage.X2
    xds = p.Xd + p.XT + stage.X2
    pe = electrical_power(delta, E, B, stage, p, trig)
    d_delta = domega
    d_omega = (p.Pm - p.D * domega - pe) / p.M
    d_e = (-xds * E + (p.Xd - p.Xdp) * p.V * trig[1]) / (xs * p.T0) + u_f / p.T0
    d_b = (-(B - p.B0) + u_r) / p.Tr
    return jnp.stack([d_delta, d_omega, d_e, d_b])


def equilibrium_state(op: OperatingPoint, plant: Plant) -> State:
    """The operating point (delta_e, 0, E_e, B0) with E_e = Pm_ref Xs / (V sin delta_e)
    on the pre-fault network."""
    xs = plant.X1 + prefault_stage(plant).X2
    e_e = op.Pm_ref * xs / (plant.V * jnp.sin(op.delta_e))
    zero = jnp.zeros_like(e_e)
    return jnp.stack([op.delta_e + zero, zero, e_e, plant.B0 + zero])


def operating_field_voltage(op: OperatingPoint, plant: Plant) -> Scalar:
    """E_fd0 (pu): the field voltage that holds E' at its operating-point value on the
    pre-fault network, (Xds E_e - (Xd - X'd) V cos delta_e) / Xs (dE/dt = 0)."""
    stage = prefault_stage(plant)
    xs = plant.X1 + stage.X2
    xds = plant.Xd + plant.XT + stage.X2
    e_e = equilibrium_state(op, plant)[2]
    return (xds * e_e - (plant.Xd - plant.Xdp) * plant.V * jnp.cos(op.delta_e)) / xs
