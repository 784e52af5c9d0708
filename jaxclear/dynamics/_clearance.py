"""Physics of a revolute clearance joint (docs/model.md §2): kinematics, contact forces, internal states.

The joint's parameters are data (``jaxclear.model.ClearanceJoint``); this module computes with
them. Every computation is written on the coordinates of the two joined bodies only ("local"):
qb, qdb (bearing body) and qj, qdj (journal body), 3-vectors (x, y, φ), zeros for ground. The
mechanism-level functions gather them from q; ``dynamics._batched`` vmaps the local functions over
several joints of the same kind, so three joints cost the kernels of one.

Internal state of a joint: [impact memory m (or u = m − δ̇ when ``joint.memory_offset``), friction
law states] (``dynamics._impact_memory``).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._geometry import dot2, perp, point_position, point_velocity
from .._core._smooth import safe_norm
from ..contact._base import ContactKinematics
from ..contact._lubrication import film_force
from ..model._clearance import ClearanceJoint
from ._impact_memory import (
    impact_velocity,
    memory,
    memory_offset_rate,
    memory_rate,
    memory_relaxation,
)
from ._outputs import JointOutputs

Index = Callable[[str], "int | None"]


class JointKinematics(eqx.Module):
    """Kinematics of one clearance joint at an instant (docs/model.md §2).

    Attributes:
        eccentricity_vector: e = r_journal − r_bearing (global components), m.
        eccentricity: ‖e‖ (safe norm, finite gradient at 0), m.
        normal: n = e/‖e‖ ((1, 0) for a centred journal).
        tangent: t = n turned by +90°.
        penetration: δ = ‖e‖ − c, m (negative in free flight).
        penetration_rate: δ̇ = nᵀė, m/s.
        tangential_rate: tᵀė, m/s.
        bearing_contact_point: Q_I = r_bearing + R_B n, m.
        journal_contact_point: Q_II = r_journal + R_J n, m.
        slip_velocity: v_T = tᵀ(ṙ(Q_II) − ṙ(Q_I)) of the material points at the contact points, m/s.
    """

    eccentricity_vector: Float[Array, "2"]
    eccentricity: Float[Array, ""]
    normal: Float[Array, "2"]
    tangent: Float[Array, "2"]
    penetration: Float[Array, ""]
    penetration_rate: Float[Array, ""]
    tangential_rate: Float[Array, ""]
    bearing_contact_point: Float[Array, "2"]
    journal_contact_point: Float[Array, "2"]
    slip_velocity: Float[Array, ""]


class ContactForces(eqx.Module):
    """Contact forces of one clearance joint at an instant.

    Attributes:
        normal_force: F_N >= 0, N (pushes the journal towards the bearing centre).
        friction_force: the friction law's force on the journal along t, N.
        tangential_force: F_T = friction plus the contact law's own tangential part, N.
        force_on_journal: −F_N n + F_T t (global components), N; the bearing gets the opposite.
        film_force: a lubricated joint's hydrodynamic force on the journal (global components),
            N, acting at the journal centre (the bearing gets the opposite at the same point);
            ``None`` for a dry joint.
        film_torque: a lubricated joint's Petroff torque on the journal, N m (the bearing gets
            the opposite); ``None`` for a dry joint.
    """

    normal_force: Float[Array, ""]
    friction_force: Float[Array, ""]
    tangential_force: Float[Array, ""]
    force_on_journal: Float[Array, "2"]
    film_force: Float[Array, "2"] | None = None
    film_torque: Float[Array, ""] | None = None


class ClearanceOutputs(JointOutputs):
    """Per-instant outputs of one clearance joint (``Trajectory.clearance[name]``).

    Attribute access (``out.normal_force``) and mapping access (``out["normal_force"]``,
    ``out.keys()``, ``out.items()``, ``"friction_state" in out``) both work; the mapping holds the
    fields that are present, in the order below (``friction_state`` only when the friction law has
    internal states). A saved trajectory adds a leading time axis (and a batch axis for batches).

    Attributes:
        ecc_x, ecc_y: eccentricity components, m.
        penetration: δ, m. penetration_rate: δ̇, m/s.
        normal_force: F_N, N. friction_force: friction law's force along t, N.
        tangential_force: F_T, N. slip_velocity: v_T, m/s.
        impact_velocity: the memory m of the normal approach speed, m/s.
        friction_state: the friction law's first internal state (LuGre z, m), or ``None``.
        film_force_x, film_force_y: a lubricated joint's film force on the journal, N, or ``None``.
    """

    ecc_x: Float[Array, "*shape"]
    ecc_y: Float[Array, "*shape"]
    penetration: Float[Array, "*shape"]
    penetration_rate: Float[Array, "*shape"]
    normal_force: Float[Array, "*shape"]
    friction_force: Float[Array, "*shape"]
    tangential_force: Float[Array, "*shape"]
    slip_velocity: Float[Array, "*shape"]
    impact_velocity: Float[Array, "*shape"]
    friction_state: Float[Array, "*shape"] | None = None
    film_force_x: Float[Array, "*shape"] | None = None
    film_force_y: Float[Array, "*shape"] | None = None

    kind = "clearance joint"


# --- gathering the two bodies' coordinates ----------------------------------------------------------
def body_indices(joint: ClearanceJoint, index: Index) -> tuple[int | None, int | None]:
    """(bearing, journal) body coordinate indices (``None`` for ground)."""
    return index(joint.bearing_body), index(joint.journal_body)


def _body(x, i):
    """Coordinates (or velocities, accelerations) of body ``i`` as a 3-vector; zeros for ground."""
    return jnp.zeros(3, dtype=x.dtype) if i is None else x[3 * i : 3 * i + 3]


def _gather(indices, q, qd):
    """(qb, qdb, qj, qdj) for body indices (bearing, journal)."""
    ib, ij = indices
    return _body(q, ib), _body(qd, ib), _body(q, ij), _body(qd, ij)


def _body_wrench(qk, point, force):
    """Generalised force (F_x, F_y, (r_P − r_k) × F) on a body with coordinates ``qk``."""
    d = point - qk[:2]
    return jnp.stack([force[0], force[1], d[0] * force[1] - d[1] * force[0]])


def _contact_point_velocity(qk, qdk, point):
    """Velocity of the body-fixed material point currently at global ``point`` (zero for ground)."""
    return qdk[:2] + qdk[2] * perp(point - qk[:2])


def _point_acceleration(qk, qdk, qddk, local):
    """r̈ + φ̈ B s' − φ̇² A s' of a body-fixed point."""
    s = point_position(qk, 0, local) - qk[:2]
    return qddk[:2] + qddk[2] * perp(s) - qdk[2] ** 2 * s


# --- kinematics and forces ---------------------------------------------------------------------------
def local_kinematics(joint: ClearanceJoint, qb, qdb, qj, qdj) -> JointKinematics:
    """``kinematics`` from the two bodies' coordinates and velocities (3-vectors each)."""
    rb = point_position(qb, 0, joint.bearing_point)
    rj = point_position(qj, 0, joint.journal_point)
    vb = point_velocity(qb, qdb, 0, joint.bearing_point)
    vj = point_velocity(qj, qdj, 0, joint.journal_point)
    ecc = rj - rb
    e = safe_norm(ecc)
    nonzero = e > 0
    n = jnp.where(nonzero, ecc / jnp.where(nonzero, e, 1.0), jnp.array([1.0, 0.0]))
    t = perp(n)
    de = vj - vb
    g = joint.geometry
    pb = rb + g.bearing_radius * n
    pj = rj + g.journal_radius * n
    slip = dot2(t, _contact_point_velocity(qj, qdj, pj) - _contact_point_velocity(qb, qdb, pb))
    return JointKinematics(
        eccentricity_vector=ecc,
        eccentricity=e,
        normal=n,
        tangent=t,
        penetration=e - g.clearance,
        penetration_rate=dot2(n, de),
        tangential_rate=dot2(t, de),
        bearing_contact_point=pb,
        journal_contact_point=pj,
        slip_velocity=slip,
    )


