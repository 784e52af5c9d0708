"""Lane refilling (``jaxclear.solve.solve_members``, issue 25 part 1): each member's result
equals its own ``simulate`` (its saved states on the output grid and its ``Trajectory`` too),
members of very different cost share the lanes, a lane whose member is done takes the next one,
and new values reuse the compiled loop; ``run_ensemble`` on refilled lanes
(``EnsembleSettings(engine="refill")``) gives each member the statistics of its own ``simulate``,
resumes across engines and replays a member from its own program.

One compiled loop for the module: the ideal benchmark slider–crank (its compilation is the
cheapest), six members of different crank speeds, end times and statistics windows on three
lanes, Tsit5 with a step budget that one member exceeds. The reference is ``simulate`` of each
member alone with the same settings (one more compilation: ``t1`` and ``statistics_start`` are
traced), shared by the refilled ensemble's members (same output-point count; one compilation of
the refilled chunk). A clearance-joint comparison (case a of the benchmarks, short horizon) is
``slow``, and so is the comparison of the refilled with the lockstep engine
(tests/test_refill_engine.py).
"""

import math

import diffrax
import jax
import numpy as np
import pytest
from cases import one_joint_b

import jaxclear
from jaxclear.mechanisms import slider_crank
from jaxclear.solve import SolverConfig, solve_members
from jaxclear.studies import EnsembleSettings, replay_member

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
TS = np.linspace(0.0, 0.04, 33)
"""s: the output grid of all members, clipped to each member's t1 (several points at t1 for the
short members; the failing member's points after its stop stay inf, as in ``simulate``)."""

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
SAVED_RTOL = 1e-12
"""Saved states against their own ``simulate``'s, relative to the largest entry: the same steps
and the same dense output (diffrax's interpolation of each step), evaluated in a program vmapped
over lanes, which may round differently; measured: 0 (bitwise equal, every member)."""
OUTPUT_RTOL = 1e-12
"""Accelerations, torque and multipliers at the saved states (``MemberSolutions.trajectories``)
against ``simulate``'s, relative to the largest entry of each: the same states, the outputs
evaluated by programs compiled apart; measured: at most 2.4e-15."""
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
        ts=TS,
    )


def _alone(rpm, t1, start):
    return jaxclear.simulate(
        _member_mechanism(rpm),
        t1,
        ts=np.minimum(TS, t1),
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


def _states(traj):
    return np.concatenate(
        [np.asarray(traj.q), np.asarray(traj.qd), np.asarray(traj.internal_state)], axis=1
    )


def test_saved_states_and_trajectories_equal_their_own_simulate(lanes, alone):
    trajectories = lanes.trajectories()
    for i, ref in enumerate(alone):
        np.testing.assert_array_equal(np.asarray(lanes.ts[i]), np.minimum(TS, T1[i]))
        ys, y_ref = np.asarray(lanes.ys[i]), _states(ref)
        reached = np.isfinite(y_ref).all(axis=1)
        assert reached.all() == (i != FAILING)
        assert not np.isfinite(ys[~reached]).any()  # not reached: inf, as in simulate
        scale = np.max(np.abs(y_ref[reached]))
        rtol = SAVED_RTOL if bool(ref.succeeded) else STOPPED_STATE_RTOL
        np.testing.assert_allclose(ys[reached], y_ref[reached], rtol=0, atol=rtol * scale)
        traj = trajectories.member(i)
        assert int(traj.num_steps) == int(ref.num_steps)
        assert bool(traj.succeeded) == bool(ref.succeeded)
        np.testing.assert_array_equal(np.asarray(traj.y_final), np.asarray(lanes.y_final[i]))
        np.testing.assert_array_equal(_states(traj), ys)
        for name in ("qdd", "input_torque", "multipliers"):
            a, b = np.asarray(getattr(traj, name))[reached], np.asarray(getattr(ref, name))[reached]
            scale = np.max(np.abs(b))
            np.testing.assert_allclose(a, b, rtol=0, atol=OUTPUT_RTOL * scale, err_msg=name)


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
        ({"rpm": [5000.0]}, 0.01, {"ts": [0.005, 0.001]}, "ts must be .* increasing"),
        (
            {"rpm": [5000.0]},
            0.01,
            {"ts": np.zeros((2, 2))},
            r"ts must be a non-empty \(T,\) array, or \(N, T\)",
        ),
    ],
)
def test_bad_input_names_the_argument(values, t1, options, match):
    with pytest.raises(ValueError, match=match):
        solve_members(_mechanism(), values, t1, **options)


