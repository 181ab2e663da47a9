"""The adaptive synergetic controller in the paper's coordinates (docs/model.md section 2).

One control law covers both controllers of the paper: alpha < 1 is the adaptive
finite-time synergetic controller (AFTSC, eqs. 21-22), alpha = 1 the adaptive synergetic
baseline (ASC, eqs. 36-37). The controller sees the measured plant state z through its
*nominal* (pre-fault) network model. The law evaluates f and g of the affine model
dx/dt = f + g u in docs/model.md's closed forms (`drift_and_gain_closed_form`), with one sin
and one cos of the rotor angle (`smibjax._plant.sincos`): about half the cost of a
Monte Carlo run was XLA evaluating them again in every fused consumer. `drift_and_gain`
derives f and g by `jax.jvp` of the coordinate map z -> x along the nominal plant
vector field, and the tests hold the closed forms to it (1e-12 over random states and
plants), so controller and plant cannot disagree unnoticed.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..._network import prefault_stage
from ..._parameters import OperatingPoint, Plant
from ..._plant import Trig, plant_vector_field
from ..._validate import is_concrete
from .gains import Gains

__all__ = [
    "spow",
    "static_alpha",
    "paper_coordinates",
    "drift_and_gain",
    "drift_and_gain_closed_form",
    "ControlOutput",
    "evolution",
    "control_law",
    "adaptation_rate",
]

Scalar = Float[Array, ""]

# Below this |y| the derivative of spow is evaluated at |y| = SPOW_DERIVATIVE_FLOOR:
# a |y|^(a-1) is infinite at y = 0 for a < 1, and reverse-mode gradients would be
# inf/NaN (docs/model.md section 3). The forward value is exact.
SPOW_DERIVATIVE_FLOOR = 1e-9


def spow(y: Array, a: Array | float) -> Array:
    """Signed power sign(y) |y|^a (exact forward value).

    Its derivative in y, a |y|^(a-1), is floored at |y| = `SPOW_DERIVATIVE_FLOOR` so
    that gradients stay finite for a < 1; the derivative in a is
    sign(y) |y|^a log|y| (0 at y = 0). With `a` the Python number 1 (a static
    exponent, see `static_alpha`) it is y itself, and no log or exp is compiled.
    """
    if isinstance(a, (int, float)) and a == 1:
        return y
    return _spow(y, a)


def static_alpha(gains: Gains, alpha_one: bool | None = None) -> Gains:
    """`gains` with alpha as the static Python number 1.0 where alpha = 1 (ASC).

    A compiled program then computes spow(y, 1) as y: the four signed powers (a log
    and an exp each, float64) were 40% of a field evaluation. `alpha_one=None`
    decides from the value, which must then be concrete (not traced) and scalar, and
    leaves `gains` unchanged otherwise; inside a traced function pass what is known
    outside it (`True` replaces alpha whatever its value: the caller vouches for it).
    Gradients with respect to alpha need it traced: do not pass `True` then.
    """
    if alpha_one is None:
        a = gains.alpha
        if not is_concrete(a) or jnp.ndim(a) != 0:
            return gains
        alpha_one = float(a) == 1.0
    if not alpha_one:
        return gains
    return eqx.tree_at(lambda g: g.alpha, gains, 1.0)


@jax.custom_jvp
def _spow(y: Array, a: Array) -> Array:
    return _spow_value(y, a)


def _spow_parts(y, a):
    """(sign(y) |y|^a, log|y| (0 at y = 0), |y|^a): one log and one exp, cheaper
    than XLA's float64 pow (which checks special cases); exactly 0 at y = 0."""
    ay = jnp.abs(y)
    pos = ay > 0
    log_ay = jnp.log(jnp.where(pos, ay, 1.0))
    mag = jnp.exp(a * log_ay)
    return jnp.where(pos, jnp.sign(y) * mag, 0.0), log_ay, mag


def _spow_value(y, a):
    return _spow_parts(y, a)[0]


@_spow.defjvp
def _spow_jvp(primals, tangents):
    y, a = primals
    ty, ta = tangents
    ay = jnp.abs(y)
    out, log_ay, mag = _spow_parts(y, a)
    # a |y|^(a-1) = a |y|^a / |y| above the floor (no second power), and the
    # floor's value below it.
    above = ay > SPOW_DERIVATIVE_FLOOR
    dy = jnp.where(
        above,
        a * mag / jnp.where(above, ay, 1.0),
        a * jnp.exp((a - 1) * jnp.log(SPOW_DERIVATIVE_FLOOR)),
    )
    da = out * log_ay  # 0 at y = 0, where log_ay = 0
    return out, dy * ty + da * ta


