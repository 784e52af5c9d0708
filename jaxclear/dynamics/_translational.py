"""Physics of a translational clearance joint (docs/model.md §2c): corner kinematics, contact and
friction forces, impact memories and friction states.

The joint's parameters are data (``jaxclear.model.TranslationalClearanceJoint``); the corner
geometry and force formulas are in ``_translational_geometry`` (their sources named there). As in
``_clearance``, everything is written on the two joined bodies' coordinates ("local"): qg, qdg
(guide) and qs, qds (slider), 3-vectors, zeros for ground.

Internal state of a joint (size 4 (1 + s), s the friction law's states per corner):
[m_1, ..., m_4 (or u_k = m_k − δ̇_k when ``joint.memory_offset``), friction states of corner 1,
..., of corner 4]. Each corner's memory follows the smooth impact memory of docs/model.md §5
(``_impact_memory``) with its own penetration: ṁ_k = w(δ_k) [δ̈_k + k_m (δ̇_k − m_k)], δ̈_k exact
(second derivative of the gap function along the motion).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..contact._base import ContactKinematics
from ..model._translational_clearance import CORNER_NAMES, TranslationalClearanceJoint
from . import _translational_geometry as geometry
from ._clearance import solve_affine
from ._impact_memory import freeze_weight, impact_velocity, memory, memory_relaxation
from ._outputs import JointOutputs

Index = Callable[[str], "int | None"]


class CornerKinematics(eqx.Module):
    """Kinematics of the four corners of one translational clearance joint at an instant.

    Attributes:
        corners: corner positions r_k (4, 2), m.
        penetration: δ_k (4,), m (negative: the corner is off its face).
        penetration_rate: δ̇_k (4,), m/s.
        slip_velocity: v_T,k (4,), m/s.
        tilt: θ, rad. offset: lateral offset of the slider centre, m.
    """

    corners: Float[Array, "4 2"]
    penetration: Float[Array, " 4"]
    penetration_rate: Float[Array, " 4"]
    slip_velocity: Float[Array, " 4"]
    tilt: Float[Array, ""]
    offset: Float[Array, ""]


class CornerForces(eqx.Module):
    """Corner forces of one translational clearance joint at an instant.

    Attributes:
        normal_force: F_N,k >= 0 (4,), N (pushes corner k back into the guide).
        friction_force: the friction law's force along the guide axis t (4,), N.
        tangential_force: friction plus the contact law's own tangential part (4,), N.
        force_on_slider: f_k (4, 2) global components, N; the guide gets −f_k.
    """

    normal_force: Float[Array, " 4"]
    friction_force: Float[Array, " 4"]
    tangential_force: Float[Array, " 4"]
    force_on_slider: Float[Array, "4 2"]


class TranslationalClearanceOutputs(JointOutputs):
    """Per-instant outputs of one translational clearance joint (``Trajectory.clearance[name]``).

    Mapping access as ``ClearanceOutputs`` (``out["tilt"]``, ``out.keys()``). Per-corner outputs
    have a trailing axis of 4 corners in ``CORNER_NAMES`` order. ``penetration`` and
    ``normal_force`` are the largest over the corners, so that contact modes, ensembles and the
    peak statistics treat the joint like a revolute clearance joint.

    Attributes:
        offset: lateral offset y of the slider centre from the guide line, m.
        tilt: slider angle to the guide θ, rad.
        penetration: max_k δ_k, m. normal_force: max_k F_N,k, N.
        corner_penetration: δ_k (4,), m. corner_penetration_rate: δ̇_k (4,), m/s.
        corner_normal_force: F_N,k (4,), N. corner_friction_force: (4,), N.
        corner_slip_velocity: v_T,k (4,), m/s. corner_impact_velocity: m_k (4,), m/s.
        corner_friction_state: the friction law's first state per corner (LuGre z, m) or ``None``.
    """

    offset: Float[Array, "*shape"]
    tilt: Float[Array, "*shape"]
    penetration: Float[Array, "*shape"]
    normal_force: Float[Array, "*shape"]
    corner_penetration: Float[Array, "*shape 4"]
    corner_penetration_rate: Float[Array, "*shape 4"]
    corner_normal_force: Float[Array, "*shape 4"]
    corner_friction_force: Float[Array, "*shape 4"]
    corner_slip_velocity: Float[Array, "*shape 4"]
    corner_impact_velocity: Float[Array, "*shape 4"]
    corner_friction_state: Float[Array, "*shape 4"] | None = None

    kind = "translational clearance joint"


CORNERS = len(CORNER_NAMES)


# --- gathering ----------------------------------------------------------------------------------
def body_indices(joint: TranslationalClearanceJoint, index: Index):
    """(guide, slider) body coordinate indices (``None`` for ground)."""
    return index(joint.guide_body), index(joint.slider_body)


def _body(x, i):
    return jnp.zeros(3, dtype=x.dtype) if i is None else x[3 * i : 3 * i + 3]


def _gather(indices, q, qd):
    """(qg, qdg, qs, qds)."""
    ig, is_ = indices
    return _body(q, ig), _body(qd, ig), _body(q, is_), _body(qd, is_)


def _split(joint, state):
    """(memories (4,), friction states (4, s))."""
    return state[:CORNERS], jnp.reshape(state[CORNERS:], (CORNERS, joint.friction_law.num_states))


# --- kinematics and forces -----------------------------------------------------------------------
def local_kinematics(joint, qg, qdg, qs, qds) -> CornerKinematics:
    """``CornerKinematics`` from the guide's and slider's coordinates and velocities."""
    corners = geometry.corner_positions(joint, qs)
    pen, rate = geometry.penetration_rates(joint, qs, qds, qg, qdg)
    return CornerKinematics(
        corners=corners,
        penetration=pen,
        penetration_rate=rate,
        slip_velocity=geometry.slip_velocities(joint, corners, qs, qds, qg, qdg),
        tilt=geometry.tilt(joint, qs, qg),
        offset=geometry.lateral_offset(joint, qs, qg),
    )


def kinematics(joint, index: Index, q, qd) -> CornerKinematics:
    """Corner positions, penetrations, rates and slip velocities (docs/model.md §2c)."""
    return local_kinematics(joint, *_gather(body_indices(joint, index), q, qd))


def corner_forces(joint, qg, k: CornerKinematics, state) -> CornerForces:
    """Normal and friction forces of the four corners from their kinematics and the state."""
    memories, friction_states = _split(joint, state)
    velocity = impact_velocity(
        memory(memories, k.penetration_rate, joint.memory_offset), joint.smoothing
    )
    geometry_ = joint.contact_geometry

    def one(pen, rate, v_imp, slip, z):
        kin = ContactKinematics(
            penetration=pen, penetration_rate=rate, impact_velocity=v_imp, tangential_rate=slip
        )
        normal, law_tangential = joint.contact_law(kin, geometry_, joint.smoothing)
        friction = joint.friction_law.force(slip, normal, z, joint.smoothing)
        return normal, friction, friction + law_tangential

    normal, friction, tangential = jax.vmap(one)(
        k.penetration, k.penetration_rate, velocity, k.slip_velocity, friction_states
    )
    return CornerForces(
        normal_force=normal,
        friction_force=friction,
        tangential_force=tangential,
        force_on_slider=geometry.corner_force_vectors(joint, qg, normal, tangential),
    )


def contact_forces(joint, index: Index, q, qd, state) -> tuple[CornerKinematics, CornerForces]:
    """(kinematics, forces) of the joint at (q, q̇) with internal state ``state``."""
    qg, qdg, qs, qds = _gather(body_indices(joint, index), q, qd)
    k = local_kinematics(joint, qg, qdg, qs, qds)
    return k, corner_forces(joint, qg, k, state)


def _stiff_rate(joint, k: CornerKinematics, state):
    """Stiff parts: each corner's memory relaxation and the friction law's stiff part."""
    memories, friction_states = _split(joint, state)
    m_dot = memory_relaxation(
        memories, k.penetration, k.penetration_rate, joint.smoothing, joint.memory_offset
    )
    z_dot = jax.vmap(lambda v, z: joint.friction_law.stiff_state_derivative(v, z, joint.smoothing))(
        k.slip_velocity, friction_states
    )
    return jnp.concatenate([m_dot, jnp.reshape(z_dot, (-1,))])


def solve_stiff_state(joint, k: CornerKinematics, partial, gamma_h):
    """(s, f_I(s)) solving s = P + γh f_I(s) (f_I affine and diagonal in s, see
    ``_clearance.solve_affine``)."""
    return solve_affine(lambda s: _stiff_rate(joint, k, s), partial, gamma_h)


def force_and_cache(joint, index: Index, q, qd, state, gamma_h=None):
    """(Q contribution (size of q), cache (``CornerKinematics``, ``CornerForces``), stage).

    ``gamma_h``: an implicit IMEX stage, as in ``_clearance.local_force_and_cache``.
    """
    ig, is_ = body_indices(joint, index)
    qg, qdg, qs, qds = _gather((ig, is_), q, qd)
    k = local_kinematics(joint, qg, qdg, qs, qds)
    stage = None if gamma_h is None else solve_stiff_state(joint, k, state, gamma_h)
    if stage is not None:
        state = stage[0]
    f = corner_forces(joint, qg, k, state)
    force = jnp.zeros_like(q)
    if is_ is not None:
        force = force.at[3 * is_ : 3 * is_ + 3].add(
            geometry.wrench(qs, k.corners, f.force_on_slider)
        )
    if ig is not None:
        force = force.at[3 * ig : 3 * ig + 3].add(
            geometry.wrench(qg, k.corners, -f.force_on_slider)
        )
    return force, (k, f), stage


def generalized_force(joint, index: Index, q, qd, state) -> Float[Array, " n"]:
    """Q contribution of the corner forces, same size as q."""
    return force_and_cache(joint, index, q, qd, state)[0]


# --- internal states ------------------------------------------------------------------------------
def initial_state(joint, index: Index, q, qd) -> Float[Array, " s"]:
    """[memories, friction states] at the start: m_k = δ̇_k (u_k = 0 in offset form)."""
    rate = kinematics(joint, index, q, qd).penetration_rate
    m0 = jnp.zeros_like(rate) if joint.memory_offset else rate
    z0 = jnp.tile(joint.friction_law.initial_state(), CORNERS)
    return jnp.concatenate([m0, z0.astype(m0.dtype)])


def state_derivative_cached(joint, cache, index: Index, q, qd, qdd, state) -> Float[Array, " s"]:
    """Internal-state rates from the cache of ``force_and_cache``; ``qdd`` this evaluation's q̈."""
    k, f = cache
    ig, is_ = body_indices(joint, index)
    qg, qdg, qs, qds = _gather((ig, is_), q, qd)
    accel = geometry.penetration_accelerations(
        joint, qs, qds, _body(qdd, is_), qg, qdg, _body(qdd, ig)
    )
    memories, friction_states = _split(joint, state)
    w = freeze_weight(k.penetration, joint.smoothing)
    k_m = joint.smoothing.memory_rate
    if joint.memory_offset:
        m_dot = (w - 1.0) * accel - w * k_m * memories
    else:
        m_dot = w * (accel + k_m * (k.penetration_rate - memories))
    z_dot = jax.vmap(lambda v, n, z: joint.friction_law.state_derivative(v, n, z, joint.smoothing))(
        k.slip_velocity, f.normal_force, friction_states
    )
    return jnp.concatenate([m_dot, jnp.reshape(z_dot, (-1,))])


