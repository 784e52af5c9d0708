"""Cylindrical (conformal, pin-in-hole) contact laws (MODEL.md §3) [lit].

Both depend on the pin length h (``geometry.length``), the radial clearance ΔR = R_B − R_J
(``geometry.clearance``) and the combined modulus E* (1/E* = σ_B + σ_J).

Pereira–Ramalho–Ambrósio 2011, unit convention [ours]
-------------------------------------------------------
The published law ``F_N = (a ΔR + b) h E* δ^n / ΔR`` is a fit to finite-element results and is
not dimensionally homogeneous (``b`` carries a length, and ``δ^n`` with ``n ≠ 1``), so its value
depends on the unit system the fits were made in. The exponent fits are written with ΔR in
millimetres (``Y = 1.51 [ln(1000 ΔR)]^(−0.151)`` on 0.005–0.34954 mm and ``Y = 0.0151 ΔR + 1.151``
on 0.34954–10 mm; the two branches meet at 0.34954 mm only with ΔR in mm, 1000 ΔR then being the
clearance in µm). We evaluate the *whole* law in the consistent mm–N–MPa system the fits use —
ΔR, h and δ in mm, E* in MPa (N/mm²), F_N in N — and convert inputs and output to SI:

    F_N = (a ΔR_u + b)/ΔR_u · (h/u) · (E* u²) · (δ/u)^n  [N],   u = 1 mm, ΔR_u = ΔR/u.

This choice reproduces Johnson's analytical conformal-cylinder law
``δ = (P/(π E*)) [ln(4π E* ΔR / P) − 1]``, ``P = F_N/h``, to within 10 % over
δ = 1–50 µm for the benchmark joint (checked in ``tests/test_contact_laws.py``), whereas mixing
SI for δ, h, E* with mm for ΔR only would make the law about three times too soft. The unit is
the parameter ``fit_length_unit``.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._smooth import safe_pow, smooth_ramp
from ._base import AbstractContactLaw, ContactGeometry, ContactKinematics, Smoothing, _array
from ._damped import damping_factor, lankarani_nikravesh_hysteresis
from ._hertz import _optional_array, check_positive, check_restitution

# Breakpoint and validity range of the exponent fits, in fit units (mm), Pereira et al. 2011.
_PEREIRA_BREAK = 0.34954
_PEREIRA_MIN_CLEARANCE = 0.005
_PEREIRA_MAX_CLEARANCE = 10.0


def pereira_exponent(clearance_in_fit_units: Float[Array, ""]) -> Float[Array, ""]:
    """Exponent ``n = Y ΔR^(−0.005)`` of Pereira et al. 2011 for internal contact.

    Args:
        clearance_in_fit_units: ΔR in the fit's length unit (mm). Values outside the fitted range
            0.005–10 mm are clipped to it [ours].

    Returns:
        n, dimensionless (about 1.16 for ΔR = 0.5 mm; between about 1.16 and 1.44 over the
        fitted range).
    """
    dr = jnp.clip(clearance_in_fit_units, _PEREIRA_MIN_CLEARANCE, _PEREIRA_MAX_CLEARANCE)
    # ln(1000 ΔR) >= ln 5 > 0 on the clipped range, so the power is safe in both branches.
    y_small = 1.51 * jnp.log(1000.0 * dr) ** (-0.151)
    y_large = 0.0151 * dr + 1.151
    y = jnp.where(dr <= _PEREIRA_BREAK, y_small, y_large)
    return y * dr ** (-0.005)


class Pereira2011(AbstractContactLaw):
    """Pereira, Ramalho & Ambrósio (2011) internal cylindrical contact with L-N damping [lit].

    ``F_N = (a ΔR + b) h E* δ^n / ΔR · (1 + 3(1 − c_e²)/4 · δ̇/δ̇⁻)``, evaluated in the
    fit's unit system (see the module docstring for the unit convention [ours]).

    Attributes:
        restitution: c_e in (0, 1] (default 0.9).
        coefficient_a: a, dimensionless (0.965 for internal contact).
        coefficient_b: b, in fit length units (0.0965 mm for internal contact).
        exponent: n; ``None`` (default) uses the published fit ``n = Y ΔR^(−0.005)``.
        fit_length_unit: u, the length unit of the published fits, m (default 1e-3: mm) [ours].
    """

    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)
    coefficient_a: Float[Array, ""] = eqx.field(converter=_array, default=0.965)
    coefficient_b: Float[Array, ""] = eqx.field(converter=_array, default=0.0965)
    exponent: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    fit_length_unit: Float[Array, ""] = eqx.field(converter=_array, default=1e-3)

    def __check_init__(self):
        check_restitution(self.restitution)
        check_positive(self.coefficient_a, "coefficient_a", "use 0.965 (internal contact)")
        check_positive(self.coefficient_b, "coefficient_b", "use 0.0965 (internal contact)")
        if self.exponent is not None:
            check_positive(self.exponent, "exponent", "pass n > 0, or None for the fit")
        check_positive(self.fit_length_unit, "fit_length_unit", "use 1e-3 (mm, as published)")

    def effective_exponent(self, geometry: ContactGeometry) -> Float[Array, ""]:
        """The exponent n used for this joint (the fit unless given), dimensionless."""
        if self.exponent is not None:
            return self.exponent
        return pereira_exponent(geometry.clearance / self.fit_length_unit)

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N.

        Args:
            kin: contact kinematics (penetration, penetration rate, impact velocity).
            geometry: joint geometry (clearance, pin length, materials).
            smoothing: regularisation widths.

        Returns:
            ``(normal, tangential)``, normal ``>= 0``, tangential 0.
        """
        unit = self.fit_length_unit
        delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
        dr = geometry.clearance / unit
        n = self.effective_exponent(geometry)
        # (a ΔR_u + b)/ΔR_u · h_u · E*_u · δ_u^n with h_u = h/u, E*_u = E* u² (N/u²), δ_u = δ/u.
        stiffness = (
            (self.coefficient_a * dr + self.coefficient_b)
            / dr
            * geometry.length
            * geometry.combined_modulus
            * unit
        )
        elastic = stiffness * safe_pow(delta / unit, n)
        factor = damping_factor(
            lankarani_nikravesh_hysteresis(self.restitution),
            kin.penetration_rate,
            kin.impact_velocity,
            smoothing.force_width,
        )
        normal = elastic * factor
        return normal, jnp.zeros_like(normal)


