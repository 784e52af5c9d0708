"""Hertz point contact law (docs/model.md §3) and the stiffness helpers shared by the contact laws.

Parameter checks come from ``jaxclear._core._checks`` (skipped for traced values inside ``jit``/``vmap``).
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_positive
from .._core._smooth import safe_pow, smooth_ramp
from ._base import (
    AbstractContactLaw,
    ContactGeometry,
    ContactKinematics,
    Smoothing,
    _array,
)


def _optional_array(x):
    """Converter for parameters where ``None`` means "derive from the geometry"."""
    return None if x is None else _array(x)


def check_stiffness_and_exponent(owner: str, stiffness, exponent) -> None:
    """Checks of a power law K δ^n: K > 0 if given (``None`` means the Hertz K), n > 0."""
    if stiffness is not None:
        check_positive(owner, "stiffness", stiffness, fix="pass K in N/m^n, or None for Hertz K")
    check_positive(owner, "exponent", exponent, fix="pass n > 0 (1.5 for Hertz)")


def resolve_stiffness(
    stiffness: Float[Array, ""] | None, geometry: ContactGeometry
) -> Float[Array, ""]:
    """The law's stiffness, or the joint's Hertz stiffness when it is ``None``, N/m^n."""
    return geometry.hertz_stiffness if stiffness is None else stiffness


class Hertz(AbstractContactLaw):
    """Undamped Hertz contact: ``F_N = K δ^n`` (docs/model.md §3) [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` (default) uses ``geometry.hertz_stiffness``
            (``4/(3(σ_B + σ_J)) √R*``).
        exponent: n, dimensionless (1.5 for Hertz point contact).
    """

    stiffness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    exponent: Float[Array, ""] = eqx.field(converter=_array, default=1.5)

    def __check_init__(self):
        check_stiffness_and_exponent(type(self).__name__, self.stiffness, self.exponent)

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N.

        Args:
            kin: contact kinematics; only the penetration is used.
            geometry: joint geometry (source of the default stiffness).
            smoothing: regularisation widths (``penetration_width``).

        Returns:
            ``(normal, tangential)``: ``K δ_s^n >= 0`` with δ_s the smooth positive part of the
            penetration, and 0.
        """
        delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
        stiffness = resolve_stiffness(self.stiffness, geometry)
        normal = stiffness * safe_pow(delta, self.exponent)
        return normal, jnp.zeros_like(normal)
