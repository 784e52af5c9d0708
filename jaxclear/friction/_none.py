"""Frictionless contact."""

import jax.numpy as jnp
from jaxtyping import Array, Float

from ..contact._base import Smoothing
from ._base import AbstractStatelessFrictionLaw


class NoFriction(AbstractStatelessFrictionLaw):
    """No tangential force: ``F_T = 0``."""

    def force(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " 0"],
        smoothing: Smoothing,
    ) -> Float[Array, ""]:
        """Friction force on the journal along t: always 0 N."""
        return jnp.zeros_like(jnp.asarray(normal_force, dtype=float))
