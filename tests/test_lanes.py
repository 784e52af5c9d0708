"""Lane refilling (``jaxclear.solve.solve_members``, issue 25 part 1): each member's result
equals its own ``simulate``, members of very different cost share the lanes, a lane whose member
is done takes the next one, and new values reuse the compiled loop.

One compiled loop for the module: the ideal benchmark slider–crank (its compilation is the
cheapest), six members of different crank speeds, end times and statistics windows on three
lanes, Tsit5 with a step budget that one member exceeds. The reference is ``simulate`` of each
member alone with the same settings (one more compilation: ``t1`` and ``statistics_start`` are
traced). A clearance-joint comparison (case a of the benchmarks, short horizon) is ``slow``.
"""

import math

import diffrax
import jax
import numpy as np
import pytest

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
from jaxclear.mechanisms import slider_crank
from jaxclear.solve import SolverConfig, solve_members

MAX_STEPS = 64
"""Step budget: the members below take 6–39 steps to their t1 (6–9 of them rejected, shrinking
the 0.01 s first step); member ``FAILING`` (0.04 s at 6000 rpm, four revolutions) runs out of
steps at about 0.023 s."""
SOLVER = SolverConfig(method="tsit5", max_steps=MAX_STEPS)
LANES = 3
RPM = np.array([3000.0, 5000.0, 6000.0, 4000.0, 6000.0, 5500.0])
T1 = np.array([0.004, 0.012, 0.006, 0.02, 0.04, 0.009])  # s; member 4 exceeds MAX_STEPS
START = 0.25 * T1  # each member's statistics window starts a quarter of the way in
FAILING = 4

STATE_RTOL = 1e-12
"""y(t1) against its own ``simulate``, relative to the largest entry of y: the two programs are
compiled apart (one vmapped over lanes), so XLA may order floating-point operations differently;
measured: at most 8e-15 (rounding level; 0 for some members)."""
TIME_RTOL = 1e-9
"""Where a solve stopped short of t1 (the member out of steps) and the step times inside the
extremes: a step's size comes from the error estimate, a difference of nearly equal numbers,
which magnifies rounding differences by about 1/rtol (1e6); measured: < 3e-12 relative."""
STOPPED_STATE_RTOL = 1e-9
"""y where a solve stopped short of t1, relative to the largest entry of y: it is taken at that
stop time, which carries the step sizes' rounding (``TIME_RTOL``); measured: 1e-11."""
EXTREMES_RTOL = 1e-9
"""Peaks and RMS integrals, relative to the largest entry of each quantity: taken at the step
ends and midpoints and interpolated between them, so they carry the step times' rounding;
measured: < 2e-11."""
CONSTRAINT_ATOL = 1e-12
"""m: the constraint violation is itself rounding (1e-16 – 1e-8 m from the Baumgarte terms);
measured difference < 1e-15 m."""
BACKEND_COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"  # one per XLA compilation


def _mechanism():
    return slider_crank(rpm=5000.0)


def _member_mechanism(rpm):
    return jaxclear.with_parameters(_mechanism(), {"rpm": rpm})


def _solve(rpm, t1, start):
    # the members assembled as simulate assembles them (outside the compiled solve, which is then
    # smaller: the loop's own assembly is compared in the slow test)
    y0 = np.stack([np.asarray(jaxclear.assemble(_member_mechanism(r))) for r in rpm])
    return solve_members(
        _mechanism(),
        {"rpm": rpm},
        t1,
        solver=SOLVER,
        lanes=LANES,
        statistics_start=start,
        y0=y0,
    )


def _alone(rpm, t1, start):
    return jaxclear.simulate(
        _member_mechanism(rpm),
        t1,
        num_points=2,
        solver=SOLVER,
        statistics_start=start,
        throw=False,
    )


@pytest.fixture(scope="module")
def lanes():
    return _solve(RPM, T1, START)


@pytest.fixture(scope="module")
def alone():
    return [_alone(RPM[i], T1[i], START[i]) for i in range(len(RPM))]


def _member(tree, i):
    return jax.tree_util.tree_map(lambda x: x[i], tree)


def _assert_same_member(lanes, i, ref):
    assert int(lanes.num_steps[i]) == int(ref.num_steps)
    assert int(lanes.num_accepted_steps[i]) == int(ref.num_accepted_steps)
    assert int(lanes.num_rejected_steps[i]) == int(ref.num_rejected_steps)
    assert int(lanes.result[i]) == int(ref.result._value)
    assert int(lanes.input_error[i]) == int(ref.input_error)
    np.testing.assert_allclose(float(lanes.t_final[i]), float(ref.t_final), rtol=TIME_RTOL)
    y, y_ref = np.asarray(lanes.y_final[i]), np.asarray(ref.y_final)
    rtol = STATE_RTOL if bool(ref.succeeded) else STOPPED_STATE_RTOL
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=rtol * np.max(np.abs(y_ref)))
    mine, theirs = _member(lanes.extremes, i), ref.extremes
    for name in (
        "duration",
        "acceleration_min",
        "acceleration_max",
        "body_acceleration_max",
        "input_torque_min",
        "input_torque_max",
        "input_torque_square_integral",
        "body_acceleration_square_integral",
    ):
        a, b = np.asarray(getattr(mine, name)), np.asarray(getattr(theirs, name))
        scale = np.max(np.abs(b))
        np.testing.assert_allclose(a, b, rtol=0, atol=EXTREMES_RTOL * scale, err_msg=name)
    np.testing.assert_allclose(
        float(mine.constraint_violation_max),
        float(theirs.constraint_violation_max),
        rtol=0,
        atol=CONSTRAINT_ATOL,
    )
    np.testing.assert_allclose(
        np.asarray(mine.times), np.asarray(theirs.times), rtol=TIME_RTOL, atol=0
    )


