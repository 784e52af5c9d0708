"""Constraint equations, equations of motion and assembly."""

from ._assembly import assemble_state as assemble_state
from ._constraints import constraint_jacobian as constraint_jacobian
from ._constraints import constraint_velocity as constraint_velocity
from ._constraints import constraints as constraints
from ._constraints import gamma as gamma
from ._equations import evaluate as evaluate
from ._equations import vector_field as vector_field
