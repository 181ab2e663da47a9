"""The batch engine: jit(vmap(simulate -> metrics)) over fault scenarios.

Every batched caller (Monte Carlo chunks, critical clearing times, the tuner's
validation and gradient-free search, the benchmarks) evaluates its scenarios here, so
that they all run one program, built one way:

- The plant, operating point and initial estimates are compile-time constants: XLA
  folds every quantity derived from them instead of recomputing it in each field
  evaluation inside the solver's loop (measured: twice the throughput). A scenario may
  replace the plant's true damping `D` and mechanical power `Pm` (the controller does
  not know them).
- A controller's tunable part (`AbstractController.tunable`: the gains of the paper's
  law, every field of the others) is an argument: one program for any values. Its
  structure (adaptation mode, projection box, boundary layer) is compiled in.
- alpha = 1 (ASC) is compiled in as the constant 1 where every lane has it
  (`smibjax.controller.static_alpha`: the signed powers disappear).
- The batch is split over the host devices (`smibjax._parallel.device_map`).

An `Engine` holds the constants and the solver settings; `Engine.run` takes one
controller for every scenario, or one per scenario (`lanes`). Compiled programs are
cached per process by the engine's settings and the controller's type and structure.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ._metrics import DEFAULT_BANDS, Metrics, metrics
from ._options import SaveOptions, SolverOptions, adopt_legacy_solver
from ._parallel import device_map
from ._parameters import Fault, InitialEstimates, OperatingPoint, Plant
from ._simulate import simulate
from ._validate import ParameterError, is_concrete, require_positive
from .controllers import AbstractController, Gains, as_controller

__all__ = ["Engine", "Outcome", "Scenarios"]


class Scenarios(NamedTuple):
    """A batch of fault scenarios (leading axis: the scenario).

    `fault`: a batched `Fault`; `D`, `Pm`: the plant's true damping and mechanical
    power (pu) of each scenario, or None to keep the engine plant's values."""

    fault: Fault
    D: Float[Array, " n"] | None = None
    Pm: Float[Array, " n"] | None = None


class Outcome(NamedTuple):
    """What the engine returns per scenario (leading axis: the scenario)."""

    metrics: Metrics  # exact metrics of the run (`smibjax._metrics`)
    lost_sync: Bool[Array, " n"]  # the run left the controller's angle range
    budget_exhausted: Bool[Array, " n"]  # max_steps spent before t_end
    t_stop: Float[Array, " n"]  # s: t_end, or when synchronism was lost
    num_steps: Int[Array, " n"]  # accepted solver steps

    @property
    def synchronous(self) -> Bool[Array, " n"]:
        """Kept synchronism to t_end (the industry's stability criterion)."""
        return ~(self.lost_sync | self.budget_exhausted)