def test_each_member_equals_its_own_simulate(lanes, alone):
    for i, ref in enumerate(alone):
        _assert_same_member(lanes, i, ref)


def test_members_end_at_their_own_t1_or_fail_alone(lanes, alone):
    ok = np.asarray(lanes.succeeded)
    assert ok.tolist() == [i != FAILING for i in range(len(RPM))]
    np.testing.assert_array_equal(np.asarray(lanes.t_final)[ok], T1[ok])  # clipped to t1 exactly
    assert int(lanes.result[FAILING]) == int(diffrax.RESULTS.max_steps_reached._value)
    assert int(lanes.num_steps[FAILING]) == MAX_STEPS
    assert float(lanes.t_final[FAILING]) < T1[FAILING]
    # the window of each member is its own: the duration covered is t_final - start
    np.testing.assert_allclose(
        np.asarray(lanes.extremes.duration), np.asarray(lanes.t_final) - START, rtol=1e-12
    )


def test_lanes_refill_instead_of_waiting(lanes):
    steps = np.asarray(lanes.num_steps)
    iterations = int(lanes.iterations)
    # never below a perfect packing of the steps into the lanes
    assert iterations >= math.ceil(steps.sum() / LANES)
    # lockstep chunks of the same size in member order wait for their slowest member
    padded = np.concatenate([steps, np.zeros(-len(steps) % LANES, dtype=steps.dtype)])
    lockstep = int(padded.reshape(-1, LANES).max(axis=1).sum())
    assert iterations < lockstep
    assert float(lanes.lane_use) > steps.sum() / (lockstep * LANES)


def test_new_values_reuse_the_compiled_loop(lanes, alone):
    compilations = []

    def listener(event, duration, **kwargs):
        if event == BACKEND_COMPILE_EVENT:
            compilations.append(duration)

    rpm, t1 = RPM[::-1].copy(), 0.5 * T1
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        again = _solve(rpm, t1, 0.0)
        ref = _alone(rpm[1], t1[1], 0.0)
        jax.block_until_ready(again.y_final)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert not compilations
    _assert_same_member(again, 1, ref)
    assert not np.allclose(np.asarray(again.y_final), np.asarray(lanes.y_final))


@pytest.mark.parametrize(
    "values, t1, options, match",
    [
        ({}, 0.01, {}, "values is empty"),
        ({"rpm": [1.0, 2.0], "crank_mass": [0.3]}, 0.01, {}, "one length"),
        ({"rpm": [5000.0]}, 0.01, {"lanes": 0}, "lanes must be a positive integer"),
        ({"rpm": [5000.0]}, 0.0, {}, "t1 must be greater than t0"),
        ({"rpm": [5000.0, 4000.0]}, [0.01], {}, "t1 must be a finite number"),
        ({"rpm": [5000.0]}, 0.01, {"y0": np.zeros((1, 3))}, r"y0 must have shape \(N, state\)"),
    ],
)
def test_bad_input_names_the_argument(values, t1, options, match):
    with pytest.raises(ValueError, match=match):
        solve_members(_mechanism(), values, t1, **options)


def test_unknown_parameter_is_a_model_error():
    with pytest.raises(jaxclear.ModelError, match="rmp"):
        solve_members(_mechanism(), {"rmp": [5000.0]}, 0.01)


@pytest.mark.slow  # two compilations of the clearance-joint solve (~25 s)
def test_clearance_members_equal_their_own_simulate_before_the_contacts_fork():
    """Case a of the benchmarks (clearance joint B, Lankarani–Nikravesh, modified Coulomb) over
    0.6 ms: the first impact of each member (onset at 0.21–0.24 ms) and what follows it. The
    impact sequence magnifies rounding (docs/model.md §5b): over a revolution the members' steps
    part; this short horizon is compared as the ideal joints are."""
    mechanism = slider_crank(
        rpm=5000.0,
        clearance_joints="B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(0.01),
        gravity=False,
    )
    clearance = 5e-4 * np.linspace(0.9, 1.1, 5)
    t1 = 6e-4
    config = jaxclear.recommended_solver(mechanism)
    got = solve_members(
        mechanism, {"B.clearance": clearance}, t1, solver=config, lanes=2, contact_events=8
    )
    assert np.all(np.asarray(got.succeeded))
    assert np.all(np.asarray(got.extremes.event_count["B"]) >= 1)  # an impact in every member
    for i, c in enumerate(clearance):
        member = jaxclear.with_parameters(mechanism, {"B.clearance": c})
        ref = jaxclear.simulate(member, t1, num_points=2, solver=config, contact_events=8)
        assert int(got.num_steps[i]) == int(ref.num_steps)
        y, y_ref = np.asarray(got.y_final[i]), np.asarray(ref.y_final)
        np.testing.assert_allclose(y, y_ref, rtol=0, atol=STATE_RTOL * np.max(np.abs(y_ref)))
        np.testing.assert_allclose(
            float(got.extremes.normal_force_max["B"][i]),
            float(ref.extremes.normal_force_max["B"]),
            rtol=EXTREMES_RTOL,
        )
