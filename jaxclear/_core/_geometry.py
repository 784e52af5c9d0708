"""Planar kinematics of points on bodies (docs/model.md §1).

Shared by the model (ideal joints' constraint functions, applied forces, springs) and the dynamics
(clearance joints), so it lives beside both rather than in either.
"""

import jax.numpy as jnp
from jaxtyping import Array, Float


def rotation(phi: Float[Array, ""]) -> Float[Array, "2 2"]:
    """A(φ), the 2x2 rotation from body to global frame."""
    c, s = jnp.cos(phi), jnp.sin(phi)
    return jnp.array([[c, -s], [s, c]])


# Small products are written element by element: XLA's CPU backend runs every `dot` as its own
# kernel, while elementwise arithmetic fuses; in the right-hand side each kernel launch costs
# ~45 ns, about the price of the arithmetic of a whole joint (measured, benchmarks/bench_clearance.py).
def dot2(a: Float[Array, "2"], b: Float[Array, "2"]) -> Float[Array, ""]:
    """aᵀb of two 2-vectors."""
    return a[0] * b[0] + a[1] * b[1]


def rotate(phi: Float[Array, ""], v: Float[Array, "2"]) -> Float[Array, "2"]:
    """A(φ) v."""
    c, s = jnp.cos(phi), jnp.sin(phi)
    return jnp.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def body_coordinates(q: Float[Array, " n"], index: int | None):
    """(r, φ) of body ``index`` from the stacked coordinates; ground (``None``) is (0, 0)."""
    if index is None:
        return jnp.zeros(2, dtype=q.dtype), jnp.zeros((), dtype=q.dtype)
    return q[3 * index : 3 * index + 2], q[3 * index + 2]


def point_position(
    q: Float[Array, " n"], index: int | None, local: Float[Array, "2"]
) -> Float[Array, "2"]:
    """Global position r + A(φ) s' of a point with local vector ``local`` on body ``index``.

    Points on ground (``index is None``) are given in global coordinates.
    """
    if index is None:
        return jnp.asarray(local, dtype=q.dtype)
    r, phi = body_coordinates(q, index)
    return r + rotate(phi, local)


def point_velocity(q, qd, index: int | None, local) -> Float[Array, "2"]:
    """Global velocity ṙ + φ̇ B(φ) s' of a body-fixed point."""
    if index is None:
        return jnp.zeros(2, dtype=q.dtype)
    _, phi = body_coordinates(q, index)
    rd, phid = body_coordinates(qd, index)
    c, s = jnp.cos(phi), jnp.sin(phi)
    return rd + phid * jnp.stack([-s * local[0] - c * local[1], c * local[0] - s * local[1]])


def perp(v: Float[Array, "2"]) -> Float[Array, "2"]:
    """v turned by +90°: (−v_y, v_x)."""
    return jnp.stack([-v[1], v[0]])


def cross2(a: Float[Array, "2"], b: Float[Array, "2"]) -> Float[Array, ""]:
    """z-component of the planar cross product a × b."""
    return a[0] * b[1] - a[1] * b[0]


def point_force_to_generalized(
    q: Float[Array, " n"], index: int | None, point: Float[Array, "2"], force: Float[Array, "2"]
) -> Float[Array, " n"]:
    """Generalised force of a force ``force`` (global) applied at the global point ``point``.

    Returns a vector the size of q: (F_x, F_y, (r_P - r_k) × F) in the body's slots, zero
    elsewhere (and zero for ground).
    """
    out = jnp.zeros_like(q)
    if index is None:
        return out
    r, _ = body_coordinates(q, index)
    moment = cross2(point - r, force)
    return out.at[3 * index : 3 * index + 3].add(jnp.stack([force[0], force[1], moment]))