def kinematics(joint: ClearanceJoint, index: Index, q, qd) -> JointKinematics:
    """Eccentricity, penetration, rates, contact points and slip velocity (docs/model.md §2)."""
    return local_kinematics(joint, *_gather(body_indices(joint, index), q, qd))


def local_contact_forces(
    joint: ClearanceJoint, qb, qdb, qj, qdj, state, k: JointKinematics | None = None
) -> tuple[JointKinematics, ContactForces]:
    """``contact_forces`` from the two bodies' coordinates and velocities (``k``: their
    kinematics if already computed)."""
    if k is None:
        k = local_kinematics(joint, qb, qdb, qj, qdj)
    kin = ContactKinematics(
        penetration=k.penetration,
        penetration_rate=k.penetration_rate,
        impact_velocity=impact_velocity(
            memory(state[0], k.penetration_rate, joint.memory_offset), joint.smoothing
        ),
        tangential_rate=k.tangential_rate,
    )
    normal, law_tangential = joint.contact_law(kin, joint.geometry, joint.smoothing)
    friction = joint.friction_law.force(k.slip_velocity, normal, state[1:], joint.smoothing)
    tangential = friction + law_tangential
    on_journal = -normal * k.normal + tangential * k.tangent
    film, torque = None, None
    if joint.lubrication is not None:
        # the film (docs/model.md §3b); the dry law above is exactly zero until the wall, where
        # the film's blend weight has reached 0 (ε₀ + Δ <= 1), so it needs no weight of its own
        rate = k.penetration_rate * k.normal + k.tangential_rate * k.tangent
        f = film_force(
            joint.lubrication,
            k.eccentricity_vector,
            rate,
            qdj[2],
            qdb[2],
            joint.geometry.journal_radius,
            joint.geometry.clearance,
        )
        film, torque = f.force, f.torque
    return k, ContactForces(
        normal_force=normal,
        friction_force=friction,
        tangential_force=tangential,
        force_on_journal=on_journal,
        film_force=film,
        film_torque=torque,
    )


