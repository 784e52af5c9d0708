"""Coulomb-type friction laws without internal state (docs/model.md §4) [lit]."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_nonnegative, check_positive
from .._core._smooth import smooth_ramp
from ..contact._base import Smoothing, _array
from ..contact._hertz import _optional_array
from ._base import AbstractStatelessFrictionLaw


class Coulomb(AbstractStatelessFrictionLaw):
    """Regularised Coulomb friction ``F_T = −μ F_N tanh(v_T/v_ε)`` [lit].

    Attributes:
        friction_coefficient: μ >= 0, dimensionless (default 0.1) [ours].
        velocity_tolerance: v_ε > 0, m/s; ``None`` (default) uses ``Smoothing.velocity_width``.
    """

    friction_coefficient: Float[Array, ""] = eqx.field(converter=_array, default=0.1)
    velocity_tolerance: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)

    def __check_init__(self):
        check_nonnegative(
            type(self).__name__,
            "friction_coefficient",
            self.friction_coefficient,
            fix="pass μ >= 0",
        )
        if self.velocity_tolerance is not None:
            check_positive(
                type(self).__name__,
                "velocity_tolerance",
                self.velocity_tolerance,
                fix="pass v_ε > 0 in m/s, or None for Smoothing.velocity_width",
            )

    def slip_transition(self, smoothing: Smoothing) -> tuple[Array, Array]:
        """(3 v_ε, v_ε): tanh(v/v_ε) turns over within |v| <= 3 v_ε (tanh 3 = 0.995), over a width
        v_ε (``AbstractFrictionLaw.slip_transition``)."""
        tolerance = (
            smoothing.velocity_width if self.velocity_tolerance is None else self.velocity_tolerance
        )
        width = jnp.asarray(tolerance, dtype=float)
        return 3.0 * width, width

    def force(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " 0"],
        smoothing: Smoothing,
    ) -> Float[Array, ""]:
        """Friction force on the journal along t, N.

        Args:
            slip_velocity: v_T, m/s.
            normal_force: F_N >= 0, N.
            state: empty.
            smoothing: regularisation widths (``velocity_width`` is the default v_ε).

        Returns:
            ``−μ F_N tanh(v_T/v_ε)``, N.
        """
        tolerance = (
            smoothing.velocity_width if self.velocity_tolerance is None else self.velocity_tolerance
        )
        return -self.friction_coefficient * normal_force * jnp.tanh(slip_velocity / tolerance)


class ModifiedCoulomb(AbstractStatelessFrictionLaw):
    """Ambrósio's modified Coulomb friction ``F_T = −μ c_d(|v_T|) F_N sgn(v_T)`` [lit].

    The dynamic correction c_d rises linearly from 0 at ``|v_T| = v0`` to 1 at ``|v_T| = v1``.
    Its two corners are rounded with ``smooth_ramp`` of width ``Smoothing.velocity_width`` w [ours]:

        c_d = [ramp(|v| − v0) − ramp(|v| − v1)] / (v1 − v0),

    which is exactly 0 for ``|v| <= v0`` (so ``c_d sgn(v)`` is C¹ through v = 0), exactly 1 for
    ``|v| >= v1 + w``, and linear with the published slope in between (lagging by w/2).

    Attributes:
        friction_coefficient: μ >= 0, dimensionless (default 0.1) [ours].
        lower_velocity: v0 >= 0, m/s (default 1e-4).
        upper_velocity: v1 > v0, m/s (default 1e-3).
    """

    friction_coefficient: Float[Array, ""] = eqx.field(converter=_array, default=0.1)
    lower_velocity: Float[Array, ""] = eqx.field(converter=_array, default=1e-4)
    upper_velocity: Float[Array, ""] = eqx.field(converter=_array, default=1e-3)

    def __check_init__(self):
        check_nonnegative(
            type(self).__name__,
            "friction_coefficient",
            self.friction_coefficient,
            fix="pass μ >= 0",
        )
        check_nonnegative(
            type(self).__name__, "lower_velocity", self.lower_velocity, fix="pass v0 >= 0 in m/s"
        )
        check_positive(
            type(self).__name__,
            "upper_velocity - lower_velocity",
            self.upper_velocity - self.lower_velocity,
            fix="pass upper_velocity (v1) > lower_velocity (v0)",
        )

    def slip_transition(self, smoothing: Smoothing) -> tuple[Array, Array]:
        """(v1 + w, v1 − v0): the force turns over within |v| <= v1 + w, over the ramp's width
        v1 − v0 (``AbstractFrictionLaw.slip_transition``)."""
        upper = jnp.asarray(self.upper_velocity, dtype=float)
        return upper + smoothing.velocity_width, upper - self.lower_velocity

    def dynamic_correction(
        self, speed: Float[Array, "..."], smoothing: Smoothing
    ) -> Float[Array, "..."]:
        """c_d(|v|) in [0, 1], dimensionless.

        Args:
            speed: slip speed |v_T| >= 0, m/s.
            smoothing: regularisation widths (``velocity_width`` rounds the corners).
        """
        w = smoothing.velocity_width
        v0, v1 = self.lower_velocity, self.upper_velocity
        return (smooth_ramp(speed - v0, w) - smooth_ramp(speed - v1, w)) / (v1 - v0)

    def force(
        self,
        slip_velocity: Float[Array, ""],
        normal_force: Float[Array, ""],
        state: Float[Array, " 0"],
        smoothing: Smoothing,
    ) -> Float[Array, ""]:
        """Friction force on the journal along t, N.

        Args:
            slip_velocity: v_T, m/s.
            normal_force: F_N >= 0, N.
            state: empty.
            smoothing: regularisation widths.

        Returns:
            ``−μ c_d(|v_T|) F_N sgn(v_T)``, N.
        """
        v = jnp.asarray(slip_velocity)
        c_d = self.dynamic_correction(jnp.abs(v), smoothing)
        return -self.friction_coefficient * c_d * normal_force * jnp.sign(v)
