"""Every bad input gives its error, naming the quantity and a fix (STYLE.md, Errors inside jit)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import NUM_POINTS

import jaxclear
from jaxclear.mechanisms import four_bar, slider_crank

RPM = 5000.0
PERIOD = 60.0 / RPM  # s
T1 = 2 * PERIOD
STEP_BUDGET = 20
"""Too few steps for two revolutions at 5000 rpm (they take 56), enough for 100 rpm (2)."""
STARVED = jaxclear.SolverConfig(method="tsit5", max_steps=STEP_BUDGET)
GRID = 11
"""Output points of every solve here. With ``STARVED`` the checks made inside the compiled solve and
the solver-failure tests share one compilation (one more for the batch), and a bad input stops after
``STEP_BUDGET`` steps instead of being integrated over the whole horizon; the input checks are
raised before the failed solve, so the starved budget does not hide them."""


# --------------------------------------------------------------------------------------------
# Model parameters (construction time, eager)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mass", [0.0, -0.3])
def test_non_positive_mass(mass):
    with pytest.raises(
        jaxclear.ModelError, match=r"Body 'crank': mass must be > 0, got -?0\.[03] kg"
    ):
        jaxclear.Body("crank", mass, 1e-4)


@pytest.mark.parametrize("inertia", [0.0, -1e-4])
def test_non_positive_inertia(inertia):
    with pytest.raises(jaxclear.ModelError, match=r"Body 'rod': inertia must be > 0"):
        jaxclear.Body("rod", 0.21, inertia)


def test_model_error_is_a_value_error():
    with pytest.raises(ValueError, match="mass"):
        jaxclear.Body("crank", 0.0, 1e-4)


def test_nan_mass():
    with pytest.raises(jaxclear.ModelError, match=r"Body 'slider': mass must be finite, got nan"):
        jaxclear.Body("slider", float("nan"), 1e-4)


def test_nan_rod_length_names_the_parameter():
    with pytest.raises(jaxclear.ModelError, match=r"rod_length=nan"):
        slider_crank(rod_length=float("nan"))


def test_nan_parameter_set_after_construction_is_named_by_simulate():
    """``eqx.tree_at`` bypasses the constructor checks; ``simulate`` still names the leaf."""
    bad = eqx.tree_at(lambda m: m.bodies[1].mass, slider_crank(), jnp.asarray(float("nan")))
    with pytest.raises(jaxclear.ModelError, match=r"bodies\[1\]\.mass is not finite"):
        jaxclear.simulate(bad, T1, num_points=NUM_POINTS, solver="fast")


def test_unknown_clearance_joint_says_how_to_list_several():
    with pytest.raises(jaxclear.ModelError, match=r"got \['X'\]\.$"):
        slider_crank(clearance_joints="X")
    with pytest.raises(
        jaxclear.ModelError, match=r"separated by commas: 'O,A,B' or \('O', 'A', 'B'\)"
    ):
        slider_crank(clearance_joints="OAB")


def test_unknown_solver_name():
    with pytest.raises(ValueError, match=r"solver 'euler' is unknown; choose 'auto', a preset"):
        jaxclear.simulate(slider_crank(), T1, solver="euler")
    with pytest.raises(ValueError, match=r"solver method 'rk4' is unknown"):
        jaxclear.SolverConfig(method="rk4")


def test_bad_time_arguments():
    mech = slider_crank()
    with pytest.raises(ValueError, match=r"t1 must be finite and greater than t0"):
        jaxclear.simulate(mech, -1.0, solver="fast")
    with pytest.raises(ValueError, match=r"ts must be increasing and inside \[t0, t1\]"):
        jaxclear.simulate(mech, T1, ts=np.array([0.0, 2 * T1]), solver="fast")
    # one point was silently the start state alone (issue 28, item 10)
    for n in (0, 1):
        with pytest.raises(ValueError, match=r"num_points must be at least 2.*ts=\[t1\]"):
            jaxclear.simulate(mech, T1, num_points=n, solver="fast")


# --------------------------------------------------------------------------------------------
# Assembly
# --------------------------------------------------------------------------------------------
def test_four_bar_that_cannot_close():
    """Ground 1.0 m, links 0.1 + 0.2 + 0.2 m: the loop misses by about half a metre."""
    mech = four_bar(ground_length=1.0, crank_length=0.1, coupler_length=0.2, rocker_length=0.2)
    pattern = (
        r"cannot be assembled: RevoluteJoint '(O2|A|B|O4)' row \d is off by -?\d\.\d+(e-?\d+)? m"
    )
    with pytest.raises(jaxclear.AssemblyError, match=pattern) as info:
        jaxclear.assemble(mech)
    off = float(str(info.value).split("off by ")[1].split(" ")[0])
    print(f"reported: {info.value}")
    assert abs(off) > 0.1  # the reported residual is of the size of the gap, not round-off
    with pytest.raises(jaxclear.AssemblyError, match="cannot be assembled"):
        jaxclear.simulate(mech, 0.1, num_points=NUM_POINTS, solver="fast")


def _duplicate_of_o():
    return jaxclear.RevoluteJoint("O_dup", "ground", (0.0, 0.0), "crank", (-0.025, 0.0))


def test_redundant_duplicate_revolute_joint():
    """Slider–crank with joint O given twice (the slider guide dropped so that there are no more
    equations than coordinates): Φ_q loses rank and both copies are named."""
    base = slider_crank()
    joints = tuple(j for j in base.joints if j.name != "slider_guide") + (_duplicate_of_o(),)
    mech = jaxclear.Mechanism(
        bodies=base.bodies, joints=joints, driver=base.driver, gravity=(0.0, 0.0)
    )
    assert mech.num_constraints == mech.num_coordinates
    with pytest.raises(
        jaxclear.AssemblyError,
        match=r"redundant.*involved: .*'O'.*'O_dup'|redundant.*involved: .*'O_dup'.*'O'",
    ):
        jaxclear.assemble(mech)


def test_over_constrained_duplicate_revolute_joint():
    """The full slider–crank plus a duplicate of O: more equations (11) than coordinates (9)."""
    base = slider_crank()
    mech = eqx.tree_at(lambda m: m.joints, base, base.joints + (_duplicate_of_o(),))
    with pytest.raises(
        jaxclear.AssemblyError,
        match=r"11 constraint equations for 9 coordinates \(over-constrained\)",
    ):
        jaxclear.assemble(mech)


# --------------------------------------------------------------------------------------------
# Value checks inside the compiled solve (returned as Trajectory.input_error, raised outside)
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def y0():
    return jaxclear.assemble(slider_crank())


def test_negative_mass_inside_jit(y0):
    """A mass made negative after construction, with ``y0`` given (so no eager parameter check):
    the compiled solve's own check fires."""
    # a strongly typed float64 leaf like the constructor's: a weakly typed one would recompile
    bad = eqx.tree_at(lambda m: m.bodies[0].mass, slider_crank(), jnp.asarray(-0.3, dtype=float))
    with pytest.raises(
        jaxclear.ModelError, match="mass and inertia of every body must be positive"
    ):
        jaxclear.simulate(bad, T1, num_points=GRID, solver=STARVED, y0=y0)