def _fingerprint(tree) -> tuple:
    """A hashable fingerprint of a concrete parameter set (its structure and its
    values, as float64 bits)."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    if not is_concrete(*leaves):
        raise ParameterError(
            "the batch engine compiles the plant, operating point and initial "
            "estimates in: they must be concrete values, not traced"
        )
    return (
        str(treedef),
        tuple(np.asarray(x, dtype=np.float64).tobytes() for x in leaves),
    )


@dataclasses.dataclass(frozen=True, eq=False)
class Engine:
    """Batched closed-loop runs and their exact metrics.

    `plant`, `op`, `init`: the constants of every run (defaults: the paper's);
    `t_end`, `dt_save` (s): horizon and sampling; `solver`: a `SolverOptions`
    (default: adaptive Tsit5, rtol 1e-6, atol 1e-8, 50,000 steps), passed whole to
    `simulate`; `delta_band` (rad), `Vt_band` (pu), `omega_band` (rad/s): the
    metrics' settling bands.

    The keywords `rtol`, `atol`, `max_steps` of 0.1 still work, with a
    `DeprecationWarning`, for one release (they build `solver`).
    """

    plant: Plant = dataclasses.field(default_factory=Plant)
    op: OperatingPoint = dataclasses.field(default_factory=OperatingPoint)
    init: InitialEstimates = dataclasses.field(default_factory=InitialEstimates)
    t_end: float = 10.0
    dt_save: float = 0.01
    solver: SolverOptions = dataclasses.field(default_factory=SolverOptions)
    delta_band: float = DEFAULT_BANDS["delta"]
    Vt_band: float = DEFAULT_BANDS["Vt"]
    omega_band: float = DEFAULT_BANDS["omega"]
    rtol: dataclasses.InitVar[float | None] = None  # deprecated: solver.rtol
    atol: dataclasses.InitVar[float | None] = None  # deprecated: solver.atol
    max_steps: dataclasses.InitVar[int | None] = None  # deprecated

    def __post_init__(self, rtol, atol, max_steps):
        adopt_legacy_solver(self, rtol, atol, max_steps)
        for name in ("t_end", "dt_save"):
            require_positive(name, getattr(self, name))
        from ._closed_loop import require_start

        require_start(self.plant, self.op)

    def key(self) -> tuple:
        """Everything that is compiled in (hashable)."""
        return (
            _fingerprint((self.plant, self.op, self.init)),
            float(self.t_end),
            float(self.dt_save),
            self.solver,
            float(self.delta_band),
            float(self.Vt_band),
            float(self.omega_band),
        )

    def run(
        self,
        controller,
        scenarios: Scenarios,
        *,
        lanes=None,
        devices=None,
    ) -> Outcome:
        """Simulate every scenario under `controller` and measure it.

        `controller`: any controller (`smibjax.controllers`), or the paper's `Gains`
        (oracle adaptation). `lanes`: None (the controller's own values in every
        scenario), or a batched tunable part (`controller.tunable()` stacked along a
        leading axis as long as the batch): scenario i runs the controller with the
        values of lane i. `devices`: JAX devices to split the batch over (default:
        all). Returns an `Outcome` (leading axis: the scenario)."""
        if not isinstance(controller, (AbstractController, Gains)):
            raise ParameterError(
                f"controller = {controller!r} is not allowed: must be a controller "
                "(smibjax.controllers) or Gains"
            )
        template = as_controller(controller)
        values = template.tunable() if lanes is None else lanes
        alpha_one = _all_alpha_one(template, values)
        key = (
            self.key(),
            type(template),
            template.structure(),
            alpha_one,
            lanes is not None,
            scenarios.D is not None,
            scenarios.Pm is not None,
        )
        fn = _PROGRAMS.get(key)
        if fn is None:
            if len(_PROGRAMS) >= _MAX_PROGRAMS:
                _PROGRAMS.pop(next(iter(_PROGRAMS)))
            fn = _PROGRAMS[key] = _program(self, template, *key[3:])
        values = jax.tree_util.tree_map(jnp.asarray, values)
        if lanes is None:
            return device_map(fn, values, scenarios, devices)
        return device_map(
            lambda _, batch: fn(*batch), None, (values, scenarios), devices
        )


def _all_alpha_one(template, values) -> bool:
    """True where the controller has an alpha and every given value of it is 1."""
    if not hasattr(template, "with_static_alpha"):
        return False
    alpha = getattr(values, "alpha", None)
    if alpha is None or not is_concrete(alpha):
        return False
    return bool(np.all(np.asarray(alpha) == 1.0))


# Compiled batch functions of this process, by (engine key, controller type and
# structure, alpha_one, per-lane, D drawn, Pm drawn); oldest dropped first.
_PROGRAMS: dict[tuple, object] = {}
_MAX_PROGRAMS = 16


def _program(
    e: Engine,
    template: AbstractController,
    alpha_one: bool,
    per_lane: bool,
    draw_D: bool,
    draw_Pm: bool,
):
    """The jitted batch function for one engine and controller structure, compiled
    once per batch shape and reused for every call (the template's tunable values
    are replaced by the argument; its structure is compiled in)."""
    plant, op, init = e.plant, e.op, e.init

    def one(values, fault, d, pm):
        ctrl = template.with_tunable(values)
        if alpha_one:
            ctrl = ctrl.with_static_alpha(True)
        p = plant
        if draw_D and draw_Pm:
            p = eqx.tree_at(lambda q: (q.D, q.Pm), plant, (d, pm))
        elif draw_D:
            p = eqx.tree_at(lambda q: q.D, plant, d)
        elif draw_Pm:
            p = eqx.tree_at(lambda q: q.Pm, plant, pm)
        tr = simulate(
            ctrl,
            fault,
            p,
            op=op,
            init=init,
            solver=e.solver,
            save=SaveOptions(e.t_end, e.dt_save),
        )
        return Outcome(
            metrics(tr, e.delta_band, e.Vt_band, e.omega_band),
            tr.lost_sync,
            tr.budget_exhausted,
            tr.t_stop,
            tr.num_steps,
        )

    @eqx.filter_jit
    def run(values, scenarios: Scenarios):
        return jax.vmap(one, in_axes=(0 if per_lane else None, 0, 0, 0))(
            values, scenarios.fault, scenarios.D, scenarios.Pm
        )

    return run
