"""Hybrid Lankarani–Nikravesh + elastic-foundation law, the paper's model (docs/model.md §3, items 1–5)
[paper for the ingredients, ours for the details].

Angles ψ are measured from the line of centres n towards t (t = n rotated by +90°), so the point of
the bearing at angle ψ has direction ``(cos ψ, sin ψ)`` in (n, t) coordinates.

1. The contact arc ``|ψ| <= θ_c = arccos(c/e)`` is split into m2 elements of angle
   ``Δθ = 2θ_c/m2`` with centres ψ_i.
2. Each element is sampled at m1 Gauss–Legendre points ``ψ_ij = ψ_i + (Δθ/2) x_j`` with weights
   H_j; ``δ_ij = e cos ψ_ij − c`` and ``δ_i = Σ_j H_j δ_ij / 2`` (the weighted mean).
3. ``K_i = K_EF R Δθ h / L`` (constant layer thickness L).
4. ``F_i = K_i δ_i + D_i^mod δ̇_i``, clamped >= 0, with ``D_i = 3 K_i (1 − c_e²) δ_i/(4 δ̇_i⁻)``
   and ``D_i^mod = D_i e^{2(1 − c_e)}`` (Bai & Zhao 2013) when ``damping_modification``; the
   element impact velocity is ``δ̇_i⁻ = max(δ̇⁻ cos ψ_i, v_min)`` and the element rate
   ``δ̇_i = δ̇ cos ψ_i + e θ̇_n sin ψ_i``. Equivalently ``F_i = K_i δ_i max(0, 1 + χ̂ δ̇_i/δ̇_i⁻)``
   with ``χ̂ = 3(1 − c_e²)/4 [· e^{2(1 − c_e)}]``.
5. Element i pushes the journal along ``−(cos ψ_i, sin ψ_i)``. The force on the journal is
   therefore ``−(Σ F_i cos ψ_i) n − (Σ F_i sin ψ_i) t``, returned as
   ``normal = Σ F_i cos ψ_i`` (along −n, >= 0) and ``tangential = −Σ F_i sin ψ_i`` (along +t).
   When the line of centres sweeps towards +t (``tangential_rate > 0``) the elements at ψ > 0 are
   being compressed and carry more damping force, so the tangential force is negative: it
   opposes the sweep, like a drag.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core._checks import check_count, check_positive, check_restitution
from .._core._smooth import smooth_max, smooth_ramp
from ._base import (
    AbstractContactLaw,
    ContactGeometry,
    ContactKinematics,
    Smoothing,
    _array,
)
from ._damped import clamp_nonnegative, lankarani_nikravesh_hysteresis
from ._foundation import (
    contact_half_angle,
    foundation_coefficient,
    local_penetration,
)
from ._hertz import _optional_array


class Hybrid(AbstractContactLaw):
    """The paper's hybrid L-N + elastic-foundation law over m2 elements × m1 Gauss points.

    See the module docstring for the equations. Defaults [ours]: m1 = 3, m2 = 10, damping
    modification on, layer thickness matched to the Hertz K at small δ, bearing material for
    K_EF. With ``restitution=1`` it is purely elastic and converges to
    :class:`~jaxclear.contact.ElasticFoundation` as m2 grows.

    Attributes:
        restitution: c_e in (0, 1] (default 0.9).
        num_gauss_points: m1 >= 1, Gauss–Legendre points per element (static, default 3).
        num_elements: m2 >= 1, elements on the contact arc (static, default 10).
        damping_modification: multiply the L-N damping by ``e^{2(1 − c_e)}`` (Bai & Zhao 2013)
            (static, default True).
        layer_thickness: L, m; ``None`` matches the small-δ stiffness to the Hertz K [ours].
        foundation_modulus: K_EF, Pa; ``None`` uses the bearing's material [ours].
    """

    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)
    num_gauss_points: int = eqx.field(static=True, default=3)
    num_elements: int = eqx.field(static=True, default=10)
    damping_modification: bool = eqx.field(static=True, default=True)
    layer_thickness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    foundation_modulus: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)

    def __check_init__(self):
        check_restitution(type(self).__name__, self.restitution)
        check_count(type(self).__name__, "num_gauss_points (m1)", self.num_gauss_points)
        check_count(type(self).__name__, "num_elements (m2)", self.num_elements)
        if not isinstance(self.damping_modification, bool):
            raise ValueError(
                f"damping_modification must be a bool, got {self.damping_modification!r}: "
                "pass True (Bai & Zhao factor) or False (plain L-N)"
            )
        if self.layer_thickness is not None:
            check_positive(
                type(self).__name__,
                "layer_thickness",
                self.layer_thickness,
                fix="pass L in m, or None to match Hertz K",
            )
        if self.foundation_modulus is not None:
            check_positive(
                type(self).__name__,
                "foundation_modulus",
                self.foundation_modulus,
                fix="pass K_EF in Pa, or None for the bearing's material",
            )

    def hysteresis_factor(self) -> Float[Array, ""]:
        """χ̂ = 3(1 − c_e²)/4, times e^{2(1 − c_e)} with the damping modification."""
        chi = lankarani_nikravesh_hysteresis(self.restitution)
        if self.damping_modification:
            chi = chi * jnp.exp(2.0 * (1.0 - self.restitution))
        return chi

    def element_forces(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, " m2"], Float[Array, " m2"]]:
        """Element forces F_i >= 0 (N) and element centre angles ψ_i (rad), shape ``(m2,)``."""
        m1, m2 = self.num_gauss_points, self.num_elements
        nodes, weights = np.polynomial.legendre.leggauss(m1)
        centres = (2.0 * np.arange(m2) + 1.0) / m2 - 1.0  # ψ_i / θ_c, in (−1, 1)

        c = geometry.clearance
        delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
        e = c + delta
        theta = contact_half_angle(delta, c)
        d_theta = 2.0 * theta / m2

        psi = theta * jnp.asarray(centres)  # (m2,)
        psi_points = psi[:, None] + (0.5 * d_theta) * jnp.asarray(nodes)[None, :]  # (m2, m1)
        delta_points = local_penetration(delta, e, psi_points)
        delta_elements = jnp.maximum(0.5 * (delta_points @ jnp.asarray(weights)), 0.0)

        stiffness = (
            foundation_coefficient(geometry, self.foundation_modulus, self.layer_thickness)
            * d_theta
        )  # K_i = K_EF R Δθ h / L, N/m

        cos_psi, sin_psi = jnp.cos(psi), jnp.sin(psi)
        rate = kin.penetration_rate * cos_psi + kin.tangential_rate * sin_psi
        impact = smooth_max(
            kin.impact_velocity * cos_psi,
            smoothing.min_impact_velocity,
            smoothing.velocity_width,
        )
        factor = clamp_nonnegative(
            1.0 + self.hysteresis_factor() * rate / impact, smoothing.force_width
        )
        return stiffness * delta_elements * factor, psi

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N.

        Args:
            kin: contact kinematics (penetration, its rate, impact velocity, tangential rate).
            geometry: joint geometry (radii, pin length, bearing material).
            smoothing: regularisation widths.

        Returns:
            ``(normal, tangential) = (Σ F_i cos ψ_i, −Σ F_i sin ψ_i)``: normal ``>= 0`` along −n,
            tangential along +t (see the module docstring for the sign).
        """
        forces, psi = self.element_forces(kin, geometry, smoothing)
        normal = jnp.sum(forces * jnp.cos(psi))
        tangential = -jnp.sum(forces * jnp.sin(psi))
        return normal, tangential
