"""Rigid planar bodies (docs/model.md §1)."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_finite, check_positive, check_shape

GROUND = "ground"
"""Reserved body name for the fixed frame. Points on ground are given in global coordinates."""


def _array(x):
    return jnp.asarray(x, dtype=float)


class Body(eqx.Module):
    """A rigid planar body with coordinates q = (x, y, φ) of its centre of mass and frame angle.

    Attributes:
        name: unique name used by joints and outputs (static; not ``"ground"``).
        mass: m, kg (> 0).
        inertia: J about the centre of mass, kg m² (> 0).
        position: initial guess (x, y, φ) in m, m, rad; refined by assembly.
        velocity: initial guess (ẋ, ẏ, φ̇) in m/s, m/s, rad/s; refined by assembly.
    """

    name: str = eqx.field(static=True)
    mass: Float[Array, ""] = eqx.field(converter=_array)
    inertia: Float[Array, ""] = eqx.field(converter=_array)
    position: Float[Array, "3"] = eqx.field(converter=_array, default=(0.0, 0.0, 0.0))
    velocity: Float[Array, "3"] = eqx.field(converter=_array, default=(0.0, 0.0, 0.0))

    def __check_init__(self):
        owner = f"Body {self.name!r}"
        if not isinstance(self.name, str) or not self.name or self.name == GROUND:
            raise ValueError(
                f"Body name must be a non-empty string other than {GROUND!r}, got {self.name!r}."
            )
        check_positive(owner, "mass", self.mass, "kg")
        check_positive(owner, "inertia", self.inertia, "kg m^2")
        check_shape(owner, "position", self.position, (3,))
        check_shape(owner, "velocity", self.velocity, (3,))
        check_finite(owner, "position", self.position)
        check_finite(owner, "velocity", self.velocity)
