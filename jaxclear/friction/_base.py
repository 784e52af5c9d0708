"""Shared contract of the friction laws (docs/model.md §4).

A friction law maps the slip velocity v_T of the journal's contact point relative to the bearing's
(along t), the normal force F_N >= 0 and its own internal state (LuGre's bristle deflection z; none
for Coulomb-type laws) to the friction force on the journal along t, which opposes v_T. Its
internal state evolves by ``state_derivative`` and lives in the integrator's state vector.

Laws with internal states subclass ``AbstractFrictionLaw`` (see ``LuGre``); laws without subclass
``AbstractStatelessFrictionLaw`` and implement ``force`` only.
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..contact._base import Smoothing


class AbstractFrictionLaw(eqx.Module):
    """Base of all friction laws.

    Attributes:
        num_states: number of internal states per clearance joint (class constant).
    """

    num_states: ClassVar[int]

    def initial_state(self) -> Float[Array, " num_states"]:
        """Internal state at the start of a simulation (zeros)."""
        return jnp.zeros((self.num_states,))

    def slip_transition(self, smoothing: Smoothing) -> tuple[Array, Array] | None:
        """Where the force turns over with the slip velocity, for the sensitivity solve's steps.

        A Coulomb-type law reverses the friction force, ±μ F_N, across a narrow band of slip
        velocities; in contact the slip velocity can cross it in tens of nanoseconds. A step that
        jumps the band without a stage inside integrates the state well enough (the force on
        either side is right) but drops the tangents' kick, the force's jump times the crossing
        instant's derivative (docs/differentiation.md, "Slip reversals in contact"). The
        error-controlled sensitivity solve therefore rejects such steps
        (``dynamics._equations.slip_step_fraction``).

        Returns:
            ``None`` where the force has no such band (no friction; LuGre, whose reversal goes
            through its integrated bristle state), else (V, u), m/s: the band is |v_T| <= V and u
            the width over which the force turns (a step inside the band may change v_T by at
            most ``dynamics._equations.SLIP_RESOLUTION`` u).
        """
        return None

    @abc.abstractmethod
    def force(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " num_states"],
        smoothing: Smoothing,
    ) -> Float[Array, ""]:
        """Friction force on the journal along t, N (sign opposite to ``slip_velocity``)."""

    @abc.abstractmethod
    def state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " num_states"],
        smoothing: Smoothing,
    ) -> Float[Array, " num_states"]:
        """Time derivative of the internal state."""

    @abc.abstractmethod
    def stiff_state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        state: Float[Array, " num_states"],
        smoothing: Smoothing,
    ) -> Float[Array, " num_states"]:
        """The stiff part of ``state_derivative`` (for IMEX solvers: treated implicitly).

        Must be a part of ``state_derivative`` and must not depend on the normal force (the
        implicit solve differentiates it and skips the contact law); the rest is integrated
        explicitly.
        """


class AbstractStatelessFrictionLaw(AbstractFrictionLaw):
    """Base of friction laws without internal state (Coulomb-type): subclasses implement ``force``."""

    num_states: ClassVar[int] = 0

    def state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " 0"],
        smoothing: Smoothing,
    ) -> Float[Array, " 0"]:
        """Time derivative of the internal state: empty."""
        return jnp.zeros((self.num_states,))

    def stiff_state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        state: Float[Array, " 0"],
        smoothing: Smoothing,
    ) -> Float[Array, " 0"]:
        """The stiff part of ``state_derivative``: empty."""
        return jnp.zeros((self.num_states,))
