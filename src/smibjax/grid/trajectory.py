"""What a multi-machine run records (`GridTrajectory`) and the centre-of-inertia
quantities read from it. No solver here: reading a stored run's arrays
(`smibjax.cli._exported`) imports neither diffrax nor the solve path."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .loop import Case

__all__ = ["GridTrajectory", "coi_weights", "coi_angles", "angle_spread"]


class GridTrajectory(eqx.Module):
    """Samples of a run: times (s); per generator (columns in `System.generators`
    order): rotor angle in the synchronous frame (rad), speed deviation (pu),
    field voltage Efd and mechanical power Pm commands, electrical power Pe (pu
    machine base), terminal voltage (pu), stabilizer output Vs; per bus: voltage
    magnitude (pu). `stable`: no loss of synchronism within the horizon;
    `t_unstable`: when synchronism was lost (inf if never); `exhausted`: the step
    budget ran out first (neither verdict holds); `y_final`: the state at the end
    (t_end, or where synchronism was lost); `gen_on`: 1 where a machine (not an
    infinite bus) is in service at the sample, 0 from its trip; `delta_ref`: the
    angles (rad, synchronous frame) of the post-disturbance equilibrium where it is
    known, the operating point's when the network in force at t_end is the one
    before the events (faults cleared, branches reclosed), NaN otherwise.
    `collapsed`: the run stopped because the network had no solution (voltage
    collapse with constant power loads; `stable` is then False and `t_unstable` =
    `t_collapse`, the time of the first accepted step without a solution; inf if
    none)."""

    ts: Float[Array, " T"]
    delta: Float[Array, "T n_gen"]
    omega: Float[Array, "T n_gen"]
    efd: Float[Array, "T n_gen"]
    pm: Float[Array, "T n_gen"]
    pe: Float[Array, "T n_gen"]
    vt: Float[Array, "T n_gen"]
    vs: Float[Array, "T n_gen"]
    v_bus: Float[Array, "T n_bus"]
    stable: Bool[Array, ""]
    t_unstable: Float[Array, ""]
    exhausted: Bool[Array, ""]
    n_steps: Array
    y_final: Float[Array, " n_state"]
    gen_on: Float[Array, "T n_gen"]
    delta_ref: Float[Array, " n_gen"]
    collapsed: Bool[Array, ""]
    t_collapse: Float[Array, ""]
    # issue 47: the renewables' signals per generator (`loop.IBR_MEASUREMENTS`: Ip,
    # Iq, Ipcmd, Iqcmd, LVPL, Ipmax, Iqmax, Qe, Pref, Qext (pu machine base), Va
    # (rad)), NaN at other generators; empty without renewables
    ibr: dict = eqx.field(default_factory=dict)


def coi_weights(case: Case, gen_status) -> Float[Array, " n_gen"]:
    """Inertia weights H * mbase of the machines in service (zero elsewhere)."""
    w = jnp.zeros(case.n_gen)
    for m, gt in zip(case.machines, case.layout.machine_gen, strict=True):
        g = np.asarray(gt, dtype=np.int64)
        h = getattr(m, "H", jnp.ones(len(g)))
        w = w.at[g].set(jnp.asarray(h) * jnp.asarray(m.mbase))
    return w * gen_status


def coi_angles(case: Case, delta, gen_status) -> Float[Array, "... n_gen"]:
    """Angles referred to the centre of inertia of the machines in service
    (`gen_status`: one per generator, or one row per sample) (rad), or to the
    synchronous frame (the infinite bus's) where the case has an infinite bus."""
    if len(case.sources):
        return delta
    w = coi_weights(case, gen_status)  # (..., n_gen) with a status per sample
    w_sum = jnp.sum(w, axis=-1, keepdims=True)
    return delta - jnp.sum(w * delta, axis=-1, keepdims=True) / w_sum


def angle_spread(case: Case, delta, gen_status):
    """The largest |angle - COI| over machines in service (rad)."""
    rel = coi_angles(case, delta, gen_status)
    return jnp.max(jnp.abs(rel) * (gen_status > 0), axis=-1)