def test_unknown_parameter_is_a_model_error():
    with pytest.raises(jaxclear.ModelError, match="rmp"):
        solve_members(_mechanism(), {"rmp": [5000.0]}, 0.01)


ENSEMBLE = {
    "rpm": np.array([5000.0, 4000.0, 6000.0, 5000.0, 5e5]),
    "crank_mass": np.array([0.3, 0.4, 0.35, -1.0, 0.3]),
}
"""``run_ensemble``'s members: member 3's crank mass is not admissible (never solved), member 4
(5e5 rpm) runs out of steps; in chunks of ``ENSEMBLE_CHUNK``, the second holding one member (the
refilled chunk's padding rows are not solved)."""
ENSEMBLE_T1, ENSEMBLE_START, ENSEMBLE_CHUNK = 0.012, 0.003, 4
ENSEMBLE_RTOL = 1e-10
"""A refilled ensemble member's statistics against its own ``simulate``, relative: the ensemble
assembles each member inside its compiled solve, ``simulate`` on the host (rounding-level
differences in y0, which the step-size control magnifies, ``TIME_RTOL``); measured: at most
4.2e-13 (the peak torque at 6000 rpm). The constraint violation is compared absolutely
(``CONSTRAINT_ATOL``; measured 4.4e-16 m)."""


def _ensemble_settings(engine, **kw):
    return EnsembleSettings(
        chunk_size=ENSEMBLE_CHUNK,
        devices=jax.local_devices()[:1],
        progress=False,
        engine=engine,
        lanes=LANES,
        **kw,
    )


def _ensemble_options():
    return dict(statistics_start=ENSEMBLE_START, num_points=len(TS), solver=SOLVER)


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory):
    out = tmp_path_factory.mktemp("refill")
    settings = _ensemble_settings("refill", out=out)
    result = jaxclear.run_ensemble(
        _mechanism(), ENSEMBLE, ENSEMBLE_T1, settings=settings, **_ensemble_options()
    )
    return result, out


def _window_rms(t, x, start):
    """RMS over t >= start, trapezoidal rule on the grid (as the ensemble's torque_fluctuation)."""
    w = (t >= start).astype(float)
    seg = 0.5 * (w[1:] + w[:-1]) * np.diff(t)
    mean = np.sum(seg * 0.5 * (x[1:] + x[:-1])) / np.sum(seg)
    x = x - mean
    return np.sqrt(np.sum(seg * 0.5 * (x[1:] ** 2 + x[:-1] ** 2)) / np.sum(seg))


def test_refilled_ensemble_members_equal_their_own_simulate(ensemble):
    got, _ = ensemble
    assert "outside its admissible range" in got.messages[3] and got.num_steps[3] == 0
    assert "solve failed" in got.messages[4] and got.num_steps[4] == MAX_STEPS
    ts = np.linspace(0.0, ENSEMBLE_T1, len(TS))
    for i in range(3):
        values = {k: v[i] for k, v in ENSEMBLE.items()}
        ref = jaxclear.simulate(
            jaxclear.with_parameters(_mechanism(), values),
            ENSEMBLE_T1,
            ts=ts,  # the compiled program of ``_alone``
            solver=SOLVER,
            statistics_start=ENSEMBLE_START,
        )
        assert got.status[i] == "ok" and got.num_steps[i] == int(ref.num_steps)
        expected = {k: float(v) for k, v in jaxclear.analysis.statistics(ref).items()}
        tau = np.asarray(ref.input_torque)
        expected["torque_fluctuation"] = _window_rms(ts, tau, ENSEMBLE_START)  # the saved grid
        assert set(expected) == set(got.statistics)
        for name, value in expected.items():
            mine = got.statistics[name][i]
            if name == "max_constraint_violation":  # rounding itself
                assert mine == pytest.approx(value, rel=0, abs=CONSTRAINT_ATOL), i
            else:
                assert mine == pytest.approx(value, rel=ENSEMBLE_RTOL, abs=0), (i, name)


