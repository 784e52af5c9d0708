"""Where ``Trajectory.extremes`` takes its samples (issue 25, part 2).

With Tsit5 (``auto``'s choice without friction states) the observations ride along the solver's
own stages: the end sample of a step is the observation at the last stage, which is (t1, y1), and
the midpoint sample the derivative of the observations' dense output (``ExtremesTracking``). These
tests check that the samples are what they claim to be, against the trajectory's own outputs at
the same instants, and that tracking them leaves the solve alone.
"""

import numpy as np
import pytest

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb

WINDOW = 1e-3
"""s: several impacts of joint B at 5000 rpm."""


@pytest.fixture(scope="module")
def runs():
    m = jaxclear.mechanisms.slider_crank(
        rpm=5000.0,
        clearance_joints="B",
        contact_law=LankaraniNikravesh(),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )
    assert jaxclear.recommended_solver(m).method == "tsit5"
    grid = np.linspace(0.0, WINDOW, 11)
    on = jaxclear.simulate(m, WINDOW, ts=grid)
    off = jaxclear.simulate(m, WINDOW, ts=grid, extremes=False)
    # the solve's own outputs at the last step's midpoint, from its dense output (a grid of the
    # same size: the same compiled solve as ``off``)
    t_mid = float(on.extremes.times[0])
    at_mid = jaxclear.simulate(m, WINDOW, ts=np.r_[grid[:9], t_mid, WINDOW], extremes=False)
    return dict(on=on, off=off, at_mid=at_mid, t_mid=t_mid)


def test_tracking_leaves_the_solve_alone(runs):
    on, off = runs["on"], runs["off"]
    assert int(on.num_steps) == int(off.num_steps)
    np.testing.assert_array_equal(np.asarray(on.y_final), np.asarray(off.y_final))
    np.testing.assert_array_equal(np.asarray(on.q), np.asarray(off.q))


def test_end_sample_is_the_observation_at_the_last_step_end(runs):
    on = runs["on"]
    end = on.extremes.recent[1]
    assert float(on.extremes.times[1]) == pytest.approx(WINDOW, rel=1e-15)
    np.testing.assert_allclose(end.accelerations, on.qdd[-1], rtol=1e-10, atol=1e-6)
    np.testing.assert_allclose(end.input_torque, on.input_torque[-1], rtol=1e-10)
    force = on.clearance["B"].normal_force[-1]
    np.testing.assert_allclose(end.normal_force["B"], force, rtol=1e-10, atol=1e-9)
    penetration = on.clearance["B"].penetration[-1]
    np.testing.assert_allclose(end.penetration["B"], penetration, rtol=1e-10, atol=1e-15)


def test_midpoint_sample_follows_the_dense_output(runs):
    """The midpoint sample is the derivative of the observations' dense output there (one order
    below the state's): close to the outputs at the interpolated state (what the samples were
    before they rode along), not equal. Measured: the rod's angular acceleration 764 407.6 against
    764 467.8 rad/s², 8.7e-5 of the largest acceleration on the grid; hence 5e-4."""
    on, at_mid = runs["on"], runs["at_mid"]
    mid = on.extremes.recent[0]
    assert runs["t_mid"] < WINDOW
    scale = np.max(np.abs(np.asarray(on.qdd)))
    np.testing.assert_allclose(mid.accelerations, at_mid.qdd[9], rtol=0, atol=5e-4 * scale)
    torque_scale = np.max(np.abs(np.asarray(on.input_torque)))
    assert abs(float(mid.input_torque - at_mid.input_torque[9])) <= 5e-4 * torque_scale
