"""jaxclear: differentiable planar multibody dynamics with revolute clearance joints.

Importing jaxclear turns on float64 in JAX (penetrations of micrometres are differences of
coordinates of order 0.1 m).
"""

import jax

jax.config.update("jax_enable_x64", True)

from . import analysis as analysis  # noqa: E402
from . import mechanisms as mechanisms  # noqa: E402
from ._core._errors import AssemblyError as AssemblyError  # noqa: E402
from ._core._errors import DataError as DataError  # noqa: E402
from ._core._errors import EnsembleError as EnsembleError  # noqa: E402
from ._core._errors import InputCheck as InputCheck  # noqa: E402
from ._core._errors import ModelError as ModelError  # noqa: E402
from ._core._errors import SimulationError as SimulationError  # noqa: E402
from ._core._executable_cache import compilation_cache_folder as compilation_cache_folder  # noqa: E402
from ._core._executable_cache import compilation_cache_statistics as compilation_cache_statistics  # noqa: E402
from ._core._executable_cache import disable_compilation_cache as disable_compilation_cache  # noqa: E402
from ._core._executable_cache import enable_compilation_cache as enable_compilation_cache  # noqa: E402
from .analysis._signals import signal_names as signal_names  # noqa: E402
from .analysis._signals import signals as signals  # noqa: E402
from .contact import Lubrication as Lubrication  # noqa: E402
from .io._measurements import Measurements as Measurements  # noqa: E402
from .model import AbstractDriver as AbstractDriver  # noqa: E402
from .model import AbstractForceElement as AbstractForceElement  # noqa: E402
from .model import AbstractJoint as AbstractJoint  # noqa: E402
from .model import AbstractStateElement as AbstractStateElement  # noqa: E402
from .model import AppliedForce as AppliedForce  # noqa: E402
from .model import AppliedTorque as AppliedTorque  # noqa: E402
from .model import Body as Body  # noqa: E402
from .model import ClearanceJoint as ClearanceJoint  # noqa: E402
from .model import ConstantSpeedDriver as ConstantSpeedDriver  # noqa: E402
from .model import FunctionDriver as FunctionDriver  # noqa: E402
from .model import Mechanism as Mechanism  # noqa: E402
from .model import ParameterInfo as ParameterInfo  # noqa: E402
from .model import RevoluteJoint as RevoluteJoint  # noqa: E402
from .model import SpringDamper as SpringDamper  # noqa: E402
from .model import TranslationalClearanceJoint as TranslationalClearanceJoint  # noqa: E402
from .model import TranslationalJoint as TranslationalJoint  # noqa: E402
from .model import get_parameter as get_parameter  # noqa: E402
from .model import parameter_info as parameter_info  # noqa: E402
from .model import parameter_names as parameter_names  # noqa: E402
from .model import with_parameters as with_parameters  # noqa: E402
from .solve._simulate import assemble as assemble  # noqa: E402
from .solve._simulate import simulate as simulate  # noqa: E402
from .solve._simulate import simulate_batch as simulate_batch  # noqa: E402
from .solve._solver import PRESETS as PRESETS  # noqa: E402
from .solve._solver import SolverConfig as SolverConfig  # noqa: E402
from .solve._solver import gradient_solver as gradient_solver  # noqa: E402
from .solve._solver import recommended_solver as recommended_solver  # noqa: E402
from .solve._startup import ideal_mechanism as ideal_mechanism  # noqa: E402
from .solve._startup import wall_start as wall_start  # noqa: E402
from .solve._trajectory import Trajectory as Trajectory  # noqa: E402
from .studies import EnsembleSettings as EnsembleSettings  # noqa: E402
from .studies import FitParameter as FitParameter  # noqa: E402
from .studies import FitSettings as FitSettings  # noqa: E402
from .studies import identify as identify  # noqa: E402
from .studies import montecarlo as montecarlo  # noqa: E402
from .studies import optimize as optimize  # noqa: E402
from .studies import run_ensemble as run_ensemble  # noqa: E402
from .studies import sweep as sweep  # noqa: E402

__version__ = "0.1.0"
