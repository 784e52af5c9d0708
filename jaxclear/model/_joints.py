"""Ideal joints and driving constraints as constraint functions Φ(q, t) (docs/model.md §1).

Each joint is an ``eqx.Module`` with static body names and array-valued geometry. The
mechanism resolves body names to coordinate indices; a joint's ``constraint`` returns its rows of
Φ. Jacobians and γ are never written here: they come from JAX derivatives of these functions
(``_constraints.py`` beside the equations of motion).
"""

import abc
from collections.abc import Callable
from typing import Any, ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_finite, check_shape
from .._core._geometry import body_coordinates, dot2, point_position


def _array(x):
    return jnp.asarray(x, dtype=float)


class AbstractJoint(eqx.Module):
    """Base of ideal joints: ``num_equations`` rows of Φ, labelled by ``name``."""

    name: eqx.AbstractVar[str]
    num_equations: ClassVar[int]

    @abc.abstractmethod
    def constraint(self, index: Callable[[str], int | None], q, t) -> Float[Array, " k"]:
        """Rows of Φ(q, t); ``index(name)`` maps a body name to its coordinate index."""

    @property
    @abc.abstractmethod
    def bodies(self) -> tuple[str, str]:
        """The two connected bodies (``"ground"`` for the fixed frame)."""


class RevoluteJoint(AbstractJoint):
    """Ideal revolute joint: point ``point_i`` on ``body_i`` coincides with ``point_j`` on ``body_j``.

    Φ = r_i^P − r_j^P (2 equations). Its multipliers λ are minus the force that body j exerts on
    body i at the joint (constraint force on q is −Φ_qᵀλ, docs/model.md §1, so body i receives −λ and
    body j receives +λ); ``Trajectory.joint_force`` returns −λ.

    Attributes:
        name: label used in outputs (static).
        body_i, body_j: body names (static); ``"ground"`` for the fixed frame.
        point_i, point_j: local vectors of the joint point in each body frame, m (global for ground).
    """

    name: str = eqx.field(static=True)
    body_i: str = eqx.field(static=True)
    point_i: Float[Array, "2"] = eqx.field(converter=_array)
    body_j: str = eqx.field(static=True)
    point_j: Float[Array, "2"] = eqx.field(converter=_array)
    num_equations: ClassVar[int] = 2

    def __check_init__(self):
        for attr in ("point_i", "point_j"):
            check_shape(f"RevoluteJoint {self.name!r}", attr, getattr(self, attr), (2,))
            check_finite(f"RevoluteJoint {self.name!r}", attr, getattr(self, attr))

    @property
    def bodies(self):
        return (self.body_i, self.body_j)

    def constraint(self, index, q, t):
        ri = point_position(q, index(self.body_i), self.point_i)
        rj = point_position(q, index(self.body_j), self.point_j)
        return ri - rj


class TranslationalJoint(AbstractJoint):
    """Ideal translational (prismatic) joint: body_i slides along an axis fixed in body_j.

    Φ = (φ_i − φ_j − angle, n_jᵀ(r_i^P − r_j^Q)) with n_j the axis normal (2 equations): the
    relative angle stays at ``angle`` and point P of body i stays on the line through Q of body j
    along ``axis`` (given in body j's frame).

    Attributes:
        name: label (static).
        body_i, body_j: slider and guide body names (static).
        point_i: P on body i, m. point_j: Q on body j (on the guide line), m.
        axis: guide direction in body j's frame (normalised internally).
        angle: relative angle φ_i − φ_j held by the joint, rad.
    """

    name: str = eqx.field(static=True)
    body_i: str = eqx.field(static=True)
    point_i: Float[Array, "2"] = eqx.field(converter=_array)
    body_j: str = eqx.field(static=True)
    point_j: Float[Array, "2"] = eqx.field(converter=_array)
    axis: Float[Array, "2"] = eqx.field(converter=_array, default=(1.0, 0.0))
    angle: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    num_equations: ClassVar[int] = 2

    def __check_init__(self):
        owner = f"TranslationalJoint {self.name!r}"
        for attr in ("point_i", "point_j", "axis"):
            check_shape(owner, attr, getattr(self, attr), (2,))
            check_finite(owner, attr, getattr(self, attr))

    @property
    def bodies(self):
        return (self.body_i, self.body_j)

    def constraint(self, index, q, t):
        ii, jj = index(self.body_i), index(self.body_j)
        _, phi_i = body_coordinates(q, ii)
        _, phi_j = body_coordinates(q, jj)
        ri = point_position(q, ii, self.point_i)
        rj = point_position(q, jj, self.point_j)
        axis = self.axis / jnp.linalg.norm(self.axis)
        normal_local = jnp.stack([-axis[1], axis[0]])
        c, s = jnp.cos(phi_j), jnp.sin(phi_j)
        normal = jnp.stack(
            [c * normal_local[0] - s * normal_local[1], s * normal_local[0] + c * normal_local[1]]
        )
        return jnp.stack([phi_i - phi_j - self.angle, dot2(normal, ri - rj)])


