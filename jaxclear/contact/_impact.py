"""ADAMS-style IMPACT contact law (docs/model.md §3) [lit].

``F_N = max(0, K δ^e + STEP(δ, 0, 0, d_max, c_max) δ̇)`` where ``STEP`` is the cubic smooth step
from 0 at δ = 0 to c_max at δ = d_max. Provided for comparison with users of commercial codes.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_nonnegative, check_positive
from .._core._smooth import safe_pow, smooth_ramp, smooth_step
from ._base import (
    AbstractContactLaw,
    ContactGeometry,
    ContactKinematics,
    Smoothing,
    _array,
)
from ._damped import clamp_nonnegative
from ._hertz import _optional_array, resolve_stiffness


class AdamsImpact(AbstractContactLaw):
    """``F_N = max(0, K δ^e + STEP(δ, 0, 0, d_max, c_max) δ̇)`` [lit].

    The damping coefficient ramps with the cubic step ``3u² − 2u³``, ``u = δ/d_max``, which is
    the ADAMS ``STEP`` function. The outer ``max(0, ·)`` is the C¹ clamp
    :func:`~jaxclear.contact._damped.clamp_nonnegative` with a force width
    ``Smoothing.force_width · K d_max^e`` (the dimensionless force width times the elastic force at
    full damping depth) [ours].

    Attributes:
        stiffness: K, N/m^e; ``None`` (default) uses ``geometry.hertz_stiffness``.
        exponent: e, dimensionless (default 1.5).
        max_damping: c_max, N·s/m (default 1e3) [ours]: with the Hertz K of the benchmark joint
            (6.6e10 N/m^1.5) and the default d_max this gives an effective restitution of about
            0.88 for a 0.3 kg body hitting at 0.5 m/s (ADAMS' rule of thumb "1 % of K" is meant
            for N/mm units and does not transfer to SI).
        max_damping_penetration: d_max, m (default 1e-5, i.e. 0.01 mm, the low end of the
            0.01–0.1 mm usually quoted, since clearance-joint penetrations are 1–80 µm) [ours].
    """

    stiffness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    exponent: Float[Array, ""] = eqx.field(converter=_array, default=1.5)
    max_damping: Float[Array, ""] = eqx.field(converter=_array, default=1e3)
    max_damping_penetration: Float[Array, ""] = eqx.field(converter=_array, default=1e-5)

    def __check_init__(self):
        if self.stiffness is not None:
            check_positive(
                type(self).__name__,
                "stiffness",
                self.stiffness,
                fix="pass K in N/m^e, or None for Hertz K",
            )
        check_positive(
            type(self).__name__, "exponent", self.exponent, fix="pass e > 0 (1.5 for Hertz)"
        )
        check_nonnegative(
            type(self).__name__, "max_damping", self.max_damping, fix="pass c_max >= 0 in N s/m"
        )
        check_positive(
            type(self).__name__,
            "max_damping_penetration",
            self.max_damping_penetration,
            fix="pass d_max > 0 in m (e.g. 1e-5)",
        )

    def __call__(
        self, kin: ContactKinematics, geometry: ContactGeometry, smoothing: Smoothing
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """Contact force on the journal in the (n, t) frame, N.

        Args:
            kin: contact kinematics (penetration and its rate; the impact velocity is unused).
            geometry: joint geometry (source of the default stiffness).
            smoothing: regularisation widths.

        Returns:
            ``(normal, tangential)``, normal ``>= 0`` (exactly 0 for δ <= 0), tangential 0.
        """
        stiffness = resolve_stiffness(self.stiffness, geometry)
        delta = smooth_ramp(kin.penetration, smoothing.penetration_width)
        elastic = stiffness * safe_pow(delta, self.exponent)
        # STEP(δ, 0, 0, d_max, c_max): 0 for δ <= 0, so the raw force vanishes in free flight.
        damping = self.max_damping * smooth_step(kin.penetration, self.max_damping_penetration)
        raw = elastic + damping * kin.penetration_rate
        force_scale = stiffness * self.max_damping_penetration**self.exponent
        normal = clamp_nonnegative(raw, smoothing.force_width * force_scale)
        return normal, jnp.zeros_like(normal)
