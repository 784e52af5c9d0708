"""``jaxclear.signals`` and ``signal_names``: the continuous columns of results.csv as JAX arrays.

Two compiled solves for the module: the slider–crank with a clearance joint at B over a tenth of a
revolution, simulated eagerly in the configuration of tests/test_clearance_joint.py (a worker that
ran that module reuses its compiled solve); the driven four-bar (ideal joints: body columns,
revolute forces, torque) simulated under ``jax.jvp``, which gives its trajectory (as aux) and the
derivative of a signal with respect to a mechanism leaf from one compilation (forward mode: 7 s of
CPU against 16 s for ``jax.value_and_grad``; reverse mode through ``signals`` is checked on the
trajectory's arrays, reverse mode through ``simulate`` by tests/test_transforms.py).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import NUM_POINTS  # as tests/test_clearance_joint.py: same compiled solve

import jaxclear
from jaxclear.contact import ContactGeometry, LankaraniNikravesh
from jaxclear.friction import LuGre, NoFriction
from jaxclear.io import result_columns
from jaxclear.mechanisms import four_bar, slider_crank

RPM = 5000.0
PERIOD = 60 / RPM  # s
CLEARANCE_SOLVER = jaxclear.SolverConfig(method="tsit5", rtol=1e-8, atol=1e-11, max_steps=400_000)
HERTZ_K = float(ContactGeometry(0.01, 0.0095).hertz_stiffness)
FOUR_BAR_POINTS = 51
SAME_RTOL = 1e-12
"""signals vs result_columns: the same float64 arrays taken apart in the same way (measured: equal
bit for bit); relative to the column's largest magnitude."""

NOT_SIGNALS = {"t", "crank_angle", "constraint_violation", "velocity_violation"}
"""Columns of result_columns that are no signals (plus each clearance joint's mode and
impact-velocity memory)."""


@pytest.fixture(scope="module")
def clearance_run():
    mech = slider_crank(
        rpm=RPM,
        clearance_joints="B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(stiffness=HERTZ_K, restitution=0.9),
        friction_law=NoFriction(),
    )
    return jaxclear.simulate(  # extremes=False as there: the same compiled solve
        mech, 0.1 * PERIOD, num_points=NUM_POINTS, solver=CLEARANCE_SOLVER, extremes=False
    )


@pytest.fixture(scope="module")
def four_bar_run():
    """The four-bar's trajectory and d(sum of crank torque)/d(crank mass), one compilation."""

    def torque_sum(crank_mass):
        mech = four_bar(crank_mass=crank_mass)
        traj = jaxclear.simulate(
            mech, 0.05, num_points=FOUR_BAR_POINTS, solver="fast", extremes=False
        )
        return jnp.sum(jaxclear.signals(traj, ["crank_torque"])["crank_torque"]), traj

    _, derivative, traj = jax.jvp(
        torque_sum, (jnp.asarray(0.2),), (jnp.asarray(1.0),), has_aux=True
    )
    return traj, derivative


def _check_equal_to_result_columns(traj):
    names = jaxclear.signal_names(traj.mechanism)
    columns = {c.name: c.values for c in result_columns(traj)}
    order = [n for n in columns if n in names]
    assert list(names) == order, "signal names in results.csv order"
    values = jaxclear.signals(traj)
    assert list(values) == list(names)
    for name in names:
        got, want = np.asarray(values[name]), columns[name]
        assert got.shape == want.shape == traj.t.shape
        scale = max(np.abs(want).max(), 1e-300)
        assert np.abs(got - want).max() <= SAME_RTOL * scale, name
    return set(columns) - set(names)


def test_slider_crank_with_clearance_equals_result_columns(clearance_run):
    normal_force = np.asarray(clearance_run.clearance["B"]["normal_force"])
    assert np.any(normal_force > 0), "the run must contain contact for the comparison to mean much"
    left_out = _check_equal_to_result_columns(clearance_run)
    assert left_out == NOT_SIGNALS | {"B_mode", "B_impact_velocity"}
    assert jaxclear.signal_names(clearance_run.mechanism)[:3] == (
        "slider_x",
        "slider_v",
        "slider_a",
    )


def test_four_bar_equals_result_columns(four_bar_run):
    traj, _ = four_bar_run
    left_out = _check_equal_to_result_columns(traj)
    assert left_out == NOT_SIGNALS
    names = jaxclear.signal_names(traj.mechanism)
    assert {"coupler_ax", "rocker_alpha", "O2_Fx", "O4_Fy", "crank_torque"} <= set(names)


def test_derivative_of_a_signal_wrt_a_mechanism_leaf(four_bar_run):
    """Through ``simulate`` (forward mode), and reverse mode through ``signals`` itself: the
    gradient of the summed crank torque with respect to the trajectory's input torque is one at
    every saved instant."""
    traj, derivative = four_bar_run
    assert np.isfinite(float(derivative)) and float(derivative) != 0.0

    def torque_sum(t):
        return jnp.sum(jaxclear.signals(t, ["crank_torque"])["crank_torque"])

    grad = eqx.filter_grad(torque_sum)(traj)
    np.testing.assert_array_equal(np.asarray(grad.input_torque), 1.0)


def test_jit_and_vmap(clearance_run):
    names = ["slider_a", "B_normal_force", "crank_torque", "slider_guide_normal"]
    eager = jaxclear.signals(clearance_run, names)
    jitted = jax.jit(lambda traj: jaxclear.signals(traj, names))(clearance_run)
    pair = jax.tree_util.tree_map(lambda x: jnp.stack([x, x]), clearance_run)
    mapped = jax.vmap(lambda traj: jaxclear.signals(traj, names))(pair)
    batched = jaxclear.signals(pair, names)
    for name in names:
        np.testing.assert_allclose(jitted[name], eager[name], rtol=SAME_RTOL, atol=0)
        for stacked in (mapped, batched):
            assert stacked[name].shape == (2, *eager[name].shape)
            np.testing.assert_array_equal(stacked[name][1], eager[name])


def test_names_of_clearance_joints():
    """``<J>_friction_state`` with a friction law that has an internal state (LuGre), after
    ``<J>_slip_velocity`` as in results.csv; never the mode or the impact-velocity memory."""
    lugre = jaxclear.signal_names(slider_crank(clearance_joints="B", friction_law=LuGre()))
    assert lugre[-2:] == ("B_slip_velocity", "B_friction_state")
    mech = slider_crank(
        clearance_joints=("A", "B"), contact_law=LankaraniNikravesh(), friction_law=NoFriction()
    )
    names = jaxclear.signal_names(mech)
    assert "A_slip_velocity" in names and "B_penetration" in names
    assert not any(n.endswith(("friction_state", "_mode", "impact_velocity")) for n in names)
    assert "O_Fx" in names and "A_Fx" not in names  # ideal O, clearance A and B
    assert "crank_angle" not in names


def test_unknown_name_lists_the_valid_ones(clearance_run):
    with pytest.raises(ValueError, match=r"'slider_y' is not a signal .* valid names: slider_x, "):
        jaxclear.signals(clearance_run, ["slider_a", "slider_y"])
    with pytest.raises(ValueError, match="'crank_angle' is not a signal"):
        jaxclear.signals(clearance_run, ["crank_angle"])
    with pytest.raises(TypeError, match=r"write \['slider_a'\]"):
        jaxclear.signals(clearance_run, "slider_a")
