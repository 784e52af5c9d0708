"""Start-up of clearance joints: journals on their bearing walls instead of centred [ours].

docs/model.md §1 starts every journal centred in its bearing (eccentricity 0). A centred journal flies
free across the clearance and strikes the wall at the speed the load has built up meanwhile: a
start-up impact much harder than any in the running motion, which then dominates plots and peak
statistics. A journal that runs loaded sits on the side of the bearing the load pushes it to;
``wall_start`` puts it there at t0, so the run begins close to how a running joint is loaded.

No impact has happened at t0, so the damped laws' impact velocity δ̇⁻ has no onset to latch. Left at
the memory's floor (v_min = 1e-4 m/s) the term χ̂ δ̇/δ̇⁻ dominates the contact for as long as it
lasts (a damping-held journal: large forces at micrometre penetrations, ~10x the solver steps).
``wall_start`` therefore starts the memory at ``WALL_START_IMPACT_VELOCITY``: no hysteresis damping
until the journal first separates, after which the memory tracks δ̇ and latches the next onset as
usual (docs/model.md §5c, "Starting in contact", for the measurements behind this choice).
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core._errors import ModelError
from ..model import Mechanism, RevoluteJoint, TranslationalJoint
from ._simulate import simulate

REACTION_HORIZON = 1e-7
"""s: the reaction at t0 is read from a solve of the ideal mechanism over this short span (its first
saved instant, at t0, is the assembled state; the span only has to be positive)."""

WALL_START_IMPACT_VELOCITY = 1e3
"""m/s: the impact-velocity memory of a journal started on its wall (``ClearanceJoint``'s
``initial_impact_velocity``): large enough that the hysteresis term χ̂ δ̇/δ̇⁻ stays below 0.2 % of
the elastic force for |δ̇| <= 1 m/s with any χ̂ <= 2 (the damped laws at c_e >= 0.5), i.e. no
damping until the first separation; small enough that the free-flight relaxation k_m = 1e6 1/s
clears it to 1e-4 m/s within ln(1e7)/k_m ≈ 16 µs of free flight, so the onset after a real
separation latches its own approach speed (a shorter, grazing separation keeps part of it: on the
one-joint benchmark the first, ~3 µs by the decay, re-latched 43 m/s; the next latched ~0.14 m/s).
Chosen by measurement against 1e-4 (the floor), 0.3, 3, 10, 100 and 1e6 m/s (docs/model.md §5c,
"Starting in contact")."""


def ideal_mechanism(mechanism: Mechanism) -> Mechanism:
    """``mechanism`` with each clearance joint replaced by an ideal ``RevoluteJoint`` of the same name
    whose first body is the bearing body and second the journal body (at their joint points), and
    each translational clearance joint by the ideal ``TranslationalJoint`` it replaced (slider
    first, same guide line and angle)."""
    replaced = tuple(
        RevoluteJoint(c.name, c.bearing_body, c.bearing_point, c.journal_body, c.journal_point)
        for c in mechanism.clearance_joints
    )
    guides = tuple(
        TranslationalJoint(
            t.name, t.slider_body, t.slider_point, t.guide_body, t.guide_point, t.axis, t.angle
        )
        for t in mechanism.translational_clearance_joints
    )
    return dataclasses.replace(
        mechanism,
        joints=(*mechanism.joints, *replaced, *guides),
        clearance_joints=(),
        translational_clearance_joints=(),
    )


def wall_start(
    mechanism: Mechanism,
    t0: float = 0.0,
    *,
    num_points: int = 2,
    impact_velocity: float = WALL_START_IMPACT_VELOCITY,
) -> Mechanism:
    """Start each journal on its bearing wall, where the ideal joint's reaction pushes it.

    In the ideal mechanism (``ideal_mechanism``: each clearance joint made an ideal revolute joint
    between the same bodies and points, bearing body first) the joint transmits a force F from the
    journal to the bearing at t0. In a clearance joint the journal transmits force only by pressing
    on the wall, along the unit vector n from the bearing centre to the contact point, with
    F = F_N n (docs/model.md §2: the contact force on the bearing is +F_N n). So the journal starts at
    eccentricity e = c n, n = F/|F|: on the wall, not yet penetrating, with the ideal joint's
    velocities. A joint that carries no force at t0 (|F| = 0) stays centred.

    A journal placed on its wall has had no impact, so its impact-velocity memory starts at
    ``impact_velocity`` (``ClearanceJoint.initial_impact_velocity``), by default
    ``WALL_START_IMPACT_VELOCITY``: no hysteresis damping until its first separation.

    Args:
        mechanism: a ``Mechanism`` with clearance joints (unbatched, concrete values).
        t0: start time, s.
        num_points: output points of the short solve of the ideal mechanism that gives the
            reaction (only the first, at t0, is used). A solve compiles once per number of output
            points, so passing the number of a later ideal-joint solve of ``ideal_mechanism`` with
            the ``"fast"`` solver shares that compilation (``jaxclear run`` does this).
        impact_velocity: initial impact-velocity memory of each journal placed on its wall, m/s
            (>= 0; 0 leaves it at the initial penetration rate, i.e. the floor v_min: the
            behaviour before this option).

    Returns:
        The mechanism with each clearance joint's ``initial_eccentricity`` set to c n (global
        components, m) and, where |F| > 0, its ``initial_impact_velocity`` to ``impact_velocity``.

    Raises:
        ModelError: ``impact_velocity`` is negative or not finite.
        AssemblyError: the ideal mechanism cannot be assembled at t0.
    """
    speed = float(impact_velocity)
    if not (np.isfinite(speed) and speed >= 0):
        raise ModelError(
            f"wall_start: impact_velocity must be a finite speed >= 0 m/s, got {impact_velocity}; "
            f"pass e.g. the default {WALL_START_IMPACT_VELOCITY:g} (no damping until the first "
            "separation) or 0 (memory at its floor)."
        )
    if not mechanism.clearance_joints:
        return mechanism
    ideal = ideal_mechanism(mechanism)
    traj = simulate(ideal, t0 + REACTION_HORIZON, t0=t0, num_points=num_points, solver="fast")
    eccentricities, speeds = [], []
    for joint in mechanism.clearance_joints:
        force = np.asarray(traj.joint_force(joint.name))[0]  # journal body on bearing body, N
        magnitude = float(np.hypot(force[0], force[1]))
        clearance = joint.geometry.bearing_radius - joint.geometry.journal_radius
        direction = force / magnitude if magnitude > 0 else np.zeros(2)
        eccentricities.append(clearance * jnp.asarray(direction))
        speeds.append(jnp.asarray(speed if magnitude > 0 else 0.0))
    mechanism = eqx.tree_at(
        lambda m: [c.initial_eccentricity for c in m.clearance_joints], mechanism, eccentricities
    )
    return eqx.tree_at(
        lambda m: [c.initial_impact_velocity for c in m.clearance_joints], mechanism, speeds
    )