def test_refilled_ensemble_resumes_and_replays_a_member(ensemble):
    got, out = ensemble
    # every member is on disk: a lockstep run with the same arguments solves none of them
    again = jaxclear.run_ensemble(
        _mechanism(),
        ENSEMBLE,
        ENSEMBLE_T1,
        settings=_ensemble_settings("lockstep", out=out),
        **_ensemble_options(),
    )
    assert again.messages == got.messages
    for name, mine in got.statistics.items():
        np.testing.assert_array_equal(again.statistics[name], mine, err_msg=name)
    member = 2
    replay = replay_member(
        _mechanism(),
        ENSEMBLE,
        ENSEMBLE_T1,
        member,
        num_steps=got.num_steps,
        settings=_ensemble_settings("refill"),
        **_ensemble_options(),
    )
    assert replay.engine == "refill" and replay.exact_chunk
    assert replay.row["num_steps"] == got.num_steps[member]
    for name, value in replay.statistics.items():
        assert value == got.statistics[name][member], name  # bitwise: the run's own program
    traj = replay.trajectory
    assert traj.t.shape == TS.shape and bool(traj.succeeded)
    mass = float(jaxclear.get_parameter(traj.mechanism, "crank_mass"))
    assert mass == ENSEMBLE["crank_mass"][member]  # the member's own mechanism
    torque = replay.trajectory_statistics["crank_torque_rms"]
    assert torque == pytest.approx(got.statistics["crank_torque_rms"][member], rel=1e-12)


@pytest.mark.slow  # two compilations of the clearance-joint solve (~25 s)
def test_clearance_members_equal_their_own_simulate_before_the_contacts_fork():
    """Case a of the benchmarks (clearance joint B, Lankarani–Nikravesh, modified Coulomb) over
    0.6 ms: the first impact of each member (onset at 0.21–0.24 ms) and what follows it. The
    impact sequence magnifies rounding (docs/model.md §5b): over a revolution the members' steps
    part; this short horizon is compared as the ideal joints are."""
    mechanism = one_joint_b()
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


@pytest.mark.slow  # two compilations of the clearance-joint solve (~20 s)
def test_saved_states_in_offset_form_equal_their_own_simulate():
    """Lawson–Tsit5 integrates the impact memory in offset form (``_Program.offset``): the saved
    states are converted back as ``simulate`` converts them. Case a of the benchmarks over 0.6 ms
    (the first impact of each member); measured: at most 9e-25 of the largest entry."""
    mechanism = one_joint_b()
    config = SolverConfig(method="lawson-tsit5")
    clearance, t1 = 5e-4 * np.array([0.9, 1.0, 1.1]), 6e-4
    ts = np.linspace(0.0, t1, 25)
    members = [jaxclear.with_parameters(mechanism, {"B.clearance": c}) for c in clearance]
    y0 = np.stack([np.asarray(jaxclear.assemble(m)) for m in members])
    got = solve_members(
        mechanism,
        {"B.clearance": clearance},
        t1,
        solver=config,
        lanes=2,
        contact_events=8,
        y0=y0,
        ts=ts,
    )
    assert np.all(np.asarray(got.extremes.event_count["B"]) >= 1)  # an impact in every member
    for i, member in enumerate(members):
        ref = jaxclear.simulate(member, t1, ts=ts, solver=config, contact_events=8)
        assert int(got.num_steps[i]) == int(ref.num_steps)
        y_ref = _states(ref)
        assert np.max(np.abs(y_ref[:, -1])) > 1.0  # the memory row holds an impact velocity
        np.testing.assert_allclose(
            np.asarray(got.ys[i]), y_ref, rtol=0, atol=SAVED_RTOL * np.max(np.abs(y_ref))
        )
