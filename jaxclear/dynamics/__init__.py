"""Constraint equations, clearance-joint physics, equations of motion and assembly."""

from ._assembly import assemble_state as assemble_state
from ._clearance import ClearanceOutputs as ClearanceOutputs
from ._clearance import ContactForces as ContactForces
from ._clearance import JointKinematics as JointKinematics
from ._constraints import constraint_jacobian as constraint_jacobian
from ._constraints import constraint_velocity as constraint_velocity
from ._constraints import constraints as constraints
from ._constraints import gamma as gamma
from ._equations import UNROLLED_SOLVE_MAX as UNROLLED_SOLVE_MAX
from ._equations import Evaluation as Evaluation
from ._equations import clearance_outputs as clearance_outputs
from ._equations import evaluate as evaluate
from ._equations import initial_state as initial_state
from ._equations import spd_solve as spd_solve
from ._equations import vector_field as vector_field
