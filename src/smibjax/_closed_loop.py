"""The closed loop: plant + controller as one vector field.

The integrated state is y = (delta, domega, E, B, s_1..s_k, J_f, J_r): the plant state,
the controller's internal state (k = `controller.n_internal`; the estimates
(th1, th2) of the paper's adaptive law) and the running control-effort integrals of
u_f^2 and u_r^2 (after limits).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ._network import (
    Stage,
    by_stage,
    fault_stage,
    postfault_stage,
    prefault_stage,
    stage_at,
)
from ._parameters import Fault, InitialEstimates, OperatingPoint, Plant
from ._plant import (
    apply_limits,
    equilibrium_state,
    plant_vector_field,
    sincos,
)
from ._validate import concrete_value, require
from .controllers import AbstractController, Gains, as_controller

__all__ = [
    "ClosedLoop",
    "initial_state",
    "closed_loop_vector_field",
    "healthy",
    "N_STATE",
    "N_DYNAMIC",
]

N_STATE = 8  # delta, domega, E, B, th1, th2, J_f, J_r (the paper's controller)
N_DYNAMIC = 6  # the first six enter the error control; the effort integrals do not

# Loss of synchronism is declared (and the run ends as unstable) when delta comes within
# DELTA_MARGIN rad of the ends of the controller's angle range (0 and pi for the paper's
# law, -pi and pi otherwise), E' falls below E_MIN, or a transfer reactance falls below
# X_MIN: the control law has 1/sin(delta) and 1/Pe singularities there (docs/model.md
# section 3) and no trajectory crosses them, so the spec's "delta leaves (0, pi)" is
# detected a hair before the singularity instead of after it.
DELTA_MARGIN = 1e-3
E_MIN = 1e-3
X_MIN = 1e-3


class ClosedLoop(eqx.Module):
    """Everything the closed-loop vector field needs, as one pytree.

    `fault_network` (the fault stage) and `safe_state` (where the field is evaluated
    outside the domain) depend on the parameters only; they are computed once here
    because XLA does not hoist them out of the solver's loop (together they were a
    quarter of the cost of a field evaluation).
    """

    controller: AbstractController
    fault: Fault
    plant: Plant
    op: OperatingPoint
    input_smoothing: float = eqx.field(static=True)
    fault_network: Stage
    safe_state: Float[Array, " n"]
    b_max: Float[Array, 3]

    def __init__(
        self,
        gains: Gains | AbstractController,
        fault: Fault,
        plant: Plant,
        op: OperatingPoint,
        oracle: bool = True,
        input_smoothing: float = 0.0,
    ):
        """`gains`: a controller, or the paper's `Gains` (then the `Synergetic`
        controller with the `oracle` or realizable update law)."""
        self.controller = as_controller(gains, "oracle" if oracle else "realizable")
        self.fault, self.plant, self.op = fault, plant, op
        self.input_smoothing = input_smoothing
        self.fault_network = fault_stage(plant, fault.lam, fault.Xf)
        self.safe_state = initial_state(
            op, plant, InitialEstimates(), self.controller, check=False
        )
        nominal = _b_max(prefault_stage(plant), plant)
        self.b_max = jnp.stack(
            [
                nominal,
                jnp.minimum(_b_max(self.fault_network, plant), nominal),
                jnp.minimum(_b_max(postfault_stage(plant), plant), nominal),
            ]
        )

    def stage(self, t: Float[Array, ""]) -> Stage:
        """The network stage in force at t (s)."""
        return stage_at(t, self.fault, self.plant, self.fault_network)

    @property
    def n_dynamic(self) -> int:
        """Number of leading states under error control (plant + controller)."""
        return 4 + self.controller.n_internal


def _b_max(stage: Stage, plant: Plant):
    """The SVC susceptance B (pu) at which the transfer reactance of `stage`,
    Xs - X1 X2 (B + Bf), falls to X_MIN."""
    xs = plant.X1 + stage.X2
    return (xs - X_MIN) / (plant.X1 * stage.X2) - stage.Bf


def require_start(plant: Plant, op: OperatingPoint) -> None:
    """Raise `ParameterError` unless the starting point y(0) (the operating point on
    the pre-fault network) lies inside the model's domain, as `healthy` tests it: the
    transfer reactance Xs - X1 XL B0 > `X_MIN` (pu; a negative one gives a negative
    terminal-voltage magnitude) and E'(0) = Pm_ref Xs / (V sin delta_e) > `E_MIN`
    (pu). A run from outside would be "unstable at t = 0", a verdict on the inputs,
    not on the controller. Skipped inside jit/vmap (values unknown)."""
    vals = [
        concrete_value(x)
        for x in (plant.Xdp, plant.XT, plant.XL, plant.B0, plant.V, op.delta_e)
    ] + [concrete_value(op.Pm_ref)]
    if any(v is None for v in vals):
        return
    xdp, xt, xl, b0, v, de, pm = (np.asarray(x, dtype=float) for x in vals)
    x1 = xdp + xt
    xs = x1 + xl
    with np.errstate(all="ignore"):
        xeff = xs - x1 * xl * b0
        e0 = pm * xs / (v * np.sin(de))
    require(
        xeff > X_MIN,
        "Plant",
        "B0",
        b0,
        "the starting point is outside the model's domain: the pre-fault transfer "
        "reactance Xs - X1 XL B0 = {} pu must be > {} (B0 < {})",
        xeff,
        X_MIN,
        (xs - X_MIN) / (x1 * xl),
    )
    require(
        e0 > E_MIN,
        "OperatingPoint",
        "Pm_ref",
        pm,
        "the starting point is outside the model's domain: E'(0) = Pm_ref Xs / "
        "(V sin delta_e) = {} pu must be > {}",
        e0,
        E_MIN,
    )


def initial_state(
    op: OperatingPoint,
    plant: Plant,
    init: InitialEstimates,
    controller: AbstractController | None = None,
    check: bool = True,
) -> Float[Array, " n"]:
    """y(0): the operating point, the controller's initial internal state (for the
    paper's controller, the default: the initial estimates) and zero effort.
    `check=False` skips the controller's checks of `init` (for a placeholder state)."""
    controller = as_controller(Gains()) if controller is None else controller
    z0 = equilibrium_state(op, plant)
    zero = jnp.zeros_like(z0[0])
    if check:
        s0 = controller.initial_internal(z0, plant, op, init)
    else:  # a placeholder (inside any projection box of the paper's law)
        s0 = controller.placeholder_internal(z0, plant, op, init)
    return jnp.concatenate([z0, s0, jnp.stack([zero, zero])])


