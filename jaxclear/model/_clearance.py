"""Revolute clearance joint (MODEL.md §2): a pin (journal) in a hole (bearing) with contact forces.

A ``ClearanceJoint`` takes the place of an ideal ``RevoluteJoint``: instead of two constraint
equations it adds two degrees of freedom and a contact force element. Its internal states (the
impact-velocity memory m and the friction law's states, e.g. LuGre z) live in the integrator state.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._checks import check_finite, check_positive, check_shape, is_concrete
from .._errors import ModelError
from .._smooth import safe_norm
from ..contact._base import AbstractContactLaw, ContactGeometry, ContactKinematics, Smoothing
from ..dynamics._impact_memory import impact_velocity, memory, memory_offset_rate, memory_rate, memory_relaxation
from ..dynamics._kinematics import dot2, point_position, point_velocity
from ..friction._base import AbstractFrictionLaw
from ._forces import AbstractForceElement


def _array(x):
    return jnp.asarray(x, dtype=float)


def _default_contact():
    from ..contact import Hybrid

    return Hybrid()


def _default_friction():
    from ..friction import LuGre

    return LuGre()


def _perp(v):
    return jnp.stack([-v[1], v[0]])


class ClearanceJoint(AbstractForceElement):
    """A revolute joint with radial clearance c = R_B − R_J.

    The bearing (hole, radius R_B) is on ``bearing_body`` at ``bearing_point``; the journal (pin,
    radius R_J) on ``journal_body`` at ``journal_point``. Eccentricity e = r_journal − r_bearing;
    penetration δ = ‖e‖ − c; contact force on the journal f = −F_N n + F_T t applied at
    Q_II = r_II + R_J n, the opposite on the bearing at Q_I = r_I + R_B n (MODEL.md §2).

    Attributes:
        name: label used in outputs (static).
        bearing_body, journal_body: body names (static; ``"ground"`` allowed).
        bearing_point, journal_point: local joint points, m.
        geometry: radii, pin length and materials (``ContactGeometry``).
        contact_law: normal contact law (default: the paper's hybrid L-N + EFM law).
        friction_law: friction law (default: LuGre).
        smoothing: regularisation widths (``Smoothing``).
        initial_eccentricity: journal offset at assembly (global components), m; default centred.
        memory_offset: carry the impact memory as u = m − δ̇ instead of m (static; set inside the
            solve by ``lawson-tsit5`` through ``Mechanism.with_memory_offset``, see
            ``dynamics._impact_memory``).
    """

    name: str = eqx.field(static=True)
    bearing_body: str = eqx.field(static=True)
    bearing_point: Float[Array, "2"] = eqx.field(converter=_array)
    journal_body: str = eqx.field(static=True)
    journal_point: Float[Array, "2"] = eqx.field(converter=_array)
    geometry: ContactGeometry = eqx.field(default_factory=lambda: ContactGeometry(0.01, 0.0095))
    contact_law: AbstractContactLaw = eqx.field(default_factory=_default_contact)
    friction_law: AbstractFrictionLaw = eqx.field(default_factory=_default_friction)
    smoothing: Smoothing = eqx.field(default_factory=Smoothing)
    initial_eccentricity: Float[Array, "2"] = eqx.field(converter=_array, default=(0.0, 0.0))
    memory_offset: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        owner = f"ClearanceJoint {self.name!r}"
        for attr in ("bearing_point", "journal_point", "initial_eccentricity"):
            check_shape(owner, attr, getattr(self, attr), (2,))
            check_finite(owner, attr, getattr(self, attr))
        g = self.geometry
        check_positive(owner, "bearing_radius", g.bearing_radius, "m")
        check_positive(owner, "journal_radius", g.journal_radius, "m")
        check_positive(owner, "length (pin length h)", g.length, "m")
        check_positive(owner, "bearing_young", g.bearing_young, "Pa")
        check_positive(owner, "journal_young", g.journal_young, "Pa")
        for attr in ("bearing_poisson", "journal_poisson"):
            nu = getattr(g, attr)
            check_finite(owner, attr, nu)
            if is_concrete(nu) and not (0.0 < float(nu) < 0.5):
                raise ModelError(f"{owner}: {attr} must be in (0, 0.5), got {float(nu)}; steel is 0.3.")
        if is_concrete(g.bearing_radius) and is_concrete(g.journal_radius):
            if not float(g.journal_radius) < float(g.bearing_radius):
                raise ModelError(
                    f"{owner}: journal_radius ({float(g.journal_radius)} m) must be smaller than bearing_radius "
                    f"({float(g.bearing_radius)} m); the clearance c = R_B - R_J must be positive."
                )
        s = self.smoothing
        for attr in ("penetration_width", "velocity_width", "memory_width", "memory_rate", "min_impact_velocity", "force_width"):
            check_positive(owner, f"smoothing.{attr}", getattr(s, attr))
        if not isinstance(self.contact_law, AbstractContactLaw):
            raise TypeError(f"{owner}: contact_law must be an AbstractContactLaw, got {type(self.contact_law).__name__}.")
        if not isinstance(self.friction_law, AbstractFrictionLaw):
            raise TypeError(f"{owner}: friction_law must be an AbstractFrictionLaw, got {type(self.friction_law).__name__}.")
        if all(is_concrete(x) for x in (self.initial_eccentricity, g.bearing_radius, g.journal_radius)):
            if np.linalg.norm(np.asarray(self.initial_eccentricity)) > float(g.bearing_radius - g.journal_radius):
                raise ModelError(f"{owner}: initial_eccentricity lies outside the clearance circle.")

    @classmethod
    def replacing(
        cls, joint, clearance: float | None = None, journal_body: str | None = None, **kwargs
    ) -> "ClearanceJoint":
        """A clearance joint at the place of an ideal ``RevoluteJoint``.

        Args:
            joint: the ``RevoluteJoint`` to replace (name, bodies and points are taken from it).
            clearance: radial clearance c, m; sets the journal radius to R_B − c (R_B from
                ``geometry`` or 10 mm).
            journal_body: which of the joint's two bodies carries the pin (journal); the other
                carries the hole (bearing). Default ``joint.body_j`` (bearing on ``joint.body_i``).
            **kwargs: other ``ClearanceJoint`` fields (geometry, contact_law, friction_law, ...).

        Returns:
            The clearance joint, named like ``joint``.

        Raises:
            ModelError: ``journal_body`` is not one of the joint's two bodies, or ``clearance`` is
                not positive and smaller than the bearing radius.
        """
        owner = f"ClearanceJoint {joint.name!r}"
        if journal_body is None:
            journal_body = joint.body_j
        if journal_body not in (joint.body_i, joint.body_j):
            raise ModelError(
                f"{owner}: journal_body={journal_body!r} is not a body of joint {joint.name!r}; "
                f"choose {joint.body_i!r} or {joint.body_j!r}."
            )
        geometry = kwargs.pop("geometry", None) or ContactGeometry(0.01, 0.0095)
        if clearance is not None:
            if is_concrete(clearance) and not float(clearance) > 0:
                raise ModelError(f"{owner}: clearance must be > 0 m, got {clearance}.")
            geometry = eqx.tree_at(lambda g: g.journal_radius, geometry, geometry.bearing_radius - clearance)
            if is_concrete(geometry.journal_radius) and not float(geometry.journal_radius) > 0:
                raise ModelError(f"{owner}: clearance {clearance} m is not smaller than the bearing radius.")
        if journal_body == joint.body_j:
            bearing = (joint.body_i, joint.point_i)
            journal = (joint.body_j, joint.point_j)
        else:
            bearing = (joint.body_j, joint.point_j)
            journal = (joint.body_i, joint.point_i)
        return cls(joint.name, *bearing, *journal, geometry=geometry, **kwargs)

    # --- layout of the internal state: [memory m (or u = m − δ̇ if memory_offset), friction states]
    @property
    def num_states(self) -> int:
        return 1 + self.friction_law.num_states

    memory_state_rows = (0,)  # which internal states hold the impact memory (Mechanism.memory_rows)

    def initial_state(self, index, q, qd):
        rate = self.kinematics(index, q, qd)["penetration_rate"]  # the memory starts at the initial δ̇
        m0 = jnp.zeros_like(rate) if self.memory_offset else rate
        return jnp.concatenate([jnp.reshape(m0, (1,)), self.friction_law.initial_state()])

    def assembly_constraint(self, index, q, t):
        """Assembly rows: journal centre at bearing centre + initial eccentricity."""
        ri = point_position(q, index(self.bearing_body), self.bearing_point)
        rj = point_position(q, index(self.journal_body), self.journal_point)
        return rj - ri - self.initial_eccentricity

    # --- kinematics and forces ---------------------------------------------------------------
    # Every computation is written on the coordinates of the two joined bodies only ("local"):
    # qb, qdb (bearing body) and qj, qdj (journal body), 3-vectors (x, y, φ), zeros for ground.
    # The mechanism-level methods gather them from q; ``dynamics._batched`` vmaps the local
    # methods over several joints of the same kind, so three joints cost the kernels of one.
    def body_indices(self, index) -> tuple[int | None, int | None]:
        """(bearing, journal) body coordinate indices (``None`` for ground)."""
        return index(self.bearing_body), index(self.journal_body)

    def kinematics(self, index, q, qd) -> dict:
        """Eccentricity, penetration, rates, contact points and slip velocity (MODEL.md §2)."""
        return self.local_kinematics(*_gather(self.body_indices(index), q, qd))

    def local_kinematics(self, qb, qdb, qj, qdj) -> dict:
        """``kinematics`` from the two bodies' coordinates and velocities (3-vectors each)."""
        rb = point_position(qb, 0, self.bearing_point)
        rj = point_position(qj, 0, self.journal_point)
        vb = point_velocity(qb, qdb, 0, self.bearing_point)
        vj = point_velocity(qj, qdj, 0, self.journal_point)
        ecc = rj - rb
        e = safe_norm(ecc)
        nonzero = e > 0
        n = jnp.where(nonzero, ecc / jnp.where(nonzero, e, 1.0), jnp.array([1.0, 0.0]))
        t = _perp(n)
        de = vj - vb
        g = self.geometry
        pb = rb + g.bearing_radius * n
        pj = rj + g.journal_radius * n
        slip = dot2(t, _contact_point_velocity(qj, qdj, pj) - _contact_point_velocity(qb, qdb, pb))
        return dict(
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

    def contact_forces(self, index, q, qd, state) -> tuple[dict, dict]:
        """(kinematics, forces): forces has normal_force F_N, friction_force F_T (along t on the
        journal, includes the law's own tangential part) and the global force on the journal."""
        return self.local_contact_forces(*_gather(self.body_indices(index), q, qd), state)

    def local_contact_forces(self, qb, qdb, qj, qdj, state) -> tuple[dict, dict]:
        """``contact_forces`` from the two bodies' coordinates and velocities."""
        k = self.local_kinematics(qb, qdb, qj, qdj)
        kin = ContactKinematics(
            penetration=k["penetration"],
            penetration_rate=k["penetration_rate"],
            impact_velocity=impact_velocity(memory(state[0], k["penetration_rate"], self.memory_offset), self.smoothing),
            tangential_rate=k["tangential_rate"],
        )
        normal, law_tangential = self.contact_law(kin, self.geometry, self.smoothing)
        friction = self.friction_law.force(k["slip_velocity"], normal, state[1:], self.smoothing)
        tangential = friction + law_tangential
        on_journal = -normal * k["normal"] + tangential * k["tangent"]
        return k, dict(normal_force=normal, friction_force=friction, tangential_force=tangential, force_on_journal=on_journal)

    def generalized_force(self, index, q, qd, t, state):
        return self.force_and_cache(index, q, qd, t, state)[0]

    def force_and_cache(self, index, q, qd, t, state):
        ib, ij = self.body_indices(index)
        on_bearing, on_journal, cache = self.local_force_and_cache(*_gather((ib, ij), q, qd), state)
        force = jnp.zeros_like(q)
        for i, f in ((ib, on_bearing), (ij, on_journal)):
            if i is not None:
                force = force.at[3 * i : 3 * i + 3].add(f)
        return force, cache

    def local_force_and_cache(self, qb, qdb, qj, qdj, state):
        """(generalised force on the bearing body (3,), on the journal body (3,), cache)."""
        k, f = self.local_contact_forces(qb, qdb, qj, qdj, state)
        fj = f["force_on_journal"]
        on_journal = _body_wrench(qj, k["journal_contact_point"], fj)
        on_bearing = _body_wrench(qb, k["bearing_contact_point"], -fj)
        return on_bearing, on_journal, (k, f)

    def state_derivative(self, index, q, qd, qdd, t, state):
        return self.state_derivative_cached(self.contact_forces(index, q, qd, state), index, q, qd, qdd, t, state)

    def state_derivative_cached(self, cache, index, q, qd, qdd, t, state):
        ib, ij = self.body_indices(index)
        return self.local_state_derivative(cache, _body(qdd, ib), _body(qdd, ij), *_gather((ib, ij), q, qd), state)

    def local_state_derivative(self, cache, qddb, qddj, qb, qdb, qj, qdj, state):
        """Internal-state rates (ṁ, friction states) from the cache of ``local_force_and_cache``."""
        k, f = cache
        accel = _point_acceleration(qj, qdj, qddj, self.journal_point) - _point_acceleration(
            qb, qdb, qddb, self.bearing_point
        )
        normal_accel = dot2(k["normal"], accel)
        c = self.geometry.clearance
        if self.memory_offset:
            m_dot = memory_offset_rate(
                state[0], k["penetration"], k["eccentricity"], c, k["tangential_rate"], normal_accel, self.smoothing
            )
        else:
            m_dot = memory_rate(
                state[0], k["penetration"], k["penetration_rate"], k["eccentricity"], c, k["tangential_rate"],
                normal_accel, self.smoothing,
            )
        z_dot = self.friction_law.state_derivative(k["slip_velocity"], f["normal_force"], state[1:], self.smoothing)
        return jnp.concatenate([jnp.reshape(m_dot, (1,)), jnp.reshape(z_dot, (-1,))])

    def stiff_state_derivative(self, index, q, qd, t, state):
        """Stiff parts: memory relaxation k_m term and the friction law's stiff part (LuGre z).

        Kinematics only (no contact law): the implicit solve differentiates this function, so it
        is kept cheap; friction laws' stiff parts must not depend on the normal force.
        """
        return self.local_stiff_state_derivative(*_gather(self.body_indices(index), q, qd), state)

    def local_stiff_state_derivative(self, qb, qdb, qj, qdj, state):
        """``stiff_state_derivative`` from the two bodies' coordinates and velocities."""
        k = self.local_kinematics(qb, qdb, qj, qdj)
        m_dot = memory_relaxation(state[0], k["penetration"], k["penetration_rate"], self.smoothing, self.memory_offset)
        z_dot = self.friction_law.stiff_state_derivative(k["slip_velocity"], state[1:], self.smoothing)
        return jnp.concatenate([jnp.reshape(m_dot, (1,)), jnp.reshape(z_dot, (-1,))])

    def outputs(self, index, q, qd, qdd, t, state) -> dict:
        """Per-instant outputs: eccentricity components, penetration, forces, internal states."""
        k, f = self.contact_forces(index, q, qd, state)
        out = dict(
            ecc_x=k["eccentricity_vector"][0],
            ecc_y=k["eccentricity_vector"][1],
            penetration=k["penetration"],
            penetration_rate=k["penetration_rate"],
            normal_force=f["normal_force"],
            friction_force=f["friction_force"],
            tangential_force=f["tangential_force"],
            slip_velocity=k["slip_velocity"],
            impact_velocity=memory(state[0], k["penetration_rate"], self.memory_offset),
        )
        if self.friction_law.num_states:
            out["friction_state"] = state[1]
        return out


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
    return qdk[:2] + qdk[2] * _perp(point - qk[:2])


def _point_acceleration(qk, qdk, qddk, local):
    """r̈ + φ̈ B s' − φ̇² A s' of a body-fixed point."""
    s = point_position(qk, 0, local) - qk[:2]
    return qddk[:2] + qddk[2] * _perp(s) - qdk[2] ** 2 * s
