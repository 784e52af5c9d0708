"""Evaluation groups: the force elements and clearance joints as the equations of motion evaluate them.

Everything that adds generalised forces and internal states (``jaxclear.model.AbstractStateElement``)
is evaluated through one interface, ``AbstractEvaluationGroup``: the generalised force with a cache
(and, in an implicit IMEX stage, the stage's internal states), the state rates from that cache,
the stiff rates, the initial states. A group is one force element (``ForceElementGroup``: its own
hooks), one clearance joint (``ClearanceJointGroup``: ``dynamics._clearance``) or several
clearance joints of the same kind evaluated in one vmap (``BatchedClearanceJoints``:
``dynamics._batched``) or one translational clearance joint (``TranslationalClearanceGroup``:
``dynamics._translational``). The equations loop once over ``evaluation_groups``.

The order of the groups is the order of the terms in the sum of generalised forces (after
gravity): the force elements in order, then the clearance groups in the order of their first
joints, then the translational clearance joints. Results are reproducible to the last bit only in that order (the contact history of a
long run forks under rounding-level changes).
"""

import abc
from typing import Any, ClassVar

import equinox as eqx
import jax
from jaxtyping import Array, Float

from ..model._clearance import ClearanceJoint
from ..model._forces import AbstractForceElement
from ..model._translational_clearance import TranslationalClearanceJoint
from . import _clearance as clearance
from . import _translational as translational
from ._batched import (
    batched_force_and_cache,
    batched_state_rates,
    batched_stiff_rates,
    groups,
)


class GroupCache(eqx.Module):
    """What a group's force evaluation hands on (``AbstractEvaluationGroup.force_and_cache``).

    Attributes:
        shared: work shared between the forces and the state rates: a force element's cache from
            its ``force_and_cache``; a clearance group's (``JointKinematics``, ``ContactForces``),
            stacked over the joints of a batched group.
        stage: in an implicit IMEX stage (``gamma_h`` given): (the internal states solved for the
            stage, the stiff rates at them), stacked like ``shared``; ``None`` otherwise.
    """

    shared: Any
    stage: tuple[Array, Array] | None = None


class AbstractEvaluationGroup(eqx.Module):
    """Base of the evaluation groups: what the equations of motion call on the parts that add
    generalised forces and internal states.

    Values of several elements come "stacked" (a leading axis over the group's joints) or as dicts
    {element name: value}; ``per_element`` turns the first into the second.
    """

    @abc.abstractmethod
    def per_element(self, stacked) -> dict[str, Array]:
        """{element name: its entry of ``stacked``} (e.g. ``GroupCache.stage`` parts)."""

    @abc.abstractmethod
    def initial_states(self, mechanism, q, qd) -> dict[str, Float[Array, " s"]]:
        """{element name: internal state at the start}, given assembled q, q̇."""

    @abc.abstractmethod
    def force_and_cache(
        self, mechanism, t, q, qd, states: dict, gamma_h=None
    ) -> tuple[Float[Array, " n"], GroupCache]:
        """(Q contribution of the group (size of q), cache for ``state_rates``).

        ``gamma_h``: in an implicit stage of an IMEX method (``dynamics._equations.implicit_stage``)
        ``states`` hold the stage's explicit parts P; the force is evaluated at the internal states
        s solving s = P + γh f_I(s) (closed form: the stiff parts are affine and diagonal), which the
        cache's ``stage`` holds with f_I(s).
        """

    @abc.abstractmethod
    def state_rates(
        self, mechanism, cache: GroupCache, t, q, qd, qdd, states: dict
    ) -> dict[str, Float[Array, " s"]]:
        """{element name: internal-state rate}; ``qdd`` is this evaluation's acceleration."""

    @abc.abstractmethod
    def stiff_rates(self, mechanism, t, q, qd, states: dict) -> dict[str, Float[Array, " s"]]:
        """{element name: stiff part of the internal-state rate} (taken implicitly by IMEX solvers)."""

    @abc.abstractmethod
    def contacts(self, cache: GroupCache) -> dict[str, tuple]:
        """{clearance joint name: (``JointKinematics``, ``ContactForces``)} of the force
        evaluation that gave ``cache`` (empty for force elements)."""


