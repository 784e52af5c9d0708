"""Cylindrical (conformal, pin-in-hole) contact laws (docs/model.md §3) [lit].

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

from .._core._checks import check_positive, check_restitution
from .._core._smooth import safe_pow
from ._base import ContactGeometry, _array
from ._damped import AbstractLNDampedElasticLaw
from ._hertz import _optional_array

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


class Pereira2011(AbstractLNDampedElasticLaw):
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
        check_restitution(type(self).__name__, self.restitution)
        check_positive(
            type(self).__name__,
            "coefficient_a",
            self.coefficient_a,
            fix="use 0.965 (internal contact)",
        )
        check_positive(
            type(self).__name__,
            "coefficient_b",
            self.coefficient_b,
            fix="use 0.0965 (internal contact)",
        )
        if self.exponent is not None:
            check_positive(
                type(self).__name__,
                "exponent",
                self.exponent,
                fix="pass n > 0, or None for the fit",
            )
        check_positive(
            type(self).__name__,
            "fit_length_unit",
            self.fit_length_unit,
            fix="use 1e-3 (mm, as published)",
        )

    def effective_exponent(self, geometry: ContactGeometry) -> Float[Array, ""]:
        """The exponent n used for this joint (the fit unless given), dimensionless."""
        if self.exponent is not None:
            return self.exponent
        return pereira_exponent(geometry.clearance / self.fit_length_unit)

    def elastic_force(self, delta: Float[Array, ""], geometry: ContactGeometry) -> Float[Array, ""]:
        """``(a ΔR + b) h E* δ^n / ΔR`` evaluated in the fit's units, N."""
        unit = self.fit_length_unit
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
        return stiffness * safe_pow(delta / unit, n)


class Liu2007(AbstractLNDampedElasticLaw):
    """Liu, Zhang & Yang (2007) conformal cylindrical contact [lit], with L-N damping [ours].

    ``F_N = (π/2) E* h δ √(δ / (2(ΔR + δ))) · (1 + 3(1 − c_e²)/4 · δ̇/δ̇⁻)``. The elastic part is
    Liu's; it grows as δ^1.5 for δ ≪ ΔR and as δ for δ ≫ ΔR. The literature gives it without damping;
    the Lankarani–Nikravesh factor is our addition [ours] (``restitution=1`` recovers the
    published elastic law).

    Attributes:
        restitution: c_e in (0, 1] (default 0.9).
    """

    restitution: Float[Array, ""] = eqx.field(converter=_array, default=0.9)

    def __check_init__(self):
        check_restitution(type(self).__name__, self.restitution)

    def elastic_force(self, delta: Float[Array, ""], geometry: ContactGeometry) -> Float[Array, ""]:
        """``(π/2) E* h δ √(δ / (2(ΔR + δ)))``, N."""
        # δ √(δ/(2(ΔR + δ))) = δ^1.5 / √(2(ΔR + δ)): smooth at δ = 0 (ΔR > 0).
        shape = safe_pow(delta, 1.5) / jnp.sqrt(2.0 * (geometry.clearance + delta))
        return 0.5 * jnp.pi * geometry.combined_modulus * geometry.length * shape
