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

from .simulate import Trajectory

__all__ = [
    "soft_settling_time",
    "soft_overshoot",
    "effort_rate",
    "divergence",
    "LossWeights",
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
    temperature: float = 0.05,
) -> Scalar:
    """Smooth "last time outside the band" (s, from `t_from`).

    With s_i = sigmoid((|signal_i - reference| - band) / width) the soft indicator of
    being outside, this is tau log(1 + sum_i s_i exp((t_i - t_from)/tau)) less the bias
    tau log(1 / (1 - exp(-dt/tau))) that the run of samples before the last exit adds;
    it tends to the exact settling time as width, tau -> 0. `width` defaults to band/4.
    """
    width = band / 4 if width is None else width
    dev = _smooth_abs(signal - reference)
    s = jax.nn.sigmoid((dev - band) / width) * (t >= t_from)
    z = (t - t_from) / temperature
    zmax = jax.lax.stop_gradient(jnp.maximum(jnp.max(jnp.where(s > 0, z, 0.0)), 0.0))
    val = zmax + jnp.log(jnp.exp(-zmax) + jnp.sum(s * jnp.exp(z - zmax)))
    dt = t[1] - t[0]
    bias = -jnp.log1p(-jnp.exp(-dt / temperature))
    return temperature * jax.nn.softplus(val - bias)


def soft_overshoot(traj: Trajectory, temperature: float = 2e-3) -> Scalar:
    """Smooth max over t >= t_fault of |delta - delta_e| (rad), temperature in rad."""
    dev = _smooth_abs(traj.delta - traj.delta_e)
    z = jnp.where(traj.t >= traj.t_fault, dev / temperature, -jnp.inf)
    return temperature * jax.nn.logsumexp(z)


def effort_rate(traj: Trajectory) -> Scalar:
    """Mean of u_f^2 + u_r^2 over the horizon (pu^2): the effort integrals / t_end."""
    return (traj.effort[0] + traj.effort[1]) / traj.t[-1]


def divergence(traj: Trajectory, scale: float = 0.1) -> Scalar:
    """Mean over the samples of log(1 + ((delta - delta_e)/scale)^2): grows with the
    angle excursion but only logarithmically, so a run that loses synchronism still has
    a finite loss whose gradient points back towards smaller excursions."""
    x = (traj.delta - traj.delta_e) / scale
    return jnp.mean(jnp.log1p(x * x))


class LossWeights(eqx.Module):
    """Weights and bands of the named loss terms (static configuration)."""

    settling_delta: float = eqx.field(static=True, default=1.0)
    settling_Vt: float = eqx.field(static=True, default=0.25)
    overshoot: float = eqx.field(static=True, default=1.0)
    effort: float = eqx.field(static=True, default=1e-4)
    divergence: float = eqx.field(static=True, default=1.0)
    delta_band: float = eqx.field(static=True, default=0.01)
    Vt_band: float = eqx.field(static=True, default=0.01)
    temperature: float = eqx.field(static=True, default=0.05)


def loss_terms(traj: Trajectory, w: LossWeights) -> dict[str, Scalar]:
    """The unweighted terms of one scenario (s, s, rad, pu^2, -)."""
    return {
        "settling_delta": soft_settling_time(
            traj.t,
            traj.delta,
            traj.delta_e,
            w.delta_band,
            traj.t_fault,
            temperature=w.temperature,
        ),
        "settling_Vt": soft_settling_time(
            traj.t,
            traj.Vt,
            traj.Vt_e,
            w.Vt_band,
            traj.t_fault,
            temperature=w.temperature,
        ),
        "overshoot": soft_overshoot(traj),
        "effort": effort_rate(traj),
        "divergence": divergence(traj),
    }


def scenario_loss(traj: Trajectory, w: LossWeights) -> Scalar:
    """Weighted sum of `loss_terms`."""
    terms = loss_terms(traj, w)
    return sum(getattr(w, k) * v for k, v in terms.items())


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
