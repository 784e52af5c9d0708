"""The shared base of what adds generalised forces and internal states: force elements and clearance
joints (docs/model.md §1, Q).

The integrator state is y = (q, q̇, internal states of each such element in the order of
``Mechanism.force_elements``). This base declares what that layout needs of an element: its name,
the bodies it acts on and how many internal states it adds. The model is data only: how each kind
of element is evaluated (forces, state rates, the stiff rates of IMEX solvers) is the equations'
business, through one interface per evaluation group (``_groups.py`` beside the equations of
motion).
"""

import abc

import equinox as eqx


class AbstractStateElement(eqx.Module):
    """Base of the parts that add generalised forces and internal states.

    Subclassed by ``AbstractForceElement`` (applied forces, springs, user elements) and
    ``ClearanceJoint``.
    """

    name: eqx.AbstractVar[str]

    @property
    @abc.abstractmethod
    def bodies(self) -> tuple[str, ...]:
        """Names of the bodies the element acts on (``"ground"`` allowed); checked by ``Mechanism``."""

    @property
    @abc.abstractmethod
    def num_states(self) -> int:
        """Number of internal states this element adds to the integrator state (static)."""
