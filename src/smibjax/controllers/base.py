"""The controller interface: what the closed loop asks of any controller.

A controller is an equinox Module whose fields are its parameters (so a controller can
be vmapped over, differentiated and tuned like any pytree). From the measured plant
state z = (delta, domega, E, B), its own internal state s and the network stage in
force (for measured quantities such as the SVC-bus voltage), it computes the commanded
inputs (u_f, u_r) (before the plant's limits), ds/dt and two diagnostic signals.
"""

from __future__ import annotations

import abc
import math
from typing import ClassVar, NamedTuple

import equinox as eqx
from jaxtyping import Array, Float

from .._network import Stage
from .._parameters import InitialEstimates, OperatingPoint, Plant
from .._plant import Trig
from .._validate import ParameterError

__all__ = ["AbstractController", "ControllerOutput"]

Scalar = Float[Array, ""]


class ControllerOutput(NamedTuple):
    """What a controller computes from one measurement."""

    u_f: Scalar  # field-voltage command (pu), before the plant's limits
    u_r: Scalar  # SVC command (pu), before the plant's limits
    d_internal: Float[Array, " k"]  # d/dt of the controller's internal state
    diagnostics: Float[Array, 2]  # two signals named by `diagnostic_names`


class AbstractController(eqx.Module):
    """A controller of the SMIB + SVC plant.

    Subclasses set the class variables and implement `initial_internal` and
    `__call__`; `parameter_kinds` names the tunable fields and the transform that
    keeps each legal while it trains (see `tuning/params.py`: `log` for > 0,
    `softplus` for >= 0, `inverse` for a non-zero sign-free gain, `alpha` for
    (1/2, 1], `free`).
    """

    n_internal: ClassVar[int]
    has_estimates: ClassVar[bool] = False  # internal[:2] estimates theta = (-D, Pm)
    diagnostic_names: ClassVar[tuple[str, str]] = ("-", "-")
    # The rotor angles (rad) inside which the run keeps synchronism: a pole slip at
    # +-pi in general; the paper's law is singular at 0 and pi (docs/model.md section 3)
    # and narrows it to (0, pi).
    angle_range: ClassVar[tuple[float, float]] = (-math.pi, math.pi)

    @abc.abstractmethod
    def initial_internal(
        self,
        z0: Float[Array, 4],
        plant: Plant,
        op: OperatingPoint,
        init: InitialEstimates,
    ) -> Float[Array, " k"]:
        """The internal state at t = 0 (the plant is at its operating point z0)."""

    @abc.abstractmethod
    def __call__(
        self,
        t: Scalar,
        z: Float[Array, 4],
        s: Float[Array, " k"],
        stage: Stage,
        plant: Plant,
        op: OperatingPoint,
        trig: Trig | None = None,
    ) -> ControllerOutput:
        """Commanded inputs, internal-state derivative and diagnostics at time t (s).
        `trig`: (sin delta, cos delta) of the measured angle when the caller has
        them (`smibjax._plant.sincos`: the closed loop computes them once per
        evaluation for the controller and the plant); None: compute them."""

    def parameters(self) -> dict[str, float]:
        """The tunable parameters as plain floats (the gains-file layout)."""
        return {n: float(getattr(self, n)) for n in self.parameter_kinds()}

    # The split a batch engine needs (`smibjax._batch`): the tunable part of a
    # controller is traced (one compiled program for any values, vmapped over lanes
    # where every lane has its own), the rest is its structure, compiled in.

    def tunable(self) -> eqx.Module:
        """The tunable part (a pytree of arrays): by default the controller itself,
        whose fields are all parameters."""
        return self

    def with_tunable(self, tunable: eqx.Module) -> AbstractController:
        """This controller with its tunable part replaced (the inverse of
        `tunable`)."""
        return tunable

    def structure(self) -> tuple:
        """A hashable description of everything that is not `tunable()`: two
        controllers of one type and structure differ only in tunable values."""
        return ()

    @classmethod
    @abc.abstractmethod
    def parameter_kinds(cls) -> dict[str, str]:
        """Tunable parameter name -> transform kind (see the class docstring)."""

    # What the core asks of a controller beyond its dynamics: the simulator, the
    # closed loop, CCT, Monte Carlo, gains files, the command line and the tuner ask
    # here, never by the controller's type. The defaults fit a controller without an
    # adaptation mode or options (none, avr-pss).

    # True: the controller has an adaptation mode ("oracle" or "realizable",
    # `with_adaptation`) and its parameter set is a separate pytree (`parameter_set`).
    has_adaptation: ClassVar[bool] = False
    # True: a conventional controller (exciter, PSS, regulators) designed for a plant
    # whose inputs have ceilings; on the paper plant (no input limits) its commands
    # are unrealistic (avr-pss: Vt up to 1.89 pu), so the commands note it
    # (`smibjax.cli.options.plant_note`).
    conventional: ClassVar[bool] = False
    # The option names a gains file or Monte Carlo spec may give (`check_options`).
    option_names: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def parameter_set(cls, name: str, values: dict[str, float]):
        """The parameter set of registry name `name` with `values` overriding the
        defaults (names already checked): the controller itself by default."""
        return cls(**values)

    @classmethod
    def parameter_type(cls) -> type:
        """The class whose fields are the tunable parameters (the tuner builds it
        from a table): the controller itself by default."""
        return cls

    @classmethod
    def required_parameters(cls) -> tuple[str, ...]:
        """The parameters a gains file for batch studies must give (none: the
        defaults stand in)."""
        return ()

    @classmethod
    def check_options(cls, name: str, options: dict) -> dict:
        """The validated options of a gains file or spec for controller `name`
        (raises `ParameterError` with one line); without options only {} is
        allowed."""
        if options:
            bad = next(iter(options))
            raise ParameterError(
                f"option {bad!r} is not allowed for controller {name!r}: it has "
                "no options"
            )
        return {}

    @classmethod
    def options_for_file(cls, name: str, values: dict, options: dict) -> tuple:
        """(registry name, options) a gains file written by the tuner records for
        tuned `values` and the configured `options`: the name and no options by
        default."""
        return name, {}

    @classmethod
    def from_parameters(
        cls, params, adaptation: str = "oracle", options: dict | None = None
    ) -> AbstractController:
        """The controller that runs parameter set `params` (`parameter_set`) under
        the adaptation mode and the options: `params` itself by default."""
        return params

    def with_adaptation(self, adaptation: str | None) -> AbstractController:
        """This controller under the adaptation mode `adaptation` (None: its own);
        a controller without one ignores it."""
        return self

    def specialized(self) -> AbstractController:
        """The controller to compile: values known to be special compiled in as
        constants (the paper's law at alpha = 1). Itself by default."""
        return self

    def placeholder_internal(
        self,
        z0: Float[Array, 4],
        plant: Plant,
        op: OperatingPoint,
        init: InitialEstimates,
    ) -> Float[Array, " k"]:
        """A harmless internal state for the closed loop's out-of-domain fallback,
        without the checks of `initial_internal` (by default it)."""
        return self.initial_internal(z0, plant, op, init)

    def check_estimates(self, init: InitialEstimates) -> None:
        """Raise `ParameterError` (one line) where the initial estimates, concrete
        and of any batch shape, are not allowed for this controller; by default
        any are."""

    def label(self) -> str:
        """A one-line label for titles and reports."""
        return type(self).__name__
