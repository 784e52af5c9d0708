"""Post-processing: energy, contact modes, run statistics; identification and design optimisation."""

from ._energy import drive_power as drive_power
from ._energy import drive_work as drive_work
from ._energy import kinetic_energy as kinetic_energy
from ._energy import potential_energy as potential_energy
from ._identify import Estimate as Estimate
from ._identify import IdentificationResult as IdentificationResult
from ._identify import identify as identify
from ._modes import CONTINUOUS as CONTINUOUS
from ._modes import FREE as FREE
from ._modes import IMPACT as IMPACT
from ._modes import MODE_NAMES as MODE_NAMES
from ._modes import combination_shares as combination_shares
from ._modes import contact_modes as contact_modes
from ._modes import trajectory_modes as trajectory_modes
from ._optimize import OptimizationResult as OptimizationResult
from ._optimize import optimize as optimize
from ._optimize import start_offsets as start_offsets
from ._parameter_space import FitParameter as FitParameter
from ._statistics import statistics as statistics
