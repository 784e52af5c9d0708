"""Shared contract of the friction laws (docs/model.md §4).

A friction law maps the slip velocity v_T of the journal's contact point relative to the bearing's
(along t), the normal force F_N >= 0 and its own internal state (LuGre's bristle deflection z; none
for Coulomb-type laws) to the friction force on the journal along t, which opposes v_T. Its
internal state evolves by ``state_derivative`` and lives in the integrator's state vector.
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..contact._base import Smoothing


class AbstractFrictionLaw(eqx.Module):
    """Base of all friction laws."""

    num_states: ClassVar[int] = 0

    def initial_state(self) -> Float[Array, " num_states"]:
        """Internal state at the start of a simulation (zeros)."""
        return jnp.zeros((self.num_states,))

    @abc.abstractmethod
    def force(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " num_states"],
        smoothing: Smoothing,
    ) -> Float[Array, ""]:
        """Friction force on the journal along t, N (sign opposite to ``slip_velocity``)."""

    def state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " num_states"],
        smoothing: Smoothing,
    ) -> Float[Array, " num_states"]:
        """Time derivative of the internal state (empty for stateless laws)."""
        return jnp.zeros((self.num_states,))

    def stiff_state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        state: Float[Array, " num_states"],
        smoothing: Smoothing,
    ) -> Float[Array, " num_states"]:
        """The stiff part of ``state_derivative`` (for IMEX solvers: treated implicitly).

        Must be a part of ``state_derivative`` and must not depend on the normal force (the
        implicit solve differentiates it and skips the contact law); the rest is integrated
        explicitly. Default: none.
        """
        return jnp.zeros((self.num_states,))
