"""Network stages of the fault sequence and the star-delta fault reduction.

The generator E' / delta sits behind X1 = X'_d + X_T from the SVC bus m; from m a stage
of the network is the pair (X2, Bf): the series reactance from m to the infinite bus and
an extra shunt susceptance at m caused by the fault (docs/model.md section 1).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._parameters import Fault, Plant

__all__ = [
    "Stage",
    "prefault_stage",
    "fault_stage",
    "postfault_stage",
    "stage_at",
    "by_stage",
]

Scalar = Float[Array, "*batch"]


class Stage(eqx.Module):
    """One network stage: X2 (pu) from the SVC bus to the infinite bus and the fault's
    shunt susceptance Bf (pu) at the SVC bus."""

    X2: Scalar
    Bf: Scalar


def prefault_stage(plant: Plant) -> Stage:
    """Both circuits in service: X2 = XL, Bf = 0 (also the restored network)."""
    return Stage(X2=plant.XL, Bf=jnp.zeros_like(plant.XL))


def postfault_stage(plant: Plant) -> Stage:
    """Circuit 1 open: X2 = 2 XL, Bf = 0."""
    return Stage(X2=2 * plant.XL, Bf=jnp.zeros_like(plant.XL))


def fault_stage(plant: Plant, lam: Scalar, Xf: Scalar) -> Stage:
    """Fault on circuit 1 at fraction `lam` from the SVC bus through reactance `Xf`.

    The fault node F (star Za = 2 lam XL to m, Zb = 2 (1 - lam) XL to the infinite bus,
    Zc = Xf to ground) is eliminated by star-delta: with S = Za Zb + Zb Zc + Zc Za,
    Z(m, inf) = S / Zc and Z(m, ground) = S / Zb. Written with admittances Zc / S and
    Zb / S so that the bolted fault Xf = 0 (Z(m, inf) infinite) needs no special case:
    X2 = 1 / (1 / (2 XL) + Zc / S) and Bf = -Zb / S.
    """
    za = 2 * lam * plant.XL
    zb = 2 * (1 - lam) * plant.XL
    zc = Xf
    s = za * zb + zb * zc + zc * za
    x2 = 1 / (1 / (2 * plant.XL) + zc / s)
    return Stage(X2=x2, Bf=-zb / s)


def by_stage(t: Scalar, fault: Fault, pre, during, post):
    """Whichever of `pre`, `during`, `post` (pytrees of one structure, e.g. stages or
    per-stage limits) is in force at time t (s): `pre` before t_fault and again from
    t_reclose, `during` in [t_fault, t_clear), `post` in [t_clear, t_reclose)."""
    in_fault = (t >= fault.t_fault) & (t < fault.t_clear)
    in_post = (t >= fault.t_clear) & (t < fault.t_reclose)
    return jax.tree_util.tree_map(
        lambda a, b, c: jnp.where(in_fault, b, jnp.where(in_post, c, a)),
        pre,
        during,
        post,
    )


def stage_at(t: Scalar, fault: Fault, plant: Plant, flt: Stage | None = None) -> Stage:
    """The stage in force at time t (s): pre-fault for t < t_fault, fault for
    t_fault <= t < t_clear, post-fault for t_clear <= t < t_reclose, restored after.
    `flt`, if given, is `fault_stage(plant, fault.lam, fault.Xf)` computed beforehand
    (the solver's loop does not hoist it)."""
    if flt is None:
        flt = fault_stage(plant, fault.lam, fault.Xf)
    return by_stage(t, fault, prefault_stage(plant), flt, postfault_stage(plant))
