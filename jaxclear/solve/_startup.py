"""Start-up of clearance joints: journals on their bearing walls instead of centred [ours].

docs/model.md §1 starts every journal centred in its bearing (eccentricity 0). A centred journal flies
free across the clearance and strikes the wall at the speed the load has built up meanwhile: a
start-up impact much harder than any in the running motion, which then dominates plots and peak
statistics. A journal that runs loaded sits on the side of the bearing the load pushes it to;
``wall_start`` puts it there at t0, so the run begins close to how a running joint is loaded.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..model import Mechanism, RevoluteJoint
from ._simulate import simulate

REACTION_HORIZON = 1e-7
"""s: the reaction at t0 is read from a solve of the ideal mechanism over this short span (its first
saved instant, at t0, is the assembled state; the span only has to be positive)."""


def ideal_mechanism(mechanism: Mechanism) -> Mechanism:
    """``mechanism`` with each clearance joint replaced by an ideal ``RevoluteJoint`` of the same name
    whose first body is the bearing body and second the journal body (at their joint points)."""
    replaced = tuple(
        RevoluteJoint(c.name, c.bearing_body, c.bearing_point, c.journal_body, c.journal_point)
        for c in mechanism.clearance_joints
    )
    return dataclasses.replace(
        mechanism, joints=(*mechanism.joints, *replaced), clearance_joints=()
    )


def wall_start(mechanism: Mechanism, t0: float = 0.0, *, num_points: int = 2) -> Mechanism:
    """Start each journal on its bearing wall, where the ideal joint's reaction pushes it.

    In the ideal mechanism (``ideal_mechanism``: each clearance joint made an ideal revolute joint
    between the same bodies and points, bearing body first) the joint transmits a force F from the
    journal to the bearing at t0. In a clearance joint the journal transmits force only by pressing
    on the wall, along the unit vector n from the bearing centre to the contact point, with
    F = F_N n (docs/model.md §2: the contact force on the bearing is +F_N n). So the journal starts at
    eccentricity e = c n, n = F/|F|: on the wall, not yet penetrating, with the ideal joint's
    velocities. A joint that carries no force at t0 (|F| = 0) stays centred.

    Args:
        mechanism: a ``Mechanism`` with clearance joints (unbatched, concrete values).
        t0: start time, s.
        num_points: output points of the short solve of the ideal mechanism that gives the
            reaction (only the first, at t0, is used). A solve compiles once per number of output
            points, so passing the number of a later ideal-joint solve of ``ideal_mechanism`` with
            the ``"fast"`` solver shares that compilation (``jaxclear run`` does this).

    Returns:
        The mechanism with each clearance joint's ``initial_eccentricity`` set to c n (global
        components, m).

    Raises:
        AssemblyError: the ideal mechanism cannot be assembled at t0.
    """
    if not mechanism.clearance_joints:
        return mechanism
    ideal = ideal_mechanism(mechanism)
    traj = simulate(ideal, t0 + REACTION_HORIZON, t0=t0, num_points=num_points, solver="fast")
    eccentricities = []
    for joint in mechanism.clearance_joints:
        force = np.asarray(traj.joint_force(joint.name))[0]  # journal body on bearing body, N
        magnitude = float(np.hypot(force[0], force[1]))
        clearance = joint.geometry.bearing_radius - joint.geometry.journal_radius
        direction = force / magnitude if magnitude > 0 else np.zeros(2)
        eccentricities.append(clearance * jnp.asarray(direction))
    return eqx.tree_at(
        lambda m: [c.initial_eccentricity for c in m.clearance_joints], mechanism, eccentricities
    )