def _affine_model(
    z: Float[Array, 4], plant: Plant, trig: Trig | None = None
) -> tuple[Float[Array, 4], Float[Array, 2], Float[Array, "2 2"]]:
    """(x, (f3, f4), g): the paper coordinates and docs/model.md's closed forms of the
    affine model, with sin and cos of delta evaluated once (or taken from `trig`)
    and x2 cot(x1) x3 written as x2 E V cos(x1) / Xs (no tangent, no division by
    sin x1)."""
    p = plant
    delta, domega, E, B = z[0], z[1], z[2], z[3]
    sin_d, cos_d = (jnp.sin(delta), jnp.cos(delta)) if trig is None else trig
    x2n = prefault_stage(p).X2
    xs = p.X1 + x2n
    xds = p.Xd + p.XT + x2n
    g31 = p.V * sin_d / xs
    pe = E * g31
    # f3 = (-a + x2 cot x1) x3 + c V^2 sin(2 x1) / (2 Xs)
    f3 = p.V * cos_d / xs * (E * domega + (p.Xd - p.Xdp) * p.V * sin_d / (xs * p.T0))
    f3 = f3 - xds / (xs * p.T0) * pe
    inv_den = 1 / (xs - p.X1 * x2n * B)
    mt = xs * inv_den - 1
    g42 = pe * p.X1 * x2n * xs * inv_den * inv_den  # -Nt
    f4 = mt * f3 - g42 * (B - p.B0) / p.Tr
    x = jnp.stack([delta, domega, pe, mt * pe])
    g = jnp.stack([jnp.stack([g31, jnp.zeros_like(g31)]), jnp.stack([mt * g31, g42])])
    return x, jnp.stack([f3, f4]), g


def paper_coordinates(
    z: Float[Array, 4], plant: Plant, trig: Trig | None = None
) -> Float[Array, 4]:
    """x = (delta, domega, Pe, Psvc) of the measured state z = (delta, domega, E, B)
    on the nominal network (X2 = XL, Bf = 0):
    Pe = E V sin(delta)/Xs and Psvc = Mt Pe with Mt = Xs/(Xs - X1 X2 B) - 1.
    `trig`: (sin delta, cos delta) if already computed (`smibjax._plant.sincos`)."""
    return _affine_model(z, plant, trig)[0]


def drift_and_gain(
    z: Float[Array, 4], plant: Plant
) -> tuple[Float[Array, 2], Float[Array, "2 2"]]:
    """(f3, f4) and g = [[g31, 0], [g41, g42]] of dx/dt = f(x) + g(x) (u_f/T0, u_r/Tr),
    by `jax.jvp` of `paper_coordinates` along the nominal plant vector field (u = 0),
    and along the unit input directions dE/dt = 1 and dB/dt = 1: the reference the
    control law's closed forms (`drift_and_gain_closed_form`) are tested against."""
    nominal = prefault_stage(plant)
    zero = jnp.zeros_like(z[0])
    drift = plant_vector_field(z, zero, zero, nominal, plant)
    basis = jnp.eye(4, dtype=z.dtype)
    tangents = jnp.stack([drift, basis[2], basis[3]])

    def pushforward(v):
        return jax.jvp(lambda zz: paper_coordinates(zz, plant)[2:], (z,), (v,))[1]

    out = jax.vmap(pushforward)(tangents)
    return out[0], out[1:].T


def drift_and_gain_closed_form(
    z: Float[Array, 4], plant: Plant, trig: Trig | None = None
) -> tuple[Float[Array, 2], Float[Array, "2 2"]]:
    """docs/model.md's closed forms of (f3, f4) and g (errata applied), the ones the
    control law evaluates: f3 = (-a + x2 cot x1) x3 + c V^2 sin(2 x1)/(2 Xs),
    g31 = V sin(x1)/Xs, f4 = Mt f3 + Nt (B - B0)/Tr, g41 = Mt g31, g42 = -Nt.
    `trig`: (sin delta, cos delta) if already computed (`smibjax._plant.sincos`)."""
    _, f, g = _affine_model(z, plant, trig)
    return f, g


class ControlOutput(NamedTuple):
    """What the controller computes from one measurement."""

    u_f: Scalar  # field voltage command (pu), before the plant's limits
    u_r: Scalar  # SVC command (pu), before the plant's limits
    x: Float[Array, 4]  # paper coordinates (delta, domega, Pe, Psvc)
    phi: Float[Array, 2]  # macro-variables (phi1, phi2), eq. (23)


