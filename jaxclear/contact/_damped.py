"""Damped point contact laws ``F_N = K δ^n (1 + χ̂ δ̇/δ̇⁻)`` (docs/model.md §3) [lit].

All five laws share one force helper and differ only in the hysteresis factor χ̂(c_e), a
function of the coefficient of restitution c_e:

- Lankarani–Nikravesh: ``χ̂ = 3(1 − c_e²)/4``;
- Hunt–Crossley: ``χ̂ = 3(1 − c_e)/2``;
- Flores et al. 2011: ``χ̂ = 8(1 − c_e)/(5 c_e)``;
- Gonthier et al.: ``χ̂ = (1 − c_e²)/c_e``;
- Zhiying–Qishao: ``χ̂ = 3(1 − c_e²) e^{2(1 − c_e)}/4``.

The factor ``1 + χ̂ δ̇/δ̇⁻`` is negative late in the restitution phase of strongly damped
contacts (the "sticky" tail of these laws); it is clamped at zero with the C¹ clamp
:func:`clamp_nonnegative` so that ``F_N >= 0`` (docs/model.md §3: force clamped >= 0).
"""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._core._checks import check_restitution
from .._core._smooth import safe_pow, smooth_ramp, smooth_step
from ._base import (
    AbstractContactLaw,
    ContactGeometry,
    ContactKinematics,
    Smoothing,
    _array,
)
from ._hertz import _optional_array, check_stiffness_and_exponent, resolve_stiffness


