"""Multi-machine power systems as data (PSS/E raw + dyr), their power flow, network
solution and devices, integrated as one jitted, vmappable, differentiable closed loop.

The names below are the public face of the grid model; the modules that define them
are its parts (`case`, `psse`, `powerflow`, `operating`, `events`, `scenarios`,
`simulate`, `metrics`, `params`, `modes`, `cct`, `damping`, `devices`). As with
`smibjax` itself, nothing is loaded (and JAX is not imported) until a name is first
used:

    import smibjax.grid as sg

    case = sg.load_case("kundur")
    op, pf = sg.operating_point(case)
    fault = sg.BusFault(bus=7, t_on=1.0, t_off=1.1)  # bus position 7: bus 8
    traj = sg.simulate_case(case, op, [fault], t_end=5.0)
    m = sg.grid_metrics(case, traj, 1.0)  # metrics from the first event at 1 s

(The modes of a case: `smibjax.grid.modes.modes`, beside `linearize` and `Mode`
here; the submodule `modes` shares the function's name, so the function is not a
name of this face.)

Every refusal of input (a file, a case, a parameter name, a power flow with no
solution) is a `smibjax.ParameterError` (see `smibjax._errors`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._face import lazy_face

if TYPE_CHECKING:  # the public names; loaded on first use (`__getattr__`)
    from .case import BUILTIN as BUILTIN
    from .case import CaseError as CaseError
    from .case import build_case as build_case
    from .case import load_case as load_case
    from .cct import critical_clearing_times_grid as critical_clearing_times_grid
    from .damping import damping_loss as damping_loss
    from .damping import mode_damping as mode_damping

    # issue 48: parameters written back into the case's dyr file
    from .dyr_write import DyrChange as DyrChange
    from .dyr_write import DyrRewrite as DyrRewrite
    from .dyr_write import dyr_updates as dyr_updates
    from .dyr_write import rewrite_dyr as rewrite_dyr
    from .events import BranchClose as BranchClose
    from .events import BranchTrip as BranchTrip
    from .events import BusFault as BusFault
    from .events import GenTrip as GenTrip
    from .events import LineFault as LineFault

    # issue 47: load and reference steps, loads as PSS/E models them
    from .events import LoadStep as LoadStep
    from .events import RefStep as RefStep
    from .loads import LoadModel as LoadModel
    from .loads import with_load_model as with_load_model
    from .loop import Case as Case
    from .loop import Operating as Operating
    from .metrics import GridMetrics as GridMetrics
    from .metrics import batch_metrics as batch_metrics
    from .metrics import grid_metrics as grid_metrics
    from .modes import Linearization as Linearization
    from .modes import Mode as Mode
    from .modes import linearize as linearize
    from .operating import operating_point as operating_point
    from .params import ParamError as ParamError
    from .params import get_param as get_param
    from .params import set_params as set_params
    from .params import tunable_names as tunable_names
    from .powerflow import PowerFlowError as PowerFlowError
    from .powerflow import PowerFlowResult as PowerFlowResult
    from .powerflow import power_flow as power_flow
    from .psse import DYR_MODELS as DYR_MODELS
    from .psse import PsseError as PsseError
    from .psse import read_dyr as read_dyr
    from .psse import read_raw as read_raw
    from .scenarios import FaultDistribution as FaultDistribution
    from .scenarios import sample_events as sample_events
    from .simulate import GridTrajectory as GridTrajectory
    from .simulate import coi_angles as coi_angles
    from .simulate import simulate_case as simulate_case


_EXPORTS, __getattr__, __dir__ = lazy_face(__file__, __name__)
__all__ = sorted(_EXPORTS)