def contact_forces(
    joint: ClearanceJoint, index: Index, q, qd, state
) -> tuple[JointKinematics, ContactForces]:
    """(kinematics, forces) of the joint at (q, q̇) with internal state ``state``."""
    return local_contact_forces(joint, *_gather(body_indices(joint, index), q, qd), state)


def local_force_and_cache(joint: ClearanceJoint, qb, qdb, qj, qdj, state, gamma_h=None):
    """(generalised force on the bearing body (3,), on the journal body (3,), cache, stage).

    The cache, (``JointKinematics``, ``ContactForces``), goes to ``local_state_derivative``.

    With ``gamma_h`` (an implicit stage of an IMEX method, ``dynamics._equations.implicit_stage``)
    ``state`` is the stage's explicit part P and the internal state used is the solution s of
    s = P + γh f_I(s) (closed form: the stiff part is affine and diagonal in the state, with
    coefficients from this kinematics); ``stage`` is then (s, f_I(s)), else ``None``.
    """
    k = local_kinematics(joint, qb, qdb, qj, qdj)
    stage = None if gamma_h is None else solve_stiff_state(joint, k, state, gamma_h)
    if stage is not None:
        state = stage[0]
    k, f = local_contact_forces(joint, qb, qdb, qj, qdj, state, k)
    fj = f.force_on_journal
    on_journal = _body_wrench(qj, k.journal_contact_point, fj)
    on_bearing = _body_wrench(qb, k.bearing_contact_point, -fj)
    if f.film_force is not None:
        # film force at the journal centre, its reaction on the bearing at the same point (no net
        # moment from the pair); Petroff torque on the journal, its opposite on the bearing
        centre = point_position(qj, 0, joint.journal_point)
        couple = jnp.stack([0.0, 0.0, f.film_torque])
        on_journal = on_journal + _body_wrench(qj, centre, f.film_force) + couple
        on_bearing = on_bearing + _body_wrench(qb, centre, -f.film_force) - couple
    return on_bearing, on_journal, (k, f), stage