def clamp_nonnegative(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """C¹, monotone ``max(x, 0)`` that is exact outside ``(0, width)`` [ours].

    ``x · smooth_step(x, width)``: exactly 0 for ``x <= 0``, exactly ``x`` for ``x >= width``,
    between 0 and ``x`` in the transition. Unlike ``smooth_ramp`` it does not shift the value by
    ``width/2`` where the clamp is inactive, so an undamped or compressing contact is not biased.

    Args:
        x: the quantity to clamp (a dimensionless damping factor or a force in N).
        width: transition width ``> 0``, same units as ``x``.

    Returns:
        The clamped value, same shape as ``x``.
    """
    x = jnp.asarray(x)
    return x * smooth_step(x, width)


def lankarani_nikravesh_hysteresis(restitution: ArrayLike) -> Float[Array, "..."]:
    """Lankarani–Nikravesh hysteresis factor ``χ̂ = 3(1 − c_e²)/4``, dimensionless."""
    return 0.75 * (1.0 - jnp.asarray(restitution) ** 2)


def damping_factor(
    hysteresis: ArrayLike,
    rate: ArrayLike,
    impact_velocity: ArrayLike,
    force_width: ArrayLike,
) -> Float[Array, "..."]:
    """Clamped hysteresis-damping factor ``max(0, 1 + χ̂ δ̇/δ̇⁻)`` (smooth, see module doc).

    Args:
        hysteresis: χ̂, dimensionless.
        rate: penetration rate δ̇, m/s.
        impact_velocity: δ̇⁻ > 0, m/s.
        force_width: width of the clamp at zero, dimensionless (``Smoothing.force_width``).

    Returns:
        The factor, ``>= 0``.
    """
    factor = 1.0 + hysteresis * jnp.asarray(rate) / impact_velocity
    return clamp_nonnegative(factor, force_width)


def damped_point_force(
    stiffness: ArrayLike,
    exponent: ArrayLike,
    hysteresis: ArrayLike,
    kin: ContactKinematics,
    smoothing: Smoothing,
) -> Float[Array, ""]:
    """``F_N = K δ_s^n max(0, 1 + χ̂ δ̇/δ̇⁻)``, N, with δ_s the smooth positive penetration.

    Args:
        stiffness: K, N/m^n.
        exponent: n.
        hysteresis: χ̂, dimensionless.
        kin: contact kinematics (penetration, its rate and the impact velocity).
        smoothing: regularisation widths.

    Returns:
        The normal force, ``>= 0`` and exactly 0 for ``δ <= 0``.
    """
    delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
    elastic = jnp.asarray(stiffness) * safe_pow(delta, exponent)
    factor = damping_factor(
        hysteresis, kin.penetration_rate, kin.impact_velocity, smoothing.force_width
    )
    return elastic * factor


class AbstractLNDampedElasticLaw(AbstractContactLaw):
    """Base of laws ``F_N = F_elastic(δ_s) · max(0, 1 + 3(1 − c_e²)/4 · δ̇/δ̇⁻)``.

    Subclasses give the elastic part ``elastic_force(δ_s, geometry)`` and a ``restitution`` field;
    the Lankarani–Nikravesh factor, the smooth positive penetration δ_s and the clamp are shared.
    Used by the cylindrical and elastic-foundation laws (their damping is [ours] where the literature gives
    the law without it, docs/model.md §3; ``restitution=1`` recovers the elastic law).
    """

    restitution: eqx.AbstractVar[Float[Array, ""]]

    @abc.abstractmethod
    def elastic_force(self, delta: Float[Array, ""], geometry: ContactGeometry) -> Float[Array, ""]:
        """Elastic normal force at smooth penetration ``delta`` (m), N."""

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N: ``(normal >= 0, 0)``."""
        delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
        factor = damping_factor(
            lankarani_nikravesh_hysteresis(self.restitution),
            kin.penetration_rate,
            kin.impact_velocity,
            smoothing.force_width,
        )
        normal = self.elastic_force(delta, geometry) * factor
        return normal, jnp.zeros_like(normal)


class AbstractDampedContactLaw(AbstractContactLaw):
    """Base of the point laws ``F_N = K δ^n (1 + χ̂(c_e) δ̇/δ̇⁻)``.

    Subclasses only define :meth:`hysteresis_factor`.

    Attributes:
        stiffness: K, N/m^n; ``None`` (default) uses ``geometry.hertz_stiffness``.
        exponent: n, dimensionless (default 1.5, Hertz).
        restitution: coefficient of restitution c_e in (0, 1] (default 0.9).
    """

    stiffness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    exponent: Float[Array, ""] = eqx.field(converter=_array, default=1.5)
    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)

    def __check_init__(self):
        check_stiffness_and_exponent(type(self).__name__, self.stiffness, self.exponent)
        check_restitution(type(self).__name__, self.restitution)

    @abc.abstractmethod
    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂(c_e), dimensionless."""

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N.

        Args:
            kin: contact kinematics (penetration, penetration rate, impact velocity).
            geometry: joint geometry (source of the default stiffness).
            smoothing: regularisation widths.

        Returns:
            ``(normal, tangential)`` with ``normal = K δ^n max(0, 1 + χ̂ δ̇/δ̇⁻) >= 0`` and
            ``tangential = 0``.
        """
        stiffness = resolve_stiffness(self.stiffness, geometry)
        normal = damped_point_force(
            stiffness, self.exponent, self.hysteresis_factor(), kin, smoothing
        )
        return normal, jnp.zeros_like(normal)


class LankaraniNikravesh(AbstractDampedContactLaw):
    """Lankarani–Nikravesh (1990): ``χ̂ = 3(1 − c_e²)/4``; meant for c_e near 1 [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` uses the Hertz K of the joint.
        exponent: n (default 1.5).
        restitution: c_e in (0, 1] (default 0.9).
    """

    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂ = 3(1 − c_e²)/4."""
        return lankarani_nikravesh_hysteresis(self.restitution)


class HuntCrossley(AbstractDampedContactLaw):
    """Hunt–Crossley (1975): ``χ̂ = 3(1 − c_e)/2`` [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` uses the Hertz K of the joint.
        exponent: n (default 1.5).
        restitution: c_e in (0, 1] (default 0.9).
    """

    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂ = 3(1 − c_e)/2."""
        return 1.5 * (1.0 - self.restitution)


class Flores(AbstractDampedContactLaw):
    """Flores, Machado, Silva & Martins (2011): ``χ̂ = 8(1 − c_e)/(5 c_e)`` [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` uses the Hertz K of the joint.
        exponent: n (default 1.5).
        restitution: c_e in (0, 1] (default 0.9).
    """

    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂ = 8(1 − c_e)/(5 c_e)."""
        return 1.6 * (1.0 - self.restitution) / self.restitution


class Gonthier(AbstractDampedContactLaw):
    """Gonthier, McPhee, Lange & Piedbœuf (2004): ``χ̂ = (1 − c_e²)/c_e`` [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` uses the Hertz K of the joint.
        exponent: n (default 1.5).
        restitution: c_e in (0, 1] (default 0.9).
    """

    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂ = (1 − c_e²)/c_e."""
        return (1.0 - self.restitution**2) / self.restitution


class ZhiyingQishao(AbstractDampedContactLaw):
    """Zhiying & Qishao (2006): ``χ̂ = 3(1 − c_e²) e^{2(1 − c_e)}/4`` [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` uses the Hertz K of the joint.
        exponent: n (default 1.5).
        restitution: c_e in (0, 1] (default 0.9).
    """

    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂ = 3(1 − c_e²) e^{2(1 − c_e)}/4."""
        c_e = self.restitution
        return 0.75 * (1.0 - c_e**2) * jnp.exp(2.0 * (1.0 - c_e))
