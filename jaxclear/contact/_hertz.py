"""Hertz point contact law (MODEL.md §3) and the construction-time parameter checks shared by
the contact and friction laws.

The checks run only on concrete values (Python/NumPy/JAX arrays); when a law is built inside
``jit`` or ``vmap`` its leaves are tracers and the checks are skipped.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._smooth import safe_pow, smooth_ramp
from ._base import AbstractContactLaw, ContactGeometry, ContactKinematics, Smoothing, _array


def _optional_array(x):
    """Converter for parameters where ``None`` means "derive from the geometry"."""
    return None if x is None else _array(x)


def _concrete(x) -> np.ndarray | None:
    """NumPy value of ``x``, or ``None`` when ``x`` is traced (inside jit/vmap)."""
    try:
        return np.asarray(x)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return None


def _fail(value, name: str, requirement: str, fix: str) -> None:
    raise ValueError(f"{name} must be {requirement}, got {value}: {fix}")


def check_positive(value, name: str, fix: str = "pass a positive value in SI units") -> None:
    """Raise ``ValueError`` naming ``name`` unless the concrete ``value`` is finite and ``> 0``."""
    v = _concrete(value)
    if v is not None and not np.all(np.isfinite(v) & (v > 0)):
        _fail(v, name, "finite and > 0", fix)


def check_nonnegative(value, name: str, fix: str = "pass a value >= 0 in SI units") -> None:
    """Raise ``ValueError`` naming ``name`` unless the concrete ``value`` is finite and ``>= 0``."""
    v = _concrete(value)
    if v is not None and not np.all(np.isfinite(v) & (v >= 0)):
        _fail(v, name, "finite and >= 0", fix)


def check_restitution(value, name: str = "restitution") -> None:
    """Raise ``ValueError`` unless the concrete coefficient of restitution is in (0, 1]."""
    v = _concrete(value)
    if v is not None and not np.all((v > 0) & (v <= 1)):
        _fail(
            v,
            name,
            "in (0, 1]",
            "use 1 for a perfectly elastic contact and e.g. 0.9 for steel on steel",
        )


def check_count(value, name: str) -> None:
    """Raise ``ValueError`` unless ``value`` is a Python integer ``>= 1`` (a static count)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        _fail(value, name, "an integer >= 1", "pass a positive whole number")


def resolve_stiffness(
    stiffness: Float[Array, ""] | None, geometry: ContactGeometry
) -> Float[Array, ""]:
    """The law's stiffness, or the joint's Hertz stiffness when it is ``None``, N/m^n."""
    return geometry.hertz_stiffness if stiffness is None else stiffness


class Hertz(AbstractContactLaw):
    """Undamped Hertz contact: ``F_N = K δ^n`` (MODEL.md §3) [lit].

    Attributes:
        stiffness: K, N/m^n; ``None`` (default) uses ``geometry.hertz_stiffness``
            (``4/(3(σ_B + σ_J)) √R*``).
        exponent: n, dimensionless (1.5 for Hertz point contact).
    """

    stiffness: Float[Array, ""] | None = eqx.field(converter=_optional_array, default=None)
    exponent: Float[Array, ""] = eqx.field(converter=_array, default=1.5)

    def __check_init__(self):
        if self.stiffness is not None:
            check_positive(self.stiffness, "stiffness", "pass K in N/m^n, or None for Hertz K")
        check_positive(self.exponent, "exponent", "pass n > 0 (1.5 for Hertz)")

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
