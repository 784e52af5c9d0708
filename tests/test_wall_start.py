"""A start in contact (docs/model.md §5c, "Starting in contact"): the impact-velocity memory of a
journal that ``jaxclear.wall_start`` puts on its wall.

No impact has happened at t0, so there is no onset to latch. Left at the floor v_min (what
``impact_velocity=0`` gives, the behaviour before) the hysteresis term χ̂ δ̇/δ̇⁻ holds the journal
up: large forces at micrometre penetrations and many times the solver steps. ``wall_start`` now
starts the memory high (no damping until the first separation). Cheap checks on the first
millisecond of the one-joint case (slider-crank, clearance at B, 5000 rpm; L-N contact without
friction and the ``fast`` solver, which compile quickly); the settled comparison with a centred
start, on the CLI's one-joint case (hybrid law, LuGre), is ``slow``.
"""

import dataclasses
import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear.contact import ContactKinematics, LankaraniNikravesh
from jaxclear.friction import NoFriction

NUM_POINTS = 401
"""One output grid for the solves here and for ``wall_start``'s ideal solve (shared compilations)."""

WINDOW = 1e-3
"""s: the first millisecond of a wall start (1/12 revolution at 5000 rpm), which holds its first
contact phase (the journal is pressed into the wall by the load from t0)."""

ELASTIC_TOLERANCE = 0.02
"""Largest |F_N − F_el| / max F_el allowed for the wall start: with the memory at
``impact_velocity`` = 1e3 m/s the hysteresis term is ~1e-4 of the elastic force, so 2 % is loose;
at the floor the damping part is several times the elastic one (measured: test_before_is_damping_held)."""

LOAD_FACTOR = 3.0
"""Largest early peak F_N / ideal-joint reaction at t0: a load applied at once to an undamped
elastic contact overshoots to at most about twice its static value; 3 leaves room for the load's
growth over the window."""


@jax.jit
def _elastic_forces(joint, penetration):
    def one(d):
        kin = ContactKinematics(d, 0.0, 1.0, 0.0)
        return joint.contact_law(kin, joint.geometry, joint.smoothing)[0]

    return jax.vmap(one)(penetration)


def _elastic_force(joint, penetration):
    """The contact law's force at the given penetrations with zero rate (no hysteresis), N."""
    return np.asarray(_elastic_forces(joint, jnp.asarray(penetration)))


def slider_crank(**options):
    return jaxclear.mechanisms.slider_crank(
        clearance_joints="B", contact_law=LankaraniNikravesh(), friction_law=NoFriction(), **options
    )


def _simulate(mechanism, t1):
    return jaxclear.simulate(mechanism, t1, num_points=NUM_POINTS, solver="fast", extremes=False)


@pytest.fixture(scope="module")
def runs():
    base = slider_crank()
    after = jaxclear.wall_start(base, num_points=NUM_POINTS)
    before = jaxclear.wall_start(base, num_points=NUM_POINTS, impact_velocity=0.0)
    # one compiled program for both: the memory's start value is an array leaf
    return dict(
        base=base,
        after=after,
        before=before,
        traj_after=_simulate(after, WINDOW),
        traj_before=_simulate(before, WINDOW),
    )


def _load(base):
    """|ideal joint B reaction| at t0, N (the short solve wall_start ran: compiled already)."""
    ideal = jaxclear.ideal_mechanism(base)
    traj = jaxclear.simulate(ideal, 1e-7, num_points=NUM_POINTS, solver="fast")
    return float(np.asarray(traj.joint_force_magnitude("B"))[0])


def _until_first_separation(traj):
    """Number of saved instants from t0 until the journal first leaves the wall."""
    pen = np.asarray(traj.clearance["B"]["penetration"])
    in_contact = pen[1:] > 0
    return 1 + (int(np.argmin(in_contact)) if not in_contact.all() else in_contact.size)


