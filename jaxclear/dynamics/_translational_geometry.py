"""Corner geometry and corner forces of a translational clearance joint (docs/model.md §2c).

Reconstructed from Flores, Ambrósio, Claro & Lankarani, "Translational joints with clearance in
rigid multibody systems", J. Comput. Nonlinear Dynam. 3(1) 011007 (2008), and Flores, Leine &
Glocker, "Modeling and analysis of planar rigid multibody systems with translational clearance
joints based on the non-smooth dynamics approach", Multibody Syst. Dyn. 23:165–190 (2010): the
four corners of the slider are four gap functions against the two guide faces; the slider's
states (free flight, one corner, a face resting flat on two adjacent corners, two opposite
corners) follow from their signs. The formulas below are ours where the papers' full text was
not at hand [ours]; they are isolated here so that they can be checked and replaced.

Geometry (all vectors global):
- guide frame: origin r_Q (``guide_point``), axis t = A(φ_g) â, normal n = t turned +90°;
- slider frame: long axis u = A(φ_s − α) â (α the nominal relative angle), v = u turned +90°;
  reference point r_P (``slider_point``), the rectangle's centre;
- corner k: r_k = r_P + σ_a,k a u + σ_b,k b v with (σ_a, σ_b) = (+,+), (−,+), (−,−), (+,−)
  (``CORNER_NAMES``: upper front, upper rear, lower rear, lower front);
- penetration of corner k into the face on its side (σ_b = +1: the face at +(b + c) along n,
  σ_b = −1: the face at −(b + c)):  δ_k = σ_b,k nᵀ(r_k − r_Q) − (b + c), gap g_k = −δ_k;
  for a ground guide along x through the origin, slider centre (x, y) and tilt θ:
  δ_k = σ_b y + σ_a σ_b a sin θ + b cos θ − (b + c);
- tilt θ = φ_s − φ_g − α; lateral offset y = nᵀ(r_P − r_Q).

Forces at corner k (on the slider; the guide gets the opposite at the same point, so the pair
has no net moment): f_k = −σ_b,k F_N,k n + F_T,k t, with F_N,k from a point contact law of
(δ_k, δ̇_k, impact velocity m_k) and F_T,k from the friction law of the slip velocity
v_T,k = tᵀ(ṙ_k^slider − ṙ_k^guide) of the slider's and the guide's material points at r_k.
"""

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core._geometry import dot2, perp, point_position, rotate

CORNER_ENDS = np.array([1.0, -1.0, -1.0, 1.0])
"""σ_a of each corner: +1 front (along +axis), −1 rear."""
CORNER_SIDES = np.array([1.0, 1.0, -1.0, -1.0])
"""σ_b of each corner: +1 upper (faces the guide face along +n), −1 lower."""


def guide_frame(joint, qg) -> tuple[Float[Array, "2"], Float[Array, "2"], Float[Array, "2"]]:
    """(r_Q, t, n): a point of the guide line, its unit axis and unit normal (global).

    ``qg``: the guide body's (x, y, φ), zeros for ground (``guide_point`` is then global).
    """
    axis = joint.axis / jnp.sqrt(dot2(joint.axis, joint.axis))
    t = rotate(qg[2], axis)
    return point_position(qg, 0, joint.guide_point), t, perp(t)


def corner_positions(joint, qs) -> Float[Array, "4 2"]:
    """r_k of the four corners (``CORNER_NAMES`` order), m; ``qs`` the slider's (x, y, φ)."""
    axis = joint.axis / jnp.sqrt(dot2(joint.axis, joint.axis))
    u = rotate(qs[2] - joint.angle, axis)
    v = perp(u)
    centre = point_position(qs, 0, joint.slider_point)
    ends = jnp.asarray(CORNER_ENDS, centre.dtype)[:, None] * joint.half_length
    sides = jnp.asarray(CORNER_SIDES, centre.dtype)[:, None] * joint.half_height
    return centre[None, :] + ends * u[None, :] + sides * v[None, :]


def corner_penetrations(joint, qs, qg) -> Float[Array, " 4"]:
    """δ_k = σ_b,k nᵀ(r_k − r_Q) − (b + c), m (positive: the corner is inside its guide face)."""
    origin, _, n = guide_frame(joint, qg)
    d = corner_positions(joint, qs) - origin[None, :]
    height = d[:, 0] * n[0] + d[:, 1] * n[1]
    sides = jnp.asarray(CORNER_SIDES, height.dtype)
    return sides * height - (joint.half_height + joint.clearance)


def tilt(joint, qs, qg) -> Float[Array, ""]:
    """θ = φ_s − φ_g − α, rad: the slider's angle to the guide."""
    return qs[2] - qg[2] - joint.angle


def lateral_offset(joint, qs, qg) -> Float[Array, ""]:
    """y = nᵀ(r_P − r_Q), m: the slider centre's offset from the guide line along n."""
    origin, _, n = guide_frame(joint, qg)
    return dot2(n, point_position(qs, 0, joint.slider_point) - origin)


def penetration_rates(joint, qs, qds, qg, qdg) -> tuple[Float[Array, " 4"], Float[Array, " 4"]]:
    """(δ_k, δ̇_k): penetrations and their rates (forward-mode derivative along the velocities)."""
    return jax.jvp(lambda a, b: corner_penetrations(joint, a, b), (qs, qg), (qds, qdg))


def penetration_accelerations(joint, qs, qds, qdds, qg, qdg, qddg) -> Float[Array, " 4"]:
    """δ̈_k = ∂δ/∂q q̈ + q̇ᵀ ∂²δ/∂q² q̇: the second derivative of δ along q(s) = q + s q̇ + s²q̈/2."""

    def along(s):
        return corner_penetrations(
            joint, qs + s * qds + 0.5 * s**2 * qdds, qg + s * qdg + 0.5 * s**2 * qddg
        )

    zero, one = jnp.zeros((), qs.dtype), jnp.ones((), qs.dtype)

    def first(s):
        return jax.jvp(along, (s,), (one,))[1]

    return jax.jvp(first, (zero,), (one,))[1]


def slip_velocities(joint, corners, qs, qds, qg, qdg) -> Float[Array, " 4"]:
    """v_T,k = tᵀ(ṙ_k^slider − ṙ_k^guide) of the material points at the corners r_k, m/s."""
    _, t, _ = guide_frame(joint, qg)

    def velocity(qk, qdk, point):
        return qdk[:2] + qdk[2] * perp(point - qk[:2])

    rel = jax.vmap(lambda r: velocity(qs, qds, r) - velocity(qg, qdg, r))(corners)
    return rel[:, 0] * t[0] + rel[:, 1] * t[1]


def corner_force_vectors(joint, qg, normal, tangential) -> Float[Array, "4 2"]:
    """f_k = −σ_b,k F_N,k n + F_T,k t on the slider at each corner (global components), N."""
    _, t, n = guide_frame(joint, qg)
    sides = jnp.asarray(CORNER_SIDES, normal.dtype)
    return (-sides * normal)[:, None] * n[None, :] + tangential[:, None] * t[None, :]


def wrench(qk, points, forces) -> Float[Array, "3"]:
    """(ΣF_x, ΣF_y, Σ(r_k − r_body) × F_k) of forces at global points on a body with coordinates qk."""
    d = points - qk[None, :2]
    moment = d[:, 0] * forces[:, 1] - d[:, 1] * forces[:, 0]
    return jnp.stack([jnp.sum(forces[:, 0]), jnp.sum(forces[:, 1]), jnp.sum(moment)])
