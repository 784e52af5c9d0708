"""Analysis: functions of one result. Named signals, run statistics, energy, contact modes,
spectra, phase portraits. Workflows that run many solves are in ``jaxclear.studies``."""

from ._energy import drive_power as drive_power
from ._energy import drive_work as drive_work
from ._energy import kinetic_energy as kinetic_energy
from ._energy import potential_energy as potential_energy
from ._modes import CONTINUOUS as CONTINUOUS
from ._modes import DEFAULT_CONTINUOUS_FRACTION as DEFAULT_CONTINUOUS_FRACTION
from ._modes import FREE as FREE
from ._modes import IMPACT as IMPACT
from ._modes import MODE_NAMES as MODE_NAMES
from ._modes import all_combinations as all_combinations
from ._modes import combination_label as combination_label
from ._modes import combination_shares as combination_shares
from ._modes import contact_events as contact_events
from ._modes import contact_joints as contact_joints
from ._modes import contact_modes as contact_modes
from ._modes import corner_pair_channels as corner_pair_channels
from ._modes import event_mode_shares as event_mode_shares
from ._modes import trajectory_modes as trajectory_modes
from ._orbits import distinct_points as distinct_points
from ._orbits import phase_portrait as phase_portrait
from ._signals import signal_names as signal_names
from ._signals import signals as signals
from ._spectrum import WINDOWS as WINDOWS
from ._spectrum import amplitude_spectrum as amplitude_spectrum
from ._spectrum import signal_spectrum as signal_spectrum
from ._statistics import statistic_names as statistic_names
from ._statistics import statistics as statistics
