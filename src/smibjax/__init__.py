"""smibjax: a differentiable simulator of a single-machine-infinite-bus power system
with a static var compensator under adaptive (finite-time) synergetic control.

The names below are the public API; the modules that define them are private
(`smibjax._simulate`, ...), except the subpackages `smibjax.controllers` (the
controller interface, the registry and the paper's law, `controllers.synergetic`)
and `smibjax.cli` (the command line).

Importing smibjax changes nothing in your process: it sets no JAX option, no
environment variable and no matplotlib backend, and it loads its modules (and JAX)
only when a name is first used. smibjax needs JAX's 64-bit mode (the closed loop is
stiff and the finite-time law works near phi = 0, where float32 is not enough); set
it before you create any array, or let `configure` set it with the rest of what the
command line sets up (host devices, the compilation cache):

    import smibjax as sj
    sj.configure()  # or: jax.config.update("jax_enable_x64", True)

`sj.simulate` refuses to run without it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._face import lazy_face

__version__ = "0.1.0"

if TYPE_CHECKING:  # the public names; loaded on first use (`__getattr__`)
    from ._batch import Engine as Engine
    from ._batch import Outcome as Outcome
    from ._batch import Scenarios as Scenarios
    from ._cct import CCTResult as CCTResult
    from ._cct import critical_clearing_times as critical_clearing_times
    from ._closed_loop import ClosedLoop as ClosedLoop
    from ._closed_loop import closed_loop_vector_field as closed_loop_vector_field
    from ._closed_loop import initial_state as initial_state
    from ._gainsfile import GainsFile as GainsFile
    from ._losses import TERM_NAMES as TERM_NAMES
    from ._losses import LossWeights as LossWeights
    from ._losses import aggregate as aggregate
    from ._losses import loss_terms as loss_terms
    from ._losses import scenario_loss as scenario_loss
    from ._metrics import Metrics as Metrics
    from ._metrics import metrics as metrics
    from ._metrics import physics_summary as physics_summary
    from ._montecarlo import MonteCarloResult as MonteCarloResult
    from ._montecarlo import MonteCarloSpec as MonteCarloSpec
    from ._montecarlo import monte_carlo as monte_carlo
    from ._network import Stage as Stage
    from ._network import fault_stage as fault_stage
    from ._network import stage_at as stage_at
    from ._options import SaveOptions as SaveOptions
    from ._options import SolverOptions as SolverOptions
    from ._parallel import device_map as device_map
    from ._parallel import shard_batch as shard_batch
    from ._parameters import FAULT_NAMES as FAULT_NAMES
    from ._parameters import PLANT_NAMES as PLANT_NAMES
    from ._parameters import Fault as Fault
    from ._parameters import InitialEstimates as InitialEstimates
    from ._parameters import OperatingPoint as OperatingPoint
    from ._parameters import ParameterError as ParameterError
    from ._parameters import Plant as Plant
    from ._plant import electrical_power as electrical_power
    from ._plant import plant_vector_field as plant_vector_field
    from ._plant import terminal_voltage as terminal_voltage
    from ._process import configure as configure
    from ._scenarios import FaultDistribution as FaultDistribution
    from ._scenarios import ScenarioDistribution as ScenarioDistribution
    from ._scenarios import sample_faults as sample_faults
    from ._scenarios import sample_scenarios as sample_scenarios
    from ._simulate import Trajectory as Trajectory
    from ._simulate import simulate as simulate
    from .controllers import AbstractController as AbstractController
    from .controllers import AvrPss as AvrPss
    from .controllers import NoControl as NoControl
    from .controllers import Synergetic as Synergetic
    from .controllers import make_controller as make_controller
    from .controllers.synergetic import GAIN_NAMES as GAIN_NAMES
    from .controllers.synergetic import EstimateBox as EstimateBox
    from .controllers.synergetic import Gains as Gains


_EXPORTS, __getattr__, __dir__ = lazy_face(
    __file__, __name__, ("controllers", "cli", "grid")
)
__all__ = sorted(_EXPORTS)
