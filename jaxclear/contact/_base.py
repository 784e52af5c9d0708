"""Shared contract of the normal contact force laws (docs/model.md §3).

A law is an ``eqx.Module`` whose parameters (restitution, exponents, element counts, ...) are its
fields. The joint's geometry and materials come from the clearance joint through
:class:`ContactGeometry`; the instantaneous contact kinematics through :class:`ContactKinematics`;
the regularisation widths through :class:`Smoothing`. A law returns the contact force that the
bearing exerts on the journal, as components in the joint's (n, t) frame:

- ``normal``: along ``-n`` on the journal (pushes the journal back to the bearing centre), ``>= 0``;
- ``tangential``: along ``t`` on the journal; zero for point laws, non-zero only for distributed
  laws (the hybrid law's element damping is asymmetric when the contact point moves).

Laws must be exactly zero in free flight (penetration <= 0), finite with finite gradients at
penetration 0, eccentricity 0 and zero rates.
"""

import abc
import dataclasses

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_positive


def _array(x):
    return jnp.asarray(x, dtype=float)


class Smoothing(eqx.Module):
    """Regularisation widths of the smooth formulation (docs/model.md §5) [ours].

    Attributes:
        penetration_width: width of the smooth positive part of the penetration, m.
        velocity_width: width of smooth ``|v|`` and ``sign(v)`` for slip velocities, m/s.
        memory_width: the impact-velocity memory freezes over ``-memory_width < δ < 0``, m.
        memory_rate: relaxation rate ``k_m`` of the memory toward δ̇ in free flight, 1/s.
        min_impact_velocity: lower bound ``v_min`` on the impact velocity used for damping, m/s.
        force_width: dimensionless width of the smooth clamp of damped force factors at zero.
    """

    penetration_width: Float[Array, ""] = eqx.field(converter=_array, default=1e-7)
    velocity_width: Float[Array, ""] = eqx.field(converter=_array, default=1e-5)
    memory_width: Float[Array, ""] = eqx.field(converter=_array, default=1e-7)
    memory_rate: Float[Array, ""] = eqx.field(converter=_array, default=1e6)
    min_impact_velocity: Float[Array, ""] = eqx.field(converter=_array, default=1e-4)
    force_width: Float[Array, ""] = eqx.field(converter=_array, default=1e-3)

    def check(self, owner: str) -> None:
        """Raise ``ModelError`` naming ``owner`` and the width unless every width is positive."""
        for f in dataclasses.fields(self):
            check_positive(owner, f"smoothing.{f.name}", getattr(self, f.name))


class ContactGeometry(eqx.Module):
    """Geometry and materials of a pin (journal) in a hole (bearing).

    Attributes:
        bearing_radius: R_B, m.
        journal_radius: R_J, m (``< R_B``).
        length: pin length h, m (used by cylindrical and foundation laws).
        bearing_young, bearing_poisson: E_B in Pa, ν_B in (0, 0.5).
        journal_young, journal_poisson: E_J in Pa, ν_J in (0, 0.5).
    """

    bearing_radius: Float[Array, ""] = eqx.field(converter=_array)
    journal_radius: Float[Array, ""] = eqx.field(converter=_array)
    length: Float[Array, ""] = eqx.field(converter=_array, default=0.01)
    bearing_young: Float[Array, ""] = eqx.field(converter=_array, default=207e9)
    bearing_poisson: Float[Array, ""] = eqx.field(converter=_array, default=0.3)
    journal_young: Float[Array, ""] = eqx.field(converter=_array, default=207e9)
    journal_poisson: Float[Array, ""] = eqx.field(converter=_array, default=0.3)

    @property
    def clearance(self) -> Float[Array, ""]:
        """Radial clearance c = R_B - R_J, m."""
        return self.bearing_radius - self.journal_radius

    @property
    def effective_radius(self) -> Float[Array, ""]:
        """R* = R_B R_J / (R_B - R_J) for a pin in a hole, m."""
        return self.bearing_radius * self.journal_radius / self.clearance

    @property
    def compliance_sum(self) -> Float[Array, ""]:
        """σ_B + σ_J with σ_k = (1 - ν_k²)/E_k, 1/Pa."""
        sb = (1.0 - self.bearing_poisson**2) / self.bearing_young
        sj = (1.0 - self.journal_poisson**2) / self.journal_young
        return sb + sj

    @property
    def combined_modulus(self) -> Float[Array, ""]:
        """E* with 1/E* = σ_B + σ_J, Pa."""
        return 1.0 / self.compliance_sum

    @property
    def hertz_stiffness(self) -> Float[Array, ""]:
        """K = 4/(3(σ_B + σ_J)) √R*, N/m^1.5 (docs/model.md §3, Hertz)."""
        return 4.0 / (3.0 * self.compliance_sum) * jnp.sqrt(self.effective_radius)


class ContactKinematics(eqx.Module):
    """Instantaneous contact kinematics of one clearance joint.

    Attributes:
        penetration: δ = e - c, m (negative in free flight; laws apply the smooth positive part).
        penetration_rate: δ̇ = nᵀė, m/s.
        impact_velocity: δ̇⁻, the normal approach speed latched at contact onset, m/s, already
            bounded below by ``Smoothing.min_impact_velocity`` (so > 0).
        tangential_rate: tᵀė = e θ̇_n, m/s, the speed at which the line of centres sweeps round.
    """

    penetration: Float[Array, ""] = eqx.field(converter=_array)
    penetration_rate: Float[Array, ""] = eqx.field(converter=_array)
    impact_velocity: Float[Array, ""] = eqx.field(converter=_array)
    tangential_rate: Float[Array, ""] = eqx.field(converter=_array, default=0.0)


class AbstractContactLaw(eqx.Module):
    """Base of all normal contact laws: ``law(kin, geometry, smoothing) -> (normal, tangential)``."""

    @abc.abstractmethod
    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N; ``normal >= 0`` pushes it inward."""