class ForceElementGroup(AbstractEvaluationGroup):
    """One force element, evaluated through its own hooks (``AbstractForceElement``)."""

    element: AbstractForceElement

    def per_element(self, stacked) -> dict[str, Array]:
        return {self.element.name: stacked}

    def initial_states(self, mechanism, q, qd):
        return {self.element.name: self.element.initial_state(mechanism.index, q, qd)}

    def force_and_cache(self, mechanism, t, q, qd, states, gamma_h=None):
        e, index = self.element, mechanism.index
        state, stage = states[e.name], None
        if gamma_h is not None:
            stage = clearance.solve_affine(
                lambda x: e.stiff_state_derivative(index, q, qd, t, x), state, gamma_h
            )
            state = stage[0]
        force, cache = e.force_and_cache(index, q, qd, t, state)
        return force, GroupCache(cache, stage)

    def state_rates(self, mechanism, cache, t, q, qd, qdd, states):
        e = self.element
        rate = e.state_derivative_cached(
            cache.shared, mechanism.index, q, qd, qdd, t, states[e.name]
        )
        return {e.name: rate}

    def stiff_rates(self, mechanism, t, q, qd, states):
        e = self.element
        return {e.name: e.stiff_state_derivative(mechanism.index, q, qd, t, states[e.name])}

    def contacts(self, cache):
        return {}


class _SingleJointGroup(AbstractEvaluationGroup):
    """One joint evaluated by the mechanism-level functions of a physics module (``physics``:
    ``initial_state``, ``force_and_cache``, ``state_derivative_cached``,
    ``stiff_state_derivative``), which the revolute and translational clearance joints share."""

    physics: ClassVar[Any]
    joint: eqx.AbstractVar[Any]

    def per_element(self, stacked) -> dict[str, Array]:
        return {self.joint.name: stacked}

    def initial_states(self, mechanism, q, qd):
        return {self.joint.name: self.physics.initial_state(self.joint, mechanism.index, q, qd)}

    def force_and_cache(self, mechanism, t, q, qd, states, gamma_h=None):
        c = self.joint
        force, cache, stage = self.physics.force_and_cache(
            c, mechanism.index, q, qd, states[c.name], gamma_h
        )
        return force, GroupCache(cache, stage)

    def state_rates(self, mechanism, cache, t, q, qd, qdd, states):
        c = self.joint
        rate = self.physics.state_derivative_cached(
            c, cache.shared, mechanism.index, q, qd, qdd, states[c.name]
        )
        return {c.name: rate}

    def stiff_rates(self, mechanism, t, q, qd, states):
        c = self.joint
        return {
            c.name: self.physics.stiff_state_derivative(c, mechanism.index, q, qd, states[c.name])
        }

    def contacts(self, cache):
        return {self.joint.name: cache.shared}


class ClearanceJointGroup(_SingleJointGroup):
    """One clearance joint, evaluated by the mechanism-level functions of ``dynamics._clearance``."""

    physics: ClassVar[Any] = clearance
    joint: ClearanceJoint


class BatchedClearanceJoints(AbstractEvaluationGroup):
    """Several clearance joints of the same kind, evaluated in one vmap (``dynamics._batched``)."""

    joints: tuple[ClearanceJoint, ...]

    def per_element(self, stacked) -> dict[str, Array]:
        return {c.name: stacked[i] for i, c in enumerate(self.joints)}

    def initial_states(self, mechanism, q, qd):
        return {c.name: clearance.initial_state(c, mechanism.index, q, qd) for c in self.joints}

    def force_and_cache(self, mechanism, t, q, qd, states, gamma_h=None):
        force, cache, stage = batched_force_and_cache(
            mechanism, self.joints, q, qd, t, states, gamma_h
        )
        return force, GroupCache(cache, stage)

    def state_rates(self, mechanism, cache, t, q, qd, qdd, states):
        return batched_state_rates(mechanism, self.joints, cache.shared, q, qd, qdd, t, states)

    def stiff_rates(self, mechanism, t, q, qd, states):
        return batched_stiff_rates(mechanism, self.joints, q, qd, t, states)

    def contacts(self, cache):
        return {
            c.name: jax.tree_util.tree_map(lambda x, i=i: x[i], cache.shared)
            for i, c in enumerate(self.joints)
        }


class TranslationalClearanceGroup(_SingleJointGroup):
    """One translational clearance joint, evaluated by ``dynamics._translational``.

    Its ``contacts`` entry holds per-corner arrays (4,): ``CornerKinematics.penetration`` and
    ``CornerForces.normal_force``.
    """

    physics: ClassVar[Any] = translational
    joint: TranslationalClearanceJoint


def evaluation_groups(mechanism) -> tuple[AbstractEvaluationGroup, ...]:
    """The groups of ``mechanism`` in evaluation order (static, computed while tracing): each force
    element, then the clearance joints grouped by kind (``dynamics._batched.groups``), then each
    translational clearance joint."""
    return (
        tuple(ForceElementGroup(e) for e in mechanism.forces)
        + tuple(
            ClearanceJointGroup(g[0]) if len(g) == 1 else BatchedClearanceJoints(g)
            for g in groups(mechanism)
        )
        + tuple(TranslationalClearanceGroup(j) for j in mechanism.translational_clearance_joints)
    )