def test_non_finite_initial_state(y0):
    with pytest.raises(jaxclear.ModelError, match="initial state is not finite"):
        jaxclear.simulate(
            slider_crank(), T1, num_points=GRID, solver=STARVED, y0=y0.at[0].set(jnp.nan)
        )


def test_wrong_initial_state_shape(y0):
    with pytest.raises(ValueError, match=r"y0 must have shape \(18,\)"):
        jaxclear.simulate(slider_crank(), T1, num_points=NUM_POINTS, solver="fast", y0=y0[:5])


def _batch(**varied):
    """Batch parameters of the two batch tests: both vary the same leaves (rpm, rod length, crank
    mass, initial angle), so their vmapped solves share one compilation."""
    params = {"rpm": [RPM] * 2, "rod_length": [0.12] * 2, "crank_mass": [0.3] * 2}
    params["initial_angle"] = [0.0] * 2
    return {k: jnp.array(v, dtype=float) for k, v in (params | varied).items()}


def _build(p):
    return slider_crank(**p)


def test_batch_member_that_cannot_be_assembled():
    """Inside ``simulate_batch`` there is no eager assembly: a member whose rod cannot reach the
    guide (l < r at a 90° start) trips the compiled assembly check."""
    params = _batch(rod_length=[0.12, 0.03], initial_angle=[jnp.pi / 2] * 2)
    with pytest.raises(
        jaxclear.AssemblyError, match=r"mechanism cannot be assembled.*batch members \[1\] of 2"
    ):
        jaxclear.simulate_batch(_build, params, T1, num_points=GRID, solver=STARVED)


# --------------------------------------------------------------------------------------------
# Solver failure
# --------------------------------------------------------------------------------------------
def test_simulation_error_gives_time_and_state():
    with pytest.raises(
        jaxclear.SimulationError,
        match=r"simulation failed at t = .* after 20 steps.*raise max_steps \(now 20\)",
    ) as info:
        jaxclear.simulate(slider_crank(rpm=RPM), T1, num_points=GRID, solver=STARVED)
    err = info.value
    print(f"SimulationError: {err}")
    assert 0.0 < err.t < T1
    assert set(err.state) == {"q", "qd", "internal"}
    q, qd = np.asarray(err.state["q"]), np.asarray(err.state["qd"])
    assert (
        q.shape == (9,) and qd.shape == (9,) and np.all(np.isfinite(q)) and np.all(np.isfinite(qd))
    )
    # the state is the mechanism's at err.t: the crank angle is ω t there
    assert q[2] == pytest.approx(RPM * 2 * np.pi / 60 * err.t, rel=1e-5)
    # throw=False returns the failed trajectory instead
    traj = jaxclear.simulate(
        slider_crank(rpm=RPM), T1, num_points=GRID, solver=STARVED, throw=False
    )
    assert not bool(traj.succeeded)
    assert float(traj.t_final) == pytest.approx(err.t, rel=1e-12)


def test_batched_failure_is_reported_per_member():
    params = _batch(rpm=[100.0, 6000.0])
    traj = jaxclear.simulate_batch(
        _build, params, T1, num_points=GRID, solver=STARVED
    )  # does not raise
    stats = traj.stats()
    print(f"batched stats: {stats}")
    assert stats["succeeded"] == [True, False]
    assert stats["t_final"][0] == pytest.approx(T1, rel=1e-12)
    assert stats["t_final"][1] < T1
    assert stats["num_steps"][1] == STEP_BUDGET