class Liu2007(AbstractContactLaw):
    """Liu, Zhang & Yang (2007) conformal cylindrical contact [lit], with L-N damping [ours].

    ``F_N = (π/2) E* h δ √(δ / (2(ΔR + δ))) · (1 + 3(1 − c_e²)/4 · δ̇/δ̇⁻)``. The elastic part is
    Liu's; it grows as δ^1.5 for δ ≪ ΔR and as δ for δ ≫ ΔR. MODEL.md gives it without damping;
    the Lankarani–Nikravesh factor is our addition [ours] (``restitution=1`` recovers the
    published elastic law).

    Attributes:
        restitution: c_e in (0, 1] (default 0.9).
    """

    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)

    def __check_init__(self):
        check_restitution(self.restitution)

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N.

        Args:
            kin: contact kinematics (penetration, penetration rate, impact velocity).
            geometry: joint geometry (clearance, pin length, materials).
            smoothing: regularisation widths.

        Returns:
            ``(normal, tangential)``, normal ``>= 0``, tangential 0.
        """
        delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
        # δ √(δ/(2(ΔR + δ))) = δ^1.5 / √(2(ΔR + δ)): smooth at δ = 0 (ΔR > 0).
        shape = safe_pow(delta, 1.5) / jnp.sqrt(2.0 * (geometry.clearance + delta))
        elastic = 0.5 * jnp.pi * geometry.combined_modulus * geometry.length * shape
        factor = damping_factor(
            lankarani_nikravesh_hysteresis(self.restitution),
            kin.penetration_rate,
            kin.impact_velocity,
            smoothing.force_width,
        )
        normal = elastic * factor
        return normal, jnp.zeros_like(normal)
