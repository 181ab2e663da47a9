"""Device models, one module per PSS/E dyr model, each a group vectorized over its
devices (see `base`)."""

from .csvgn1 import CSVGN1 as CSVGN1
from .direct import DirectField as DirectField
from .direct import DirectSVC as DirectSVC
from .exst1 import EXST1 as EXST1
from .gencls import GENCLS as GENCLS
from .genroe import GENROE as GENROE
from .genrou import GENROU as GENROU
from .gensae import GENSAE as GENSAE
from .gensal import GENSAL as GENSAL
from .gentra import GENTRA as GENTRA
from .ieeest import IEEEST as IEEEST
from .ieeex1 import EXDC2 as EXDC2
from .ieeex1 import IEEEX1 as IEEEX1
from .sexs import SEXS as SEXS
from .stab1 import STAB1 as STAB1
from .synex import SYNEX as SYNEX
from .tgov1 import TGOV1 as TGOV1

# isort: split
# issue 45: exciters and the load compensator
from .esdc2a import ESDC1A as ESDC1A
from .esdc2a import ESDC2A as ESDC2A
from .esst3a import ESST3A as ESST3A

# governors and stabilizers of issue 45
from .gast import GAST as GAST
from .hygov import HYGOV as HYGOV
from .ieeeg1 import IEEEG1 as IEEEG1
from .ieeet1 import IEEET1 as IEEET1
from .ieeet2 import IEEET2 as IEEET2
from .ieeevc import IEEEVC as IEEEVC
from .ieesgo import IEESGO as IEESGO
from .pss2 import PSS2A as PSS2A
from .pss2 import PSS2B as PSS2B
from .scrx import SCRX as SCRX
from .st2cut import ST2CUT as ST2CUT
from .stab2a import STAB2A as STAB2A

# isort: split
# issue 47: loads as current injectors
from .zipload import ZIPLoad as ZIPLoad