def stiff_state_derivative(joint, index: Index, q, qd, state) -> Float[Array, " s"]:
    """Stiff parts of the state rate (memory relaxations, friction), from kinematics only."""
    return _stiff_rate(joint, kinematics(joint, index, q, qd), state)


def memory_shift(joint, index: Index, q, qd) -> Float[Array, " 4"]:
    """δ̇_k: the shift between the memory forms on the joint's memory rows (m = u + δ̇)."""
    return kinematics(joint, index, q, qd).penetration_rate


# --- assembly and outputs -------------------------------------------------------------------------
ASSEMBLY_EQUATIONS = 2
"""Rows a translational clearance joint adds to the assembly constraints."""


def assembly_constraint(joint, index: Index, q, t) -> Float[Array, "2"]:
    """Assembly rows: tilt and lateral offset at their initial values (the ideal joint's Φ, shifted)."""
    qg = _body(q, index(joint.guide_body))
    qs = _body(q, index(joint.slider_body))
    return jnp.stack(
        [
            geometry.tilt(joint, qs, qg) - joint.initial_tilt,
            geometry.lateral_offset(joint, qs, qg) - joint.initial_offset,
        ]
    )


def outputs(joint, index: Index, q, qd, state) -> TranslationalClearanceOutputs:
    """Per-instant outputs: offset, tilt, corner penetrations, forces, slips, memories."""
    k, f = contact_forces(joint, index, q, qd, state)
    memories, friction_states = _split(joint, state)
    return TranslationalClearanceOutputs(
        offset=k.offset,
        tilt=k.tilt,
        penetration=jnp.max(k.penetration),
        normal_force=jnp.max(f.normal_force),
        corner_penetration=k.penetration,
        corner_penetration_rate=k.penetration_rate,
        corner_normal_force=f.normal_force,
        corner_friction_force=f.friction_force,
        corner_slip_velocity=k.slip_velocity,
        corner_impact_velocity=memory(memories, k.penetration_rate, joint.memory_offset),
        corner_friction_state=friction_states[:, 0] if joint.friction_law.num_states else None,
    )