def test_initial_memory_is_the_wall_start_value(runs):
    default = inspect.signature(jaxclear.wall_start).parameters["impact_velocity"].default
    joint = runs["after"].clearance_joints[0]
    assert float(joint.initial_impact_velocity) == default
    memory = np.asarray(runs["traj_after"].clearance["B"]["impact_velocity"])
    assert memory[0] == default
    # the journal is on its wall, not penetrating, not yet moving into it
    pen0 = float(runs["traj_after"].clearance["B"]["penetration"][0])
    assert abs(pen0) < 1e-12
    # frozen in contact: the memory keeps its start value until the journal first leaves the wall
    until = _until_first_separation(runs["traj_after"])
    assert until > 10  # the load keeps the journal on the wall for a while
    assert np.all(memory[:until] == default)


def test_zero_keeps_the_memory_at_the_initial_rate(runs):
    """initial_impact_velocity = 0 (the default of ClearanceJoint) starts the memory at δ̇(t0),
    bitwise: runs that do not use the option are unchanged."""
    c = runs["traj_before"].clearance["B"]
    assert float(c["impact_velocity"][0]) == float(c["penetration_rate"][0])
    assert float(runs["base"].clearance_joints[0].initial_impact_velocity) == 0.0


def test_early_force_is_elastic(runs):
    """In the first contact of a wall start (until the journal first leaves the wall) the normal
    force is what the elastic law gives at that penetration: the load is carried by the contact's
    stiffness, not by hysteresis damping."""
    joint = runs["after"].clearance_joints[0]
    c = runs["traj_after"].clearance["B"]
    until = _until_first_separation(runs["traj_after"])
    pen = np.asarray(c["penetration"])[:until]
    assert pen.max() > 1e-6  # the load presses the journal micrometres into the wall
    fn = np.asarray(c["normal_force"])[:until]
    fel = _elastic_force(joint, pen)
    assert np.max(np.abs(fn - fel)) < ELASTIC_TOLERANCE * np.max(fel)


def test_before_is_damping_held(runs):
    """The defect this fixes, measured: with the memory at its floor most of the force is damping."""
    joint = runs["before"].clearance_joints[0]
    c = runs["traj_before"].clearance["B"]
    pen = np.asarray(c["penetration"])
    fn = np.asarray(c["normal_force"])
    fel = _elastic_force(joint, pen)
    assert np.max(fn) > 2.0 * np.max(fel)


def test_early_force_has_the_size_of_the_load(runs):
    load = _load(runs["base"])
    peak = float(np.max(runs["traj_after"].clearance["B"]["normal_force"]))
    assert 0.5 * load < peak < LOAD_FACTOR * load
    # and the solver is not held back by a stiff damping-held contact
    steps_after = int(runs["traj_after"].num_steps)
    steps_before = int(runs["traj_before"].num_steps)
    assert steps_after < steps_before / 3


@pytest.mark.slow  # the forward-sensitivity solve is another compilation (~40 s on 2 cores)
def test_gradients_finite():
    """d(mean F_N over a short wall start)/d(initial_impact_velocity, clearance): finite."""
    base = jaxclear.wall_start(slider_crank(), num_points=NUM_POINTS)
    horizon = 2e-4

    def mean_force(params):
        v0, clearance = params
        m = dataclasses.replace(
            base,
            clearance_joints=(
                dataclasses.replace(
                    base.clearance_joints[0],
                    initial_impact_velocity=v0,
                    geometry=dataclasses.replace(
                        base.clearance_joints[0].geometry,
                        journal_radius=base.clearance_joints[0].geometry.bearing_radius - clearance,
                    ),
                ),
            ),
        )
        traj = jaxclear.simulate(
            m, horizon, num_points=NUM_POINTS, solver="fast", extremes=False, adjoint="forward"
        )
        return jnp.mean(traj.clearance["B"]["normal_force"])

    grad = jax.jacfwd(mean_force)(jnp.asarray([1e3, 5e-4]))
    assert np.all(np.isfinite(np.asarray(grad)))


