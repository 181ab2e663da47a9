"""Smooth surrogates of the exact metrics, for gradient-based tuning.

Each term is a small pure function of a `Trajectory`, tested against the exact metric it
stands for (tests/test_losses.py). `LossWeights` combines them; `aggregate` turns a batch
of per-scenario losses into one number (mean plus a CVaR tail term).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._simulate import Trajectory

__all__ = [
    "soft_settling_time",
    "soft_overshoot",
    "effort_rate",
    "divergence",
    "margin",
    "instability",
    "chatter",
    "saturation",
    "LossWeights",
    "TERM_NAMES",
    "TERMS",
    "loss_terms",
    "scenario_loss",
    "cvar",
    "aggregate",
]

Scalar = Float[Array, ""]


def _smooth_abs(x, eps=1e-6):
    return jnp.sqrt(x * x + eps * eps)


def soft_settling_time(
    t: Float[Array, " n"],
    signal: Float[Array, " n"],
    reference,
    band: float,
    t_from,
    width: float | None = None,
    t_stop=None,
) -> Scalar:
    """Smooth settling time (s, from `t_from`) on a uniform grid t.

    The exact settling time is the length of [t_from, t_end] on which the *remaining*
    peak deviation D(t) = max_{s >= t} |signal(s) - reference| exceeds the band. This
    is sum_i dt sigmoid((D_i - band) / width) over t_i >= t_from: as width -> 0 it is
    the exact value to within one sample; its gradient lives where D crosses the band.
    `width` defaults to band / 8. Samples after `t_stop` (a loss of synchronism) count
    as outside the band: a run that breaks down never settles.
    """
    width = band / 8 if width is None else width
    after = t >= t_from
    dev = jnp.where(after, _smooth_abs(signal - reference), 0.0)
    if t_stop is not None:
        dev = jnp.where(t > t_stop, 10 * band, dev)
    remaining = jax.lax.cummax(dev, reverse=True)
    s = jax.nn.sigmoid((remaining - band) / width) * after
    return jnp.sum(s) * (t[1] - t[0])


def soft_overshoot(traj: Trajectory, temperature: float = 2e-3) -> Scalar:
    """Smooth max over t >= t_fault of |delta - delta_e| (rad), temperature in rad."""
    dev = _smooth_abs(traj.delta - traj.delta_e)
    z = jnp.where(traj.t >= traj.t_fault, dev / temperature, -jnp.inf)
    return temperature * jax.nn.logsumexp(z)


def effort_rate(traj: Trajectory) -> Scalar:
    """log(1 + mean of u_f^2 + u_r^2 over the horizon (pu^2)), and 0 for a run that
    lost synchronism: the inputs blow up on the way to the breakdown, and their
    derivatives (1e4 and more) would drown every other term (`instability` prices
    such runs instead)."""
    rate = jnp.maximum(traj.effort[0] + traj.effort[1], 0.0) / traj.t[-1]
    return jnp.where(traj.lost_sync, 0.0, jnp.log1p(rate))


def divergence(traj: Trajectory, scale: float = 0.1) -> Scalar:
    """Mean over the samples of log(1 + ((delta - delta_e)/scale)^2): grows with the
    angle excursion but only logarithmically, so a run that loses synchronism still has
    a finite loss whose gradient points back towards smaller excursions."""
    x = (traj.delta - traj.delta_e) / scale
    return jnp.mean(jnp.log1p(x * x))


def margin(traj: Trajectory, E_floor: float = 0.3, B_ceiling: float = 4.0) -> Scalar:
    """Mean over the samples of log(1 + softplus) barriers on the way to a breakdown:
    E' falling towards 0 (below `E_floor`, pu) and |B| rising towards the network
    singularity (above `B_ceiling`, pu); logarithmic so that a collapsed run stays
    finite. A run that breaks down holds its last sample for the rest
    of the horizon, so this term grows with the time lost and its gradient points
    back from the collapse (the settling surrogate is flat there)."""
    e = jax.nn.softplus((E_floor - traj.E) / 0.05)
    b = jax.nn.softplus((_smooth_abs(traj.B) - B_ceiling) / 0.25)
    return jnp.mean(jnp.log1p(e) + jnp.log1p(b))


def chatter(traj: Trajectory, uf_scale: float = 10.0, ur_scale: float = 2.0) -> Scalar:
    """Total variation per second of the applied inputs, each over a scale (pu: by
    default the widths of the realistic limits, 10 and 2), as a smooth sum:
    sum_i sqrt(du_i^2 + eps^2). One full swing between both limits per second costs
    2; a settled, smooth input almost 0. 0 for a run that lost synchronism (as
    `effort_rate`)."""
    tv = jnp.sum(_smooth_abs(jnp.diff(traj.u_f), 1e-4)) / uf_scale
    tv = tv + jnp.sum(_smooth_abs(jnp.diff(traj.u_r), 1e-4)) / ur_scale
    return jnp.where(traj.lost_sync, 0.0, tv / traj.t[-1])


def saturation(
    traj: Trajectory, uf_scale: float = 1.0, ur_scale: float = 0.2
) -> Scalar:
    """Mean over the samples of log(1 + (excess_f/uf_scale)^2) + log(1 +
    (excess_r/ur_scale)^2), where excess is how far the commanded input lies beyond
    what reaches the plant (pu; 0 inside the limits). It prices living on the limits,
    and it is the one term with a gradient there: beyond a limit the applied input,
    and with it every other term, does not move with the gains. Logarithmic: the
    paper's gains command 1e4 pu. 0 for a run that lost synchronism (as
    `effort_rate`)."""
    ef = (traj.u_f_cmd - traj.u_f) / uf_scale
    er = (traj.u_r_cmd - traj.u_r) / ur_scale
    value = jnp.mean(jnp.log1p(ef * ef) + jnp.log1p(er * er))
    return jnp.where(traj.lost_sync, 0.0, value)


def instability(traj: Trajectory) -> Scalar:
    """1 if the run lost synchronism, else 0. A value, not a gradient: it ranks broken
    runs last in the batch aggregate and in model selection, while `margin` and
    `divergence` supply the gradient that leads away from them."""
    return jax.lax.stop_gradient(traj.lost_sync.astype(traj.t.dtype))


class LossWeights(eqx.Module):
    """Weights and bands of the named loss terms (static configuration)."""

    settling_delta: float = eqx.field(static=True, default=1.0)
    settling_Vt: float = eqx.field(static=True, default=0.25)
    overshoot: float = eqx.field(static=True, default=1.0)
    effort: float = eqx.field(static=True, default=0.02)
    divergence: float = eqx.field(static=True, default=1.0)
    margin: float = eqx.field(static=True, default=1.0)
    instability: float = eqx.field(static=True, default=5.0)
    chatter: float = eqx.field(static=True, default=0.0)
    saturation: float = eqx.field(static=True, default=0.0)
    delta_band: float = eqx.field(static=True, default=0.01)
    Vt_band: float = eqx.field(static=True, default=0.01)


def _settling_delta(traj: Trajectory, w: LossWeights) -> Scalar:
    return soft_settling_time(
        traj.t, traj.delta, traj.delta_e, w.delta_band, traj.t_fault
    )


def _settling_Vt(traj: Trajectory, w: LossWeights) -> Scalar:
    return soft_settling_time(traj.t, traj.Vt, traj.Vt_e, w.Vt_band, traj.t_fault)


# The named loss terms, each once: name -> the unweighted term of one scenario (s, s,
# rad, -, -, -, -, 1/s, -). Its weight is the `LossWeights` field of the same name.
TERMS = {
    "settling_delta": _settling_delta,
    "settling_Vt": _settling_Vt,
    "overshoot": lambda traj, w: soft_overshoot(traj),
    "effort": lambda traj, w: effort_rate(traj),
    "divergence": lambda traj, w: divergence(traj),
    "margin": lambda traj, w: margin(traj),
    "instability": lambda traj, w: instability(traj),
    "chatter": lambda traj, w: chatter(traj),
    "saturation": lambda traj, w: saturation(traj),
}
TERM_NAMES = tuple(TERMS)


def loss_terms(traj: Trajectory, w: LossWeights) -> dict[str, Scalar]:
    """The unweighted terms of one scenario, named as in `TERMS`."""
    return {name: term(traj, w) for name, term in TERMS.items()}


def scenario_loss(traj: Trajectory, w: LossWeights) -> Scalar:
    """Weighted sum of `loss_terms`."""
    terms = loss_terms(traj, w)
    return sum(getattr(w, k) * v for k, v in terms.items() if getattr(w, k) != 0)


def cvar(x: Float[Array, " b"], q: float) -> Scalar:
    """Conditional value at risk: the mean of the worst (1 - q) fraction of `x`
    (at least one element)."""
    k = max(1, int(round((1 - q) * x.shape[0])))
    return jnp.mean(jax.lax.top_k(x, k)[0])


def aggregate(
    x: Float[Array, " b"], tail_weight: float = 0.5, q: float = 0.9
) -> Scalar:
    """Robust batch loss: mean(x) + tail_weight * CVaR_q(x)."""
    return jnp.mean(x) + tail_weight * cvar(x, q)