def closed_loop_vector_field(
    t: Float[Array, ""], y: Float[Array, 8], loop: ClosedLoop
) -> Float[Array, 8]:
    """dy/dt: the controller measures z, its inputs pass the plant's limits, the plant
    runs on the network stage in force at t and the estimates follow eq. (22).

    Outside the model's domain (see `healthy`: past a loss of synchronism, where the
    run is stopped anyway) the field is 0, evaluated at a harmless state, so that
    neither the values nor the derivatives of a step that crosses the boundary can be
    inf or NaN (a 0 cotangent times an infinite Jacobian is NaN in reverse mode).
    """
    ok = healthy(t, y, loop)
    safe = jnp.where(ok, y, loop.safe_state)
    z, s = safe[:4], safe[4 : loop.n_dynamic]
    stage = loop.stage(t)
    trig = sincos(z[0])  # once, for the controller and the plant
    out = loop.controller(t, z, s, stage, loop.plant, loop.op, trig)
    u_f, u_r = apply_limits(out.u_f, out.u_r, loop.plant, loop.input_smoothing)
    dz = plant_vector_field(z, u_f, u_r, stage, loop.plant, trig)
    dy = jnp.concatenate([dz, out.d_internal, jnp.stack([u_f**2, u_r**2])])
    return jnp.where(ok, dy, 0.0)


def healthy(
    t: Float[Array, ""], y: Float[Array, 8], loop: ClosedLoop
) -> Bool[Array, ""]:
    """False once the run has lost synchronism or left the model's domain (see
    `DELTA_MARGIN`), or any dynamic state is non-finite.

    The reactance condition, Xs - X1 X2 (B + Bf) > X_MIN on the stage in force and on
    the controller's nominal network, is evaluated as B < b_max(stage) with the
    thresholds computed once per run (`ClosedLoop.b_max`): the same test, at a
    fraction of the cost inside the solver's loop.
    """
    delta, E, B = y[0], y[2], y[3]
    lo, hi = loop.controller.angle_range
    b = loop.b_max
    b_lim = by_stage(t, loop.fault, b[0], b[1], b[2])
    return (
        jnp.isfinite(jnp.sum(y[: loop.n_dynamic]))
        & (delta > lo + DELTA_MARGIN)
        & (delta < hi - DELTA_MARGIN)
        & (E > E_MIN)
        & (B < b_lim)
    )
