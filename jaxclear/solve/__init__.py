"""Solving: the front door ``simulate``, solver settings and presets, the custom stepping methods
(Lawson, IMEX), extremes tracked in the solve, start-up helpers and the ``Trajectory`` result."""

from ._extremes import combine_extremes as combine_extremes
from ._lanes import MemberSolutions as MemberSolutions
from ._lanes import solve_members as solve_members
from ._simulate import assemble as assemble
from ._simulate import failure_error as failure_error
from ._simulate import simulate as simulate
from ._simulate import simulate_batch as simulate_batch
from ._solver import METHODS as METHODS
from ._solver import PRESETS as PRESETS
from ._solver import SolverConfig as SolverConfig
from ._solver import gradient_solver as gradient_solver
from ._solver import recommended_solver as recommended_solver
from ._solver import solver_config as solver_config
from ._startup import ideal_mechanism as ideal_mechanism
from ._startup import wall_start as wall_start
from ._trajectory import BODY_OUTPUTS as BODY_OUTPUTS
from ._trajectory import CLEARANCE_OUTPUTS as CLEARANCE_OUTPUTS
from ._trajectory import Trajectory as Trajectory
from ._trajectory import finite_rows as finite_rows
from ._trajectory import join_trajectories as join_trajectories
from ._trajectory import window as window
