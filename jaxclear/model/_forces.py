"""Force elements: applied forces and torques, linear spring–dampers (docs/model.md §1, Q).

A force element contributes a generalised force vector Q (size of q). Elements with internal
states declare ``num_states`` and give their time derivatives; those states live in the
integrator's state vector. Everything the equations of motion call on a force element is declared
on ``AbstractForceElement`` with a default, so a new element (the user's extension point) overrides
only what it uses. Force elements and clearance joints share the base ``AbstractStateElement``
(name, bodies, number of internal states); a clearance joint is data (``ClearanceJoint``) whose
contact physics is computed with the equations of motion (``_clearance.py`` of the next stage).
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_finite, check_nonnegative, check_shape
from .._core._geometry import dot2, point_force_to_generalized, point_position, point_velocity
from ._element import AbstractStateElement


def _array(x):
    return jnp.asarray(x, dtype=float)


Index = Callable[[str], "int | None"]


class AbstractForceElement(AbstractStateElement):
    """Base of force elements. Subclass and implement ``bodies`` and ``generalized_force``.

    The other hooks have defaults: no internal states, no potential energy, no work shared
    between the force and the state rates.
    """

    @property
    def num_states(self) -> int:
        """Number of internal states this element adds to the integrator state (static; default 0)."""
        return 0

    def initial_state(self, index: Index, q, qd) -> Float[Array, " s"]:
        """Internal state at the start, given assembled q, q̇."""
        return jnp.zeros((self.num_states,))

    @abc.abstractmethod
    def generalized_force(self, index: Index, q, qd, t, state) -> Float[Array, " n"]:
        """Q contribution, same size as q (N, N, N m per body)."""

    def state_derivative(self, index: Index, q, qd, qdd, t, state) -> Float[Array, " s"]:
        """Time derivative of the internal state; ``qdd`` is this evaluation's acceleration."""
        return jnp.zeros((self.num_states,))

    def force_and_cache(self, index: Index, q, qd, t, state):
        """(Q contribution, cache) in one pass; the cache goes to ``state_derivative_cached``.

        Override both to share work between forces and state rates (default: no sharing).
        """
        return self.generalized_force(index, q, qd, t, state), None

    def state_derivative_cached(
        self, cache, index: Index, q, qd, qdd, t, state
    ) -> Float[Array, " s"]:
        """``state_derivative`` reusing the cache of ``force_and_cache``."""
        return self.state_derivative(index, q, qd, qdd, t, state)

    def stiff_state_derivative(self, index: Index, q, qd, t, state) -> Float[Array, " s"]:
        """The stiff part of ``state_derivative``, integrated implicitly by IMEX solvers (KenCarp).

        Must not depend on accelerations. Default: nothing is stiff.
        """
        return jnp.zeros((self.num_states,))

    def potential_energy(self, index: Index, q) -> Float[Array, ""]:
        """Energy stored in the element at coordinates q, J (default: none; conservative elements
        override it for ``jaxclear.analysis.potential_energy``)."""
        return jnp.zeros((), dtype=q.dtype)


class AppliedForce(AbstractForceElement):
    """Constant force (global components, N) applied at a body-fixed point (local vector, m)."""

    name: str = eqx.field(static=True)
    body: str = eqx.field(static=True)
    point: Float[Array, "2"] = eqx.field(converter=_array)
    force: Float[Array, "2"] = eqx.field(converter=_array)

    def __check_init__(self):
        for attr in ("point", "force"):
            check_shape(f"AppliedForce {self.name!r}", attr, getattr(self, attr), (2,))
            check_finite(f"AppliedForce {self.name!r}", attr, getattr(self, attr))

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body,)

    def generalized_force(self, index, q, qd, t, state):
        i = index(self.body)
        return point_force_to_generalized(q, i, point_position(q, i, self.point), self.force)


class AppliedTorque(AbstractForceElement):
    """Constant torque on a body, N m (counter-clockwise positive)."""

    name: str = eqx.field(static=True)
    body: str = eqx.field(static=True)
    torque: Float[Array, ""] = eqx.field(converter=_array)

    def __check_init__(self):
        check_finite(f"AppliedTorque {self.name!r}", "torque", self.torque)

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body,)

    def generalized_force(self, index, q, qd, t, state):
        i = index(self.body)
        out = jnp.zeros_like(q)
        if i is None:
            return out
        return out.at[3 * i + 2].add(self.torque)


class SpringDamper(AbstractForceElement):
    """Linear translational spring–damper between two points.

    Force magnitude (tension positive) f = k (ℓ − ℓ0) + c ℓ̇, acting along the line of the points.

    Attributes:
        stiffness: k, N/m (>= 0). damping: c, N s/m (>= 0). free_length: ℓ0, m (>= 0).
    """

    name: str = eqx.field(static=True)
    body_i: str = eqx.field(static=True)
    point_i: Float[Array, "2"] = eqx.field(converter=_array)
    body_j: str = eqx.field(static=True)
    point_j: Float[Array, "2"] = eqx.field(converter=_array)
    stiffness: Float[Array, ""] = eqx.field(converter=_array)
    damping: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    free_length: Float[Array, ""] = eqx.field(converter=_array, default=0.0)

    def __check_init__(self):
        owner = f"SpringDamper {self.name!r}"
        for attr in ("point_i", "point_j"):
            check_shape(owner, attr, getattr(self, attr), (2,))
            check_finite(owner, attr, getattr(self, attr))
        for attr in ("stiffness", "damping", "free_length"):
            check_nonnegative(owner, attr, getattr(self, attr))

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body_i, self.body_j)

    def generalized_force(self, index, q, qd, t, state):
        i, j = index(self.body_i), index(self.body_j)
        pi, pj = point_position(q, i, self.point_i), point_position(q, j, self.point_j)
        vi, vj = point_velocity(q, qd, i, self.point_i), point_velocity(q, qd, j, self.point_j)
        d = pj - pi
        length_sq = dot2(d, d)
        safe = length_sq > 0
        length = jnp.where(safe, jnp.sqrt(jnp.where(safe, length_sq, 1.0)), 0.0)
        u = jnp.where(safe, d / jnp.where(safe, length, 1.0), 0.0)
        rate = dot2(u, vj - vi)
        tension = self.stiffness * (length - self.free_length) + self.damping * rate
        f_on_i = tension * u
        return point_force_to_generalized(q, i, pi, f_on_i) + point_force_to_generalized(
            q, j, pj, -f_on_i
        )

    def potential_energy(self, index, q):
        """Elastic energy ½ k (ℓ − ℓ0)², J."""
        i, j = index(self.body_i), index(self.body_j)
        d = point_position(q, j, self.point_j) - point_position(q, i, self.point_i)
        return 0.5 * self.stiffness * (jnp.sqrt(dot2(d, d)) - self.free_length) ** 2