def force_and_cache(joint: ClearanceJoint, index: Index, q, qd, state, gamma_h=None):
    """(Q contribution of the joint (size of q), cache for ``state_derivative_cached``, stage);
    ``gamma_h`` and the stage: see ``local_force_and_cache``."""
    ib, ij = body_indices(joint, index)
    on_bearing, on_journal, cache, stage = local_force_and_cache(
        joint, *_gather((ib, ij), q, qd), state, gamma_h
    )
    force = jnp.zeros_like(q)
    for i, f in ((ib, on_bearing), (ij, on_journal)):
        if i is not None:
            force = force.at[3 * i : 3 * i + 3].add(f)
    return force, cache, stage


def generalized_force(joint: ClearanceJoint, index: Index, q, qd, state) -> Float[Array, " n"]:
    """Q contribution of the contact forces, same size as q (N, N, N m per body)."""
    return force_and_cache(joint, index, q, qd, state)[0]


# --- internal states ---------------------------------------------------------------------------------
def initial_state(joint: ClearanceJoint, index: Index, q, qd) -> Float[Array, " s"]:
    """[memory, friction states] at the start.

    The memory starts at the initial δ̇, or at max(δ̇, v₀) where the joint's
    ``initial_impact_velocity`` v₀ is positive (a journal started on its wall: docs/model.md
    §5c); in offset form u = m − δ̇, i.e. 0 or max(0, v₀ − δ̇). v₀ = 0 gives
    exactly the initial δ̇ (``where``, so the default start is unchanged to the last bit).
    """
    rate = kinematics(joint, index, q, qd).penetration_rate
    v0 = joint.initial_impact_velocity
    if joint.memory_offset:
        m0 = jnp.where(v0 > 0, jnp.maximum(v0 - rate, 0.0), jnp.zeros_like(rate))
    else:
        m0 = jnp.where(v0 > 0, jnp.maximum(rate, v0), rate)
    return jnp.concatenate([jnp.reshape(m0, (1,)), joint.friction_law.initial_state()])


def local_state_derivative(joint: ClearanceJoint, cache, qddb, qddj, qb, qdb, qj, qdj, state):
    """Internal-state rates (ṁ, friction states) from the cache of ``local_force_and_cache``."""
    k, f = cache
    accel = _point_acceleration(qj, qdj, qddj, joint.journal_point) - _point_acceleration(
        qb, qdb, qddb, joint.bearing_point
    )
    normal_accel = dot2(k.normal, accel)
    c = joint.geometry.clearance
    if joint.memory_offset:
        m_dot = memory_offset_rate(
            state[0],
            k.penetration,
            k.eccentricity,
            c,
            k.tangential_rate,
            normal_accel,
            joint.smoothing,
        )
    else:
        m_dot = memory_rate(
            state[0],
            k.penetration,
            k.penetration_rate,
            k.eccentricity,
            c,
            k.tangential_rate,
            normal_accel,
            joint.smoothing,
        )
    z_dot = joint.friction_law.state_derivative(
        k.slip_velocity, f.normal_force, state[1:], joint.smoothing
    )
    return jnp.concatenate([jnp.reshape(m_dot, (1,)), jnp.reshape(z_dot, (-1,))])


def state_derivative_cached(
    joint: ClearanceJoint, cache, index: Index, q, qd, qdd, state
) -> Float[Array, " s"]:
    """``state_derivative`` reusing the cache of ``force_and_cache``."""
    ib, ij = body_indices(joint, index)
    return local_state_derivative(
        joint, cache, _body(qdd, ib), _body(qdd, ij), *_gather((ib, ij), q, qd), state
    )


