"""Names the command line shares with the library that are not part of the user API.

``jaxclear.cli`` enters the library through public names (``jaxclear``, ``jaxclear.solve``,
``jaxclear.studies``, ``jaxclear.io``, ``jaxclear.plot``, ...) and through this module only, as
``equinox.internal`` serves equinox's own extensions. These names may change without notice.
"""

from ._core._error_mode import set_error_mode as set_error_mode
from .solve._lanes import DEFAULT_LANES as DEFAULT_LANES
from .studies._engine import DEFAULT_CHUNK as DEFAULT_CHUNK
from .studies._engine import ENGINES as ENGINES
from .studies._ensemble import EVENTS_PER_REVOLUTION as EVENTS_PER_REVOLUTION
from .studies._ensemble import inadmissible_values as inadmissible_values
from .studies._ensemble_result import MANIFEST as MANIFEST
from .studies._ensemble_result import ResumeWarning as ResumeWarning
from .studies._ensemble_result import configuration_differences as configuration_differences
from .studies._ensemble_result import read_table as read_table
from .studies._fit_settings import NOISE_LEVEL_LOSS as NOISE_LEVEL_LOSS
from .studies._identify import check_identification as check_identification
