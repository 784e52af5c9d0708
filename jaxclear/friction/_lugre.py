"""LuGre friction normalised by the normal force (docs/model.md §4) [paper; defaults ours].

    ż = v − σ0 |v| z / g(v),           g(v) = μ_k + (μ_s − μ_k) exp(−(v/v_s)²),
    F_T = −(σ0 z + σ1(v) ż + σ2 v) F_N,  σ1(v) = σ1 exp(−(v/v_s)²),

with z the mean bristle deflection (m) and |v| the smooth ``sqrt(v² + w²)`` of width
``Smoothing.velocity_width``. At constant v, z relaxes to ``z_ss = g(v) v/(σ0 |v|)`` and the force
to the Stribeck curve ``−g(v) F_N sgn(v) − σ2 v F_N``. The z equation is stiff (rate
``σ0 |v|/g ≈ 1e7 1/s`` at 1 m/s with the defaults).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_nonnegative, check_positive
from .._core._smooth import smooth_abs
from ..contact._base import Smoothing, _array
from ._base import AbstractFrictionLaw


class LuGre(AbstractFrictionLaw):
    """LuGre friction with one internal state z per clearance joint.

    Attributes:
        bristle_stiffness: σ0 > 0, 1/m (default 1e5) [ours].
        bristle_damping: σ1 >= 0, s/m (default 316), faded out while sliding as
            ``σ1 exp(−(v/v_s)²)`` [ours].
        viscous_friction: σ2 >= 0, s/m (default 0) [ours].
        static_friction: μ_s > 0 (default 0.15) [ours].
        kinetic_friction: μ_k > 0 (default 0.1) [ours].
        stribeck_velocity: v_s > 0, m/s (default 1e-3) [ours].
    """

    num_states: ClassVar[int] = 1

    bristle_stiffness: Float[Array, ""] = eqx.field(converter=_array, default=1e5)
    bristle_damping: Float[Array, ""] = eqx.field(converter=_array, default=316.0)
    viscous_friction: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    static_friction: Float[Array, ""] = eqx.field(converter=_array, default=0.15)
    kinetic_friction: Float[Array, ""] = eqx.field(converter=_array, default=0.1)
    stribeck_velocity: Float[Array, ""] = eqx.field(converter=_array, default=1e-3)

    def __check_init__(self):
        check_positive(
            type(self).__name__,
            "bristle_stiffness",
            self.bristle_stiffness,
            fix="pass σ0 > 0 in 1/m",
        )
        check_nonnegative(
            type(self).__name__, "bristle_damping", self.bristle_damping, fix="pass σ1 >= 0 in s/m"
        )
        check_nonnegative(
            type(self).__name__,
            "viscous_friction",
            self.viscous_friction,
            fix="pass σ2 >= 0 in s/m",
        )
        check_positive(
            type(self).__name__, "static_friction", self.static_friction, fix="pass μ_s > 0"
        )
        check_positive(
            type(self).__name__, "kinetic_friction", self.kinetic_friction, fix="pass μ_k > 0"
        )
        check_positive(
            type(self).__name__,
            "stribeck_velocity",
            self.stribeck_velocity,
            fix="pass v_s > 0 in m/s",
        )

    def stribeck(self, slip_velocity: Float[Array, "..."]) -> Float[Array, "..."]:
        """g(v) = μ_k + (μ_s − μ_k) exp(−(v/v_s)²), dimensionless."""
        fade = jnp.exp(-((slip_velocity / self.stribeck_velocity) ** 2))
        return self.kinetic_friction + (self.static_friction - self.kinetic_friction) * fade

    def steady_state(
        self, slip_velocity: Float[Array, ""], smoothing: Smoothing
    ) -> Float[Array, " 1"]:
        """``z_ss = g(v) v / (σ0 |v|)`` (m) at which ż = 0 for constant v, shape ``(1,)``."""
        speed = smooth_abs(slip_velocity, smoothing.velocity_width)
        z = self.stribeck(slip_velocity) * slip_velocity / (self.bristle_stiffness * speed)
        return jnp.reshape(z, (1,))

    def state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " 1"],
        smoothing: Smoothing,
    ) -> Float[Array, " 1"]:
        """ż = v − σ0 |v| z / g(v), m/s, shape ``(1,)``.

        Args:
            slip_velocity: v_T, m/s.
            normal_force: F_N, N (unused: the law is normalised by F_N).
            state: ``(z,)``, m.
            smoothing: regularisation widths (``velocity_width`` for |v|).
        """
        speed = smooth_abs(slip_velocity, smoothing.velocity_width)
        g = self.stribeck(slip_velocity)
        return slip_velocity - self.bristle_stiffness * speed * state / g

    def stiff_state_derivative(
        self,
        slip_velocity: Float[Array, ""],
        state: Float[Array, " 1"],
        smoothing: Smoothing,
    ) -> Float[Array, " 1"]:
        """The part of ż that IMEX solvers take implicitly: all of it, v − σ0 |v| z / g(v).

        Affine in z with rate σ0|v|/g (≈ 1e7 1/s sliding at 1 m/s). The forcing v goes with the
        relaxation: with only −σ0|v|z/g implicit and v explicit, the two terms that balance at
        z_ss were taken at different instants of a step, z then lagged z_ss by the step's
        change of v, and z's error estimate, not the motion's, set the step size in sliding
        contact. Moving v to the implicit side took the three-joint LuGre benchmark (case c of
        benchmarks/bench_clearance.py, KenCarp5) from 10 600–11 800 to 7 700 steps.
        """
        speed = smooth_abs(slip_velocity, smoothing.velocity_width)
        return slip_velocity - self.bristle_stiffness * speed * state / self.stribeck(slip_velocity)

    def force(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " 1"],
        smoothing: Smoothing,
    ) -> Float[Array, ""]:
        """Friction force on the journal along t, N.

        Args:
            slip_velocity: v_T, m/s.
            normal_force: F_N >= 0, N.
            state: ``(z,)``, m.
            smoothing: regularisation widths.

        Returns:
            ``−(σ0 z + σ1(v) ż + σ2 v) F_N``, N.
        """
        z_dot = self.state_derivative(slip_velocity, normal_force, state, smoothing)[0]
        fade = jnp.exp(-((slip_velocity / self.stribeck_velocity) ** 2))
        damping = self.bristle_damping * fade
        stress = self.bristle_stiffness * state[0] + damping * z_dot
        stress = stress + self.viscous_friction * slip_velocity
        return -stress * normal_force