def state_derivative(joint: ClearanceJoint, index: Index, q, qd, qdd, state) -> Float[Array, " s"]:
    """Time derivative of the internal state; ``qdd`` is this evaluation's acceleration."""
    return state_derivative_cached(
        joint, contact_forces(joint, index, q, qd, state), index, q, qd, qdd, state
    )


def _stiff_rate(joint: ClearanceJoint, k: JointKinematics, state):
    m_dot = memory_relaxation(
        state[0], k.penetration, k.penetration_rate, joint.smoothing, joint.memory_offset
    )
    z_dot = joint.friction_law.stiff_state_derivative(k.slip_velocity, state[1:], joint.smoothing)
    return jnp.concatenate([jnp.reshape(m_dot, (1,)), jnp.reshape(z_dot, (-1,))])


def solve_affine(rate, partial, gamma_h):
    """(s, rate(s)): the solution of s = P + γh rate(s), P = ``partial``, for a ``rate`` affine and
    diagonal in s (each entry depends on its own state only: ``tests/test_fast_paths.py`` checks
    the stiff parts): rate(s) = a + ℓ s with a, ℓ from one Jacobian–vector product at s = 0, so
    s = (P + γh a) / (1 − γh ℓ)."""
    zero = jnp.zeros_like(partial)
    a, slope = jax.jvp(rate, (zero,), (jnp.ones_like(partial),))
    state = (partial + gamma_h * a) / (1.0 - gamma_h * slope)
    return state, a + slope * state


def solve_stiff_state(joint: ClearanceJoint, k: JointKinematics, partial, gamma_h):
    """``solve_affine`` for the joint's internal state (memory, friction states), with the
    stiff part's coefficients from the kinematics ``k``."""
    return solve_affine(lambda s: _stiff_rate(joint, k, s), partial, gamma_h)


def local_stiff_state_derivative(joint: ClearanceJoint, qb, qdb, qj, qdj, state):
    """``stiff_state_derivative`` from the two bodies' coordinates and velocities."""
    return _stiff_rate(joint, local_kinematics(joint, qb, qdb, qj, qdj), state)


def stiff_state_derivative(joint: ClearanceJoint, index: Index, q, qd, state) -> Float[Array, " s"]:
    """Stiff parts: memory relaxation k_m term and the friction law's stiff part (LuGre z).

    Kinematics only (no contact law): the implicit solve differentiates this function, so it
    is kept cheap; friction laws' stiff parts must not depend on the normal force.
    """
    return local_stiff_state_derivative(joint, *_gather(body_indices(joint, index), q, qd), state)


# --- assembly and outputs ----------------------------------------------------------------------------
ASSEMBLY_EQUATIONS = 2
"""Rows a clearance joint adds to the assembly constraints (``assembly_constraint``)."""


def assembly_constraint(joint: ClearanceJoint, index: Index, q, t) -> Float[Array, "2"]:
    """Assembly rows: journal centre at bearing centre + initial eccentricity."""
    ri = point_position(q, index(joint.bearing_body), joint.bearing_point)
    rj = point_position(q, index(joint.journal_body), joint.journal_point)
    return rj - ri - joint.initial_eccentricity


def outputs(joint: ClearanceJoint, index: Index, q, qd, state) -> ClearanceOutputs:
    """Per-instant outputs: eccentricity components, penetration, forces, internal states."""
    k, f = contact_forces(joint, index, q, qd, state)
    return ClearanceOutputs(
        ecc_x=k.eccentricity_vector[0],
        ecc_y=k.eccentricity_vector[1],
        penetration=k.penetration,
        penetration_rate=k.penetration_rate,
        normal_force=f.normal_force,
        friction_force=f.friction_force,
        tangential_force=f.tangential_force,
        slip_velocity=k.slip_velocity,
        impact_velocity=memory(state[0], k.penetration_rate, joint.memory_offset),
        friction_state=state[1] if joint.friction_law.num_states else None,
        film_force_x=None if f.film_force is None else f.film_force[0],
        film_force_y=None if f.film_force is None else f.film_force[1],
    )
