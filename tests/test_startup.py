"""``jaxclear.wall_start``: journals start on their bearing walls, along the ideal joint's reaction."""

import numpy as np
import pytest

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import NoFriction

CLEARANCE = 5e-4  # m
RPM = 5000.0
HORIZON = 4e-4  # s: at 5000 rpm a centred journal first strikes the wall after about 0.2-0.3 ms
NUM_POINTS = (
    401  # one output grid for every solve here: the solves share one compilation per topology
)
EXTREMES = False
"""The clearance-joint solves here leave ``Trajectory.extremes`` out: the checks read the saved
trajectory, and the compilation takes about 40 % less CPU without the tracking. (The ideal solve in
``ideal_joint_force`` keeps the default: it shares ``wall_start``'s compiled solve.)"""
PEAK_RATIO = 5.0
"""The centred start's first-impact peak must exceed the wall start's by at least this factor: a
journal that starts on the wall is already loaded, a centred one strikes it after flying free."""


def slider_crank(joint: str, **options):
    return jaxclear.mechanisms.slider_crank(
        rpm=RPM,
        clearance_joints={joint: options},
        clearance=CLEARANCE,
        contact_law=LankaraniNikravesh(),
        friction_law=NoFriction(),
    )


def ideal_joint_force(mechanism, joint: str) -> np.ndarray:
    """Force the journal transmits to the bearing at t = 0 in the ideal mechanism, N."""
    from jaxclear.solve import ideal_mechanism

    traj = jaxclear.simulate(ideal_mechanism(mechanism), 1e-7, num_points=NUM_POINTS, solver="fast")
    return np.asarray(traj.joint_force(joint))[0]


SLOW = pytest.mark.slow  # another joint is another topology: two more compilations


@pytest.mark.parametrize(
    ("joint", "journal_body"),
    [("B", None), pytest.param("B", "rod", marks=SLOW), pytest.param("O", None, marks=SLOW)],
)
def test_eccentricity_on_the_wall_along_the_reaction(joint, journal_body):
    options = {} if journal_body is None else {"journal_body": journal_body}
    mechanism = slider_crank(joint, **options)
    started = jaxclear.wall_start(mechanism, num_points=NUM_POINTS)
    (clearance_joint,) = started.clearance_joints
    eccentricity = np.asarray(clearance_joint.initial_eccentricity)
    np.testing.assert_allclose(np.linalg.norm(eccentricity), CLEARANCE, rtol=1e-12)
    force = ideal_joint_force(mechanism, joint)
    assert np.linalg.norm(force) > 100.0  # the benchmark's joints carry kN at 5000 rpm
    # e = c n with n along the force the journal puts on the bearing (contact force on the bearing +F_N n)
    np.testing.assert_allclose(
        eccentricity, CLEARANCE * force / np.linalg.norm(force), rtol=1e-9, atol=1e-15
    )
    # only the eccentricity changed
    assert clearance_joint.bearing_body == mechanism.clearance_joints[0].bearing_body
    np.testing.assert_array_equal(
        np.asarray(mechanism.clearance_joints[0].initial_eccentricity), [0.0, 0.0]
    )
    # assembled: the journal centre sits at bearing centre + e, i.e. on the wall, no penetration
    traj = jaxclear.simulate(started, 1e-7, num_points=NUM_POINTS, solver="fast", extremes=EXTREMES)
    out = traj.clearance[joint]
    np.testing.assert_allclose([out["ecc_x"][0], out["ecc_y"][0]], eccentricity, atol=1e-12)
    assert abs(float(out["penetration"][0])) < 1e-12


def test_pin_side_flips_the_wall():
    """Swapping which body carries the pin swaps bearing and journal, so the wall side flips."""
    on_slider = jaxclear.wall_start(slider_crank("B"), num_points=NUM_POINTS).clearance_joints[0]
    on_rod = jaxclear.wall_start(
        slider_crank("B", journal_body="rod"), num_points=NUM_POINTS
    ).clearance_joints[0]
    np.testing.assert_allclose(
        np.asarray(on_rod.initial_eccentricity),
        -np.asarray(on_slider.initial_eccentricity),
        rtol=1e-9,
    )


@pytest.mark.parametrize(
    "joint", ["B", pytest.param("A", marks=SLOW), pytest.param("O", marks=SLOW)]
)
def test_wall_start_softens_the_first_impact(joint):
    mechanism = slider_crank(joint)
    peaks = {}
    for name, start in (
        ("centred", mechanism),
        ("wall", jaxclear.wall_start(mechanism, num_points=NUM_POINTS)),
    ):
        traj = jaxclear.simulate(
            start, HORIZON, num_points=NUM_POINTS, solver="fast", extremes=EXTREMES
        )
        force = np.asarray(traj.clearance[joint]["normal_force"])
        assert force.max() > 0, f"{name}: no contact within {HORIZON} s"
        peaks[name] = force.max()
    assert peaks["centred"] > PEAK_RATIO * peaks["wall"], peaks


def test_no_clearance_joints_is_unchanged():
    mechanism = jaxclear.mechanisms.slider_crank(rpm=RPM)
    assert jaxclear.wall_start(mechanism) is mechanism
