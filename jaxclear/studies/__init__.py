"""Studies: everything that runs many solves. The vectorised ensemble engine and the file-backed
ensemble run, Monte Carlo over tolerances (distributions, ISO 286 fits), sweeps, Poincaré sections
and bifurcation diagrams, Lyapunov exponents, identification and design optimisation."""

from .._core._errors import EnsembleError as EnsembleError
from ._distributions import AbstractDistribution as AbstractDistribution
from ._distributions import Fixed as Fixed
from ._distributions import IsoFit as IsoFit
from ._distributions import LogNormal as LogNormal
from ._distributions import Normal as Normal
from ._distributions import Uniform as Uniform
from ._distributions import distribution_from_spec as distribution_from_spec
from ._engine import EnsembleSettings as EnsembleSettings
from ._ensemble import run_ensemble as run_ensemble
from ._ensemble_result import EnsembleResult as EnsembleResult
from ._identify import Estimate as Estimate
from ._identify import FitSettings as FitSettings
from ._identify import IdentificationResult as IdentificationResult
from ._identify import identify as identify
from ._iso286 import fit_clearance as fit_clearance
from ._iso286 import fit_zones as fit_zones
from ._iso286 import standard_tolerance as standard_tolerance
from ._iso286 import tolerance_zone as tolerance_zone
from ._lyapunov import ConstraintProjection as ConstraintProjection
from ._lyapunov import LyapunovResult as LyapunovResult
from ._lyapunov import LyapunovSweep as LyapunovSweep
from ._lyapunov import MechanismFlow as MechanismFlow
from ._lyapunov import ODEFlow as ODEFlow
from ._lyapunov import flow_lyapunov as flow_lyapunov
from ._lyapunov import largest_lyapunov as largest_lyapunov
from ._lyapunov import lyapunov_solver as lyapunov_solver
from ._lyapunov import lyapunov_sweep as lyapunov_sweep
from ._lyapunov import mechanism_weights as mechanism_weights
from ._lyapunov import two_trajectory_lyapunov as two_trajectory_lyapunov
from ._montecarlo import draw as draw
from ._montecarlo import montecarlo as montecarlo
from ._montecarlo import sweep as sweep
from ._montecarlo import sweep_values as sweep_values
from ._optimize import OptimizationResult as OptimizationResult
from ._optimize import optimize as optimize
from ._optimize import start_offsets as start_offsets
from ._parameter_space import FitParameter as FitParameter
from ._poincare import BifurcationDiagram as BifurcationDiagram
from ._poincare import bifurcation_points as bifurcation_points
from ._poincare import default_section_signals as default_section_signals
from ._poincare import poincare_section as poincare_section
from ._poincare import section_times as section_times
