"""Elastic foundation model (EFM) of a pin in a bushing (docs/model.md §3) [lit; closed form ours].

A layer of thickness L on the bearing carries the pressure ``p = K_EF δ(ψ)/L`` with the layer
modulus ``K_EF = (1 − ν)E/((1 + ν)(1 − 2ν))``. With eccentricity ``e = c + δ`` the local
penetration at angle ψ from the line of centres is ``δ(ψ) = e cos ψ − c`` on the contact arc
``|ψ| <= θ_c = arccos(c/e)``. Integrating the normal components over the arc and the pin length h:

    F_N = K_EF (R h / L) (e θ_c − c sin θ_c)                                  [ours, derived]

which for δ ≪ c grows as ``K_EF (R h/L)(4/3)√(2/c) δ^1.5``. By default [ours] the layer is the
bearing's material (the softer/coated part), R is the bearing radius, and L is chosen so that this
small-δ stiffness equals the joint's Hertz K (h/L ≈ 0.28 for the benchmark joint).

``θ_c`` is computed as ``atan2(√(δ(2c + δ)), c)`` (equal to arccos(c/e)) with ``safe_sqrt`` so it
is smooth, with finite gradients, at contact onset.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._core._checks import check_count, check_positive, check_restitution
from .._core._smooth import safe_sqrt
from ._base import ContactGeometry, _array
from ._damped import AbstractLNDampedElasticLaw
from ._hertz import _optional_array

# Below this half-angle θ − sin θ is evaluated by its Taylor series to avoid cancellation.
_SERIES_ANGLE = 1e-2


def foundation_modulus(
    geometry: ContactGeometry, modulus: Float[Array, ""] | None = None
) -> Float[Array, ""]:
    """``K_EF = (1 − ν)E/((1 + ν)(1 − 2ν))`` of the bearing's material, Pa [ours: bearing side].

    Args:
        geometry: joint geometry and materials.
        modulus: an explicit K_EF in Pa, returned unchanged when not ``None``.

    Returns:
        K_EF, Pa.
    """
    if modulus is not None:
        return modulus
    young, poisson = geometry.bearing_young, geometry.bearing_poisson
    return (1.0 - poisson) * young / ((1.0 + poisson) * (1.0 - 2.0 * poisson))


def matched_layer_thickness(
    geometry: ContactGeometry, modulus: Float[Array, ""]
) -> Float[Array, ""]:
    """Layer thickness L that makes the small-δ EFM stiffness equal the Hertz K, m [ours].

    ``K_EF (R h/L)(4/3)√(2/c) = K_Hertz`` ⇒ ``L = K_EF R h (4/3) √(2/c) / K_Hertz``.
    """
    c = geometry.clearance
    return (
        modulus
        * geometry.bearing_radius
        * geometry.length
        * (4.0 / 3.0)
        * jnp.sqrt(2.0 / c)
        / geometry.hertz_stiffness
    )


def contact_half_angle(delta: ArrayLike, clearance: ArrayLike) -> Float[Array, "..."]:
    """θ_c = arccos(c/e) = atan2(√(δ(2c + δ)), c), rad; 0 (with zero gradient) at δ <= 0.

    Args:
        delta: smooth penetration δ_s >= 0, m.
        clearance: radial clearance c > 0, m.

    Returns:
        The half-angle of the contact arc, rad.
    """
    delta = jnp.asarray(delta)
    return jnp.arctan2(safe_sqrt(delta * (2.0 * clearance + delta)), clearance)


def local_penetration(
    delta: ArrayLike, eccentricity: ArrayLike, angle: ArrayLike
) -> Float[Array, "..."]:
    """``e cos ψ − c`` written as ``δ − 2e sin²(ψ/2)`` (no cancellation at small δ), m."""
    s = jnp.sin(0.5 * jnp.asarray(angle))
    return jnp.asarray(delta) - 2.0 * eccentricity * s * s


def _angle_minus_sine(theta: Float[Array, ""]) -> Float[Array, ""]:
    """θ − sin θ, accurate for small θ (series θ³/6 (1 − θ²/20 + θ⁴/840))."""
    small = theta < _SERIES_ANGLE
    t = jnp.where(small, theta, 0.0)
    t2 = t * t
    series = t * t2 / 6.0 * (1.0 - t2 / 20.0 + t2 * t2 / 840.0)
    return jnp.where(small, series, theta - jnp.sin(theta))


def foundation_coefficient(
    geometry: ContactGeometry,
    modulus: Float[Array, ""] | None = None,
    thickness: Float[Array, ""] | None = None,
) -> Float[Array, ""]:
    """The lumped coefficient ``K_EF R h / L``, N/m per radian of arc.

    Args:
        geometry: joint geometry and materials.
        modulus: K_EF in Pa, or ``None`` for the bearing's material [ours].
        thickness: L in m, or ``None`` for the Hertz-matched thickness [ours].
    """
    k_ef = foundation_modulus(geometry, modulus)
    layer = matched_layer_thickness(geometry, k_ef) if thickness is None else thickness
    return k_ef * geometry.bearing_radius * geometry.length / layer


def _check_foundation(law) -> None:
    check_restitution(type(law).__name__, law.restitution)
    if law.layer_thickness is not None:
        check_positive(
            type(law).__name__,
            "layer_thickness",
            law.layer_thickness,
            fix="pass L in m, or None to match Hertz K",
        )
    if law.foundation_modulus is not None:
        check_positive(
            type(law).__name__,
            "foundation_modulus",
            law.foundation_modulus,
            fix="pass K_EF in Pa, or None for bearing's",
        )


class ElasticFoundation(AbstractLNDampedElasticLaw):
    """Closed-form elastic foundation law ``F_N = K_EF (R h/L)(e θ_c − c sin θ_c)`` [ours].

    The closed form is elastic; as a usable law it is multiplied by the Lankarani–Nikravesh factor
    ``1 + 3(1 − c_e²)/4 · δ̇/δ̇⁻`` (clamped >= 0) [ours]; ``restitution=1`` gives the pure
    elastic closed form.

    Attributes:
        restitution: c_e in (0, 1] (default 0.9).
        layer_thickness: L, m; ``None`` (default) chooses L so the small-δ stiffness equals the
            joint's Hertz K [ours].
        foundation_modulus: K_EF, Pa; ``None`` (default) uses the bearing's material [ours].
    """

    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)
    layer_thickness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    foundation_modulus: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)

    def __check_init__(self):
        _check_foundation(self)

    def elastic_force(self, delta: Float[Array, ""], geometry: ContactGeometry) -> Float[Array, ""]:
        """Elastic closed form at smooth penetration ``delta >= 0``, N."""
        coefficient = foundation_coefficient(
            geometry, self.foundation_modulus, self.layer_thickness
        )
        c = geometry.clearance
        theta = contact_half_angle(delta, c)
        # e θ_c − c sin θ_c = δ θ_c + c (θ_c − sin θ_c), both terms >= 0.
        shape = delta * theta + c * _angle_minus_sine(theta)
        return coefficient * shape


class ElasticFoundationDiscrete(AbstractLNDampedElasticLaw):
    """Elastic foundation summed over m2 elements of the contact arc (midpoint rule) [ours].

    The arc ``[−θ_c, θ_c]`` (relative to n) is split into ``num_elements`` equal elements of
    angle ``Δθ = 2θ_c/m2``; element i at centre ψ_i has stiffness ``K_EF R Δθ h/L`` and
    penetration ``e cos ψ_i − c``, and pushes along ``(cos ψ_i, sin ψ_i)``. Converges to
    :class:`ElasticFoundation` as ``num_elements`` grows (error O(m2⁻²)). The sum is multiplied by
    the same Lankarani–Nikravesh factor as :class:`ElasticFoundation` [ours].

    Attributes:
        restitution: c_e in (0, 1] (default 0.9).
        num_elements: m2 >= 1 (static, default 10).
        layer_thickness: L, m; ``None`` matches the small-δ Hertz K [ours].
        foundation_modulus: K_EF, Pa; ``None`` uses the bearing's material [ours].
    """

    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)
    num_elements: int = eqx.field(static=True, default=10)
    layer_thickness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    foundation_modulus: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)

    def __check_init__(self):
        _check_foundation(self)
        check_count(type(self).__name__, "num_elements (m2)", self.num_elements)

    def elastic_force(self, delta: Float[Array, ""], geometry: ContactGeometry) -> Float[Array, ""]:
        """Elastic element sum at smooth penetration ``delta >= 0``, N."""
        coefficient = foundation_coefficient(
            geometry, self.foundation_modulus, self.layer_thickness
        )
        c = geometry.clearance
        theta = contact_half_angle(delta, c)
        m2 = self.num_elements
        centres = jnp.asarray((2.0 * np.arange(m2) + 1.0) / m2 - 1.0)  # in units of θ_c
        psi = theta * centres
        d_theta = 2.0 * theta / m2
        local = jnp.maximum(local_penetration(delta, c + delta, psi), 0.0)
        return coefficient * d_theta * jnp.sum(local * jnp.cos(psi))
