"""Smooth, gradient-safe primitives for non-smooth contact quantities (docs/model.md §5) [ours].

Every function here is C¹, finite, and has finite gradients everywhere, including the kinks of
the functions they regularise (zero penetration, zero eccentricity, zero slip). Non-smooth points
use the double-``where`` pattern (jax_md/util.py ``safe_mask``): the unsafe branch never sees an
input at which its derivative is infinite, so no NaN leaks into the gradient.

As each width goes to zero these functions converge to their sharp counterparts: ``smooth_ramp``
to ``max(x, 0)``, ``smooth_step`` to the Heaviside step, ``smooth_abs`` to ``|x|``.
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float


def smooth_ramp(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """C¹ positive part with compact support: exactly 0 for ``x <= 0``.

    ``0`` for ``x <= 0``; ``x²/(2w)`` for ``0 < x < w``; ``x - w/2`` for ``x >= w``.
    The shift of ``w/2`` in the linear branch vanishes as ``w -> 0``.

    Args:
        x: the quantity to clip at zero (e.g. penetration in m).
        width: transition width ``w > 0``, same units as ``x``.

    Returns:
        The smoothed positive part, same shape as ``x``.
    """
    x = jnp.asarray(x)
    width = jnp.asarray(width)
    xc = jnp.clip(x, 0.0, width)
    quad = xc * xc / (2.0 * width)
    return jnp.where(x >= width, x - 0.5 * width, quad)


def smooth_step(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """C¹ cubic step from 0 at ``x <= 0`` to 1 at ``x >= width`` (``3u² - 2u³``)."""
    u = jnp.clip(jnp.asarray(x) / width, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def smooth_abs(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """``sqrt(x² + w²)``: smooth ``|x|``, at least ``w``."""
    x = jnp.asarray(x)
    return jnp.sqrt(x * x + jnp.asarray(width) ** 2)


def smooth_sign(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """``x / sqrt(x² + w²)``: smooth sign in (-1, 1)."""
    x = jnp.asarray(x)
    return x / smooth_abs(x, width)


def smooth_max(x: ArrayLike, floor: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """C¹ ``max(x, floor)``, exact outside ``[floor - width/2, floor + width/2]`` (``floor + w/8`` at ``x = floor``)."""
    return jnp.asarray(floor) + smooth_ramp(jnp.asarray(x) - floor + 0.5 * width, width)


def safe_norm(v: ArrayLike, axis: int = -1) -> Float[Array, "..."]:
    """Euclidean norm with gradient 0 (not NaN) at ``v = 0``."""
    v = jnp.asarray(v)
    sq = jnp.sum(v * v, axis=axis)
    is_zero = sq <= 0.0
    return jnp.where(is_zero, 0.0, jnp.sqrt(jnp.where(is_zero, 1.0, sq)))


def safe_sqrt(x: ArrayLike) -> Float[Array, "..."]:
    """``sqrt(max(x, 0))`` with gradient 0 (not inf) at ``x <= 0``."""
    x = jnp.asarray(x)
    pos = x > 0.0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def safe_pow(x: ArrayLike, exponent: ArrayLike) -> Float[Array, "..."]:
    """``max(x, 0) ** exponent`` for ``exponent > 0`` with finite gradients at ``x <= 0``."""
    x = jnp.asarray(x)
    pos = x > 0.0
    return jnp.where(pos, jnp.where(pos, x, 1.0) ** exponent, 0.0)
