"""Constraint function Φ(q, t), its Jacobian Φ_q, Φ̇ and γ, all from JAX derivatives (docs/model.md §1)."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float


def constraints(mechanism, q: Float[Array, " n"], t) -> Float[Array, " m"]:
    """Φ(q, t): rows of every ideal joint then the driver, in ``mechanism.constraint_elements`` order."""
    rows = [c.constraint(mechanism.index, q, t) for c in mechanism.constraint_elements]
    if not rows:
        return jnp.zeros((0,), dtype=q.dtype)
    return jnp.concatenate(rows)


def constraint_jacobian(mechanism, q, t) -> Float[Array, "m n"]:
    """Φ_q = ∂Φ/∂q by forward-mode differentiation."""
    return jax.jacfwd(constraints, argnums=1)(mechanism, q, t)


def _along_path(mechanism, q, qd, t):
    """Φ(q + s q̇, t + s) as a function of s: its s-derivatives at 0 are Φ̇ and Φ̈|_{q̈=0}."""
    t = jnp.asarray(t, dtype=q.dtype)
    return lambda s: constraints(mechanism, q + s * qd, t + s)


def constraint_velocity(mechanism, q, qd, t) -> Float[Array, " m"]:
    """Φ̇ = Φ_q q̇ + Φ_t."""
    f = _along_path(mechanism, q, qd, t)
    _, dphi = jax.jvp(f, (jnp.zeros((), q.dtype),), (jnp.ones((), q.dtype),))
    return dphi


def gamma(mechanism, q, qd, t) -> tuple[Float[Array, " m"], Float[Array, " m"]]:
    """Right-hand side γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt, and Φ̇.

    The second s-derivative of Φ(q + s q̇, t + s) equals q̇ᵀΦ_qq q̇ + 2Φ_qt q̇ + Φ_tt = −γ.
    """
    f = _along_path(mechanism, q, qd, t)
    zero, one = jnp.zeros((), q.dtype), jnp.ones((), q.dtype)

    def first(s):
        return jax.jvp(f, (s,), (one,))[1]

    dphi, d2phi = jax.jvp(first, (zero,), (one,))
    return -d2phi, dphi