def evolution(phi: Array, T: Array, a: Array | float, layer: float = 0.0) -> Array:
    """The evolution law's rate phi_dot = spow(-phi/T, alpha) (docs/model.md section 2), or
    with `layer` = eps > 0 (same units as phi) its boundary-layer ("practical
    finite-time") form -phi (phi^2 + eps^2)^((alpha - 1)/2) / T^alpha: equal to the
    exact law to a relative 1 - (1 + eps^2/phi^2)^((alpha - 1)/2) (< 1e-3 for
    |phi| > 12 eps at alpha = 5/7), linear with the finite slope
    eps^(alpha - 1)/T^alpha for |phi| << eps, and smooth. alpha = 1 is unaffected."""
    if layer == 0 or (isinstance(a, (int, float)) and a == 1):
        return spow(-phi / T, a)
    return -phi * jnp.exp(0.5 * (a - 1) * jnp.log(phi * phi + layer * layer)) / T**a


def control_law(
    z: Float[Array, 4],
    th_hat: Float[Array, 2],
    gains: Gains,
    plant: Plant,
    op: OperatingPoint,
    layer: float = 0.0,
    trig: Trig | None = None,
) -> ControlOutput:
    """The synergetic control law, eq. (21) (eq. (36) for alpha = 1):

        u_f/T0 = -(b1 f3 + x2 + xdot2_hat - spow(-phi1/T1, alpha)) / (b1 g31)
        u_r/Tr = -(b2 (f4 + g41 u_f/T0) + x2 + xdot2_hat - spow(-phi2/T2, alpha))
                 / (b2 g42)
    with xdot2_hat = (th2 + th1 x2 - x3 - x4)/M, errors e = x - (delta_e, 0, Pm_ref, 0)
    and macro-variables phi1 = e1 + e2 + b1 e3, phi2 = e1 + e2 + b2 e4. With weighted
    macro-variables (docs/model.md section 2) phi_i = c_i e1 + e2 + b_i e_(i+2) and the
    x2 of each law becomes c_i x2 (c1 = c2 = 1: the paper, the default). `layer` > 0:
    the boundary-layer form of the evolution law (see `evolution`; 0: exact).
    f and g are the closed forms (`drift_and_gain_closed_form`); `trig`: (sin delta,
    cos delta) if already computed (`smibjax._plant.sincos`).
    """
    x, f, g = _affine_model(z, plant, trig)
    e1 = x[0] - op.delta_e
    e2 = x[1]
    e3 = x[2] - op.Pm_ref
    e4 = x[3]
    b1, b2, a = gains.beta1, gains.beta2, gains.alpha
    c1, c2 = gains.c1, gains.c2
    phi1 = c1 * e1 + e2 + b1 * e3
    phi2 = c2 * e1 + e2 + b2 * e4
    xdot2_hat = (th_hat[1] + th_hat[0] * x[1] - x[2] - x[3]) / plant.M
    # (c x2 + xdot2_hat) grouped as the paper's common term x2 + xdot2_hat was
    v1 = -(
        b1 * f[0] + (c1 * x[1] + xdot2_hat) - evolution(phi1, gains.T1, a, layer)
    ) / (b1 * g[0, 0])
    v2 = -(
        b2 * (f[1] + g[1, 0] * v1)
        + (c2 * x[1] + xdot2_hat)
        - evolution(phi2, gains.T2, a, layer)
    ) / (b2 * g[1, 1])
    return ControlOutput(
        u_f=plant.T0 * v1, u_r=plant.Tr * v2, x=x, phi=jnp.stack([phi1, phi2])
    )


def adaptation_rate(
    out: ControlOutput,
    th_hat: Float[Array, 2],
    gains: Gains,
    plant: Plant,
    oracle: bool = True,
) -> Float[Array, 2]:
    """d th_hat/dt, eq. (22) (eq. (37) for alpha = 1):

        dth1/dt = gamma1 (k1 spow(theta1 - th1, alpha) + x2 (phi1 + phi2)/M)
        dth2/dt = gamma2 (k2 spow(theta2 - th2, alpha) + (phi1 + phi2)/M)
    with the true theta = (-D, Pm) in the k-terms (`oracle=True`, the paper); with
    `oracle=False` the k-terms are dropped (k1 = k2 = 0, realizable adaptation).
    """
    s = (out.phi[0] + out.phi[1]) / plant.M
    a = gains.alpha
    if oracle:
        o1 = gains.k1 * spow(-plant.D - th_hat[0], a)
        o2 = gains.k2 * spow(plant.Pm - th_hat[1], a)
    else:
        o1 = o2 = 0.0
    return jnp.stack([gains.gamma1 * (o1 + out.x[1] * s), gains.gamma2 * (o2 + s)])