class AbstractDriver(eqx.Module):
    """Driving constraint Φ_d = φ_body − φ_reference − θ(t) (1 equation).

    Its multiplier gives the input torque the motor applies to ``body`` (see ``simulate``).
    ``relative_to`` is the reference body of a relative angle (``"ground"`` for absolute).
    """

    name: eqx.AbstractVar[str]
    body: eqx.AbstractVar[str]
    relative_to: eqx.AbstractVar[str]
    num_equations: ClassVar[int] = 1

    @abc.abstractmethod
    def angle(self, t) -> Float[Array, ""]:
        """Prescribed angle θ(t), rad."""

    @property
    def bodies(self):
        return (self.body, self.relative_to)

    @property
    @abc.abstractmethod
    def constant_speed(self) -> Float[Array, ""] | None:
        """Constant angular speed ω, rad/s, or ``None`` if the prescribed speed varies."""

    def constraint(self, index, q, t):
        _, phi = body_coordinates(q, index(self.body))
        _, phi_ref = body_coordinates(q, index(self.relative_to))
        return jnp.reshape(phi - phi_ref - self.angle(t), (1,))


class ConstantSpeedDriver(AbstractDriver):
    """θ(t) = initial_angle + speed · t.

    Attributes:
        body: driven body (static). relative_to: reference body, default ground (static).
        speed: ω, rad/s. initial_angle: θ(0), rad. name: label (static).
    """

    body: str = eqx.field(static=True)
    speed: Float[Array, ""] = eqx.field(converter=_array)
    initial_angle: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    relative_to: str = eqx.field(static=True, default="ground")
    name: str = eqx.field(static=True, default="driver")

    def __check_init__(self):
        check_finite(f"ConstantSpeedDriver {self.name!r}", "speed", self.speed)
        check_finite(f"ConstantSpeedDriver {self.name!r}", "initial_angle", self.initial_angle)

    def angle(self, t):
        return self.initial_angle + self.speed * t

    @property
    def constant_speed(self) -> Float[Array, ""]:
        return self.speed


class FunctionDriver(AbstractDriver):
    """θ(t) = function(t, parameters) for any smooth JAX function of time.

    Attributes:
        body: driven body (static). function: ``f(t, parameters) -> angle`` (static; a new function
            recompiles). parameters: pytree of arrays passed to ``function`` (differentiable).
        relative_to: reference body (static). name: label (static).
    """

    body: str = eqx.field(static=True)
    function: Callable[[Any, Any], Any] = eqx.field(static=True)
    parameters: Any = None
    relative_to: str = eqx.field(static=True, default="ground")
    name: str = eqx.field(static=True, default="driver")

    def angle(self, t):
        return jnp.asarray(self.function(t, self.parameters), dtype=float)

    @property
    def constant_speed(self) -> None:
        """``None``: the prescribed speed of a function of time is not known to be constant."""
        return None
