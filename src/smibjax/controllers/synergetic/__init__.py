"""The paper's adaptive synergetic law, in one place (docs/model.md section 2):

- `law`: the control law and the adaptation in the paper's coordinates (eqs. 21-22,
  36-37), the signed power and the affine model's closed forms;
- `gains`: its parameter set `Gains`;
- `options`: the projection box of the estimates and the boundary layer;
- `transforms`: the tuner's transform of each gain;
- `controller`: `Synergetic`, the law as a controller of the closed loop.
"""

from .controller import Synergetic as Synergetic
from .gains import GAIN_NAMES as GAIN_NAMES
from .gains import Gains as Gains
from .law import ControlOutput as ControlOutput
from .law import adaptation_rate as adaptation_rate
from .law import control_law as control_law
from .law import drift_and_gain as drift_and_gain
from .law import drift_and_gain_closed_form as drift_and_gain_closed_form
from .law import evolution as evolution
from .law import paper_coordinates as paper_coordinates
from .law import spow as spow
from .law import static_alpha as static_alpha
from .options import EstimateBox as EstimateBox
from .options import project as project
from .options import synergetic_options as synergetic_options
from .transforms import GAIN_KINDS as GAIN_KINDS

__all__ = [
    "Synergetic",
    "GAIN_NAMES",
    "Gains",
    "ControlOutput",
    "adaptation_rate",
    "control_law",
    "drift_and_gain",
    "drift_and_gain_closed_form",
    "evolution",
    "paper_coordinates",
    "spow",
    "static_alpha",
    "EstimateBox",
    "project",
    "synergetic_options",
    "GAIN_KINDS",
]