def test_bad_impact_velocity():
    base = slider_crank()
    with pytest.raises(jaxclear.ModelError, match="impact_velocity"):
        jaxclear.wall_start(base, impact_velocity=-1.0)
    with pytest.raises(jaxclear.ModelError, match="initial_impact_velocity"):
        dataclasses.replace(base.clearance_joints[0], initial_impact_velocity=-1.0)


# --- settled statistics: wall start against centred start (slow) --------------------------------
RPM = 5000.0
REVOLUTION = 60.0 / RPM  # s
REVOLUTIONS = 10
SETTLED_FROM = 4
"""Revolutions 4-9 are the settled ones: from revolution 3 on, per-revolution peaks of both starts
change by < 1 % from one revolution to the next (measured with this helper)."""
RTOLS = (0.8e-6, 0.9e-6, 1e-6, 1.1e-6, 1.25e-6)
"""Nearby runs: the impact sequence forks at the rounding level (docs/model.md §5b), so each start
is run at five tolerances around the default and compared by the median over them."""
AGREEMENT = 0.02
"""Target of issue 24: a wall start and a centred start agree within 2 % on settled statistics."""


def per_revolution_peaks(mechanism, rtol):
    """Per revolution: peak |slider acceleration|, peak B normal force, peak |crank torque|.

    One ``simulate`` per revolution, continued from the previous ``y_final``, peaks from
    ``Trajectory.extremes`` (the solver's steps, so they do not depend on the output grid).
    """
    solver = dataclasses.replace(jaxclear.recommended_solver(mechanism), rtol=rtol)
    i = 3 * mechanism.body_index("slider")
    y, rows = None, []
    for k in range(REVOLUTIONS):
        traj = jaxclear.simulate(
            mechanism,
            (k + 1) * REVOLUTION,
            t0=k * REVOLUTION,
            y0=y,
            num_points=2,
            statistics_start=k * REVOLUTION,
            solver=solver,
        )
        ex = traj.extremes
        rows.append(
            (
                max(-float(ex.acceleration_min[i]), float(ex.acceleration_max[i])),
                float(ex.normal_force_max["B"]),
                max(-float(ex.input_torque_min), float(ex.input_torque_max)),
            )
        )
        y = traj.y_final
    return np.asarray(rows)


def settled_medians(mechanism):
    """(len(RTOLS), 3): per tolerance, the median over settled revolutions of each peak."""
    return np.asarray(
        [np.median(per_revolution_peaks(mechanism, r)[SETTLED_FROM:], axis=0) for r in RTOLS]
    )


@pytest.mark.slow
def test_wall_start_settles_like_a_centred_start():
    """The CLI's one-joint case (hybrid law, LuGre, clearance at B, 5000 rpm; ``--start wall``
    calls ``wall_start``): settled medians of the wall start within 2 % of the centred start's,
    and the floor memory (``impact_velocity=0``, the behaviour before) further off."""
    base = jaxclear.mechanisms.slider_crank(rpm=RPM, clearance_joints="B")
    centred = settled_medians(base)
    wall = settled_medians(jaxclear.wall_start(base))
    floor = settled_medians(jaxclear.wall_start(base, impact_velocity=0.0))
    reference = np.median(centred, axis=0)
    names = ("peak |slider acceleration| m/s^2", "peak B normal force N", "peak |crank torque| N m")
    for label, table in (("centred", centred), ("wall", wall), ("wall, floor memory", floor)):
        for k, name in enumerate(names):
            deviation = 100 * (table[:, k] / reference[k] - 1)
            print(
                f"{label}: {name}: median {np.median(table[:, k]):.1f} "
                f"({100 * (np.median(table[:, k]) / reference[k] - 1):+.1f} % vs centred), "
                f"over rtols {deviation.min():+.1f} .. {deviation.max():+.1f} %"
            )
    np.testing.assert_array_less(np.abs(np.median(wall, axis=0) / reference - 1), AGREEMENT)
    # the floor memory's damping-held contact: its B force is further off than the target
    assert abs(np.median(floor[:, 1]) / reference[1] - 1) > AGREEMENT
