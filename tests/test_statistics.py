"""Peaks and RMS values from the solver's steps (``Trajectory.extremes``,
``jaxclear.analysis.statistics``): independent of the output grid, right on the ideal mechanism,
restricted to the statistics window."""

import jax
import numpy as np
import pytest

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
from jaxclear.mechanisms import slider_crank

RPM = 5000.0
PERIOD = 60.0 / RPM
GRIDS = (181, 5001)
"""The output-grid sizes of the issue's check (a reported peak must change by < 1 % between them)."""
GRID_INDEPENDENT_RTOL = 1e-12
"""Saving at more instants does not change the solver's steps (diffrax interpolates the saved
values), so values taken from the steps agree to round-off."""


def _one_joint():
    return slider_crank(
        rpm=RPM,
        clearance_joints="B",
        friction_law=ModifiedCoulomb(0.01),
        contact_law=LankaraniNikravesh(),
    )


@pytest.fixture(scope="module")
def runs():
    mech = _one_joint()
    return {n: jaxclear.simulate(mech, PERIOD, num_points=n, solver="fast") for n in GRIDS}


def test_statistics_do_not_depend_on_the_output_grid(runs):
    coarse, fine = (jaxclear.analysis.statistics(runs[n]) for n in GRIDS)
    assert set(coarse) == set(fine)
    for name in coarse:
        a, b = float(coarse[name]), float(fine[name])
        print(f"{name}: {a:.9g} ({GRIDS[0]} points) {b:.9g} ({GRIDS[1]} points)")
        assert a == pytest.approx(b, rel=GRID_INDEPENDENT_RTOL, abs=1e-300)


def test_peak_force_from_steps_bounds_the_grid_peaks(runs):
    """The grid peak of a coarse grid misses the impact peaks; the steps' peak does not: the peak
    on a fine grid is within 1 % of it, the coarse grid's peak below it."""
    peak = float(runs[GRIDS[0]].extremes.normal_force_max["B"])
    grid = {n: float(np.max(np.asarray(runs[n].clearance["B"]["normal_force"]))) for n in GRIDS}
    print(f"peak F_N at B: steps {peak:.6g} N, grid {grid}")
    assert grid[GRIDS[0]] < 0.9 * peak  # a coarse grid misses the peak
    assert grid[GRIDS[1]] == pytest.approx(peak, rel=1e-2)
    assert float(runs[GRIDS[0]].extremes.penetration_max["B"]) > 0  # the journal hit the wall


def test_named_statistics(runs):
    stats = jaxclear.analysis.statistics(runs[GRIDS[0]])
    for name in (
        "B_peak_normal_force",
        "B_peak_penetration",
        "peak_slider_acceleration",
        "rms_slider_acceleration",
        "crank_torque_rms",
        "crank_torque_min",
        "crank_torque_max",
    ):
        assert np.isfinite(float(stats[name])), name
    assert 0 < float(stats["rms_slider_acceleration"]) < float(stats["peak_slider_acceleration"])
    assert float(stats["crank_torque_min"]) < 0 < float(stats["crank_torque_max"])
    assert float(stats["statistics_duration"]) == pytest.approx(PERIOD, rel=1e-12)


IDEAL_TORQUE_EXTREME = (
    138.52  # N m, docs/model.md §6 (computed independently), 5000 rpm, no gravity
)
IDEAL_SLIDER_ACCELERATION = 19419.0  # m/s², peak |ẍ| at outer dead centre, same source
IDEAL_RTOL = 5e-3
"""Step ends of the smooth ideal run are ~6° of crank angle apart, so the extremes between them
are missed by at most 1 − cos 3° ≈ 0.14 %; the references are given to 4–5 digits."""


def test_statistic_names_without_a_solve(runs):
    """``statistic_names`` gives the names ``statistics`` gives a run, without solving: here a
    clearance joint's; the ideal mechanism's in the next test."""
    traj = runs[GRIDS[0]]
    names = jaxclear.analysis.statistic_names(traj.mechanism)
    assert names == sorted(jaxclear.analysis.statistics(traj))
    assert "B_peak_normal_force" in names and "crank_torque_rms" in names


def test_ideal_extremes_match_the_reference():
    traj = jaxclear.simulate(
        slider_crank(rpm=RPM, gravity=False), PERIOD, num_points=GRIDS[0], solver="fast"
    )
    stats = jaxclear.analysis.statistics(traj)
    print({k: float(v) for k, v in stats.items()})
    assert sorted(stats) == jaxclear.analysis.statistic_names(traj.mechanism)
    assert float(stats["crank_torque_max"]) == pytest.approx(IDEAL_TORQUE_EXTREME, rel=IDEAL_RTOL)
    assert float(stats["crank_torque_min"]) == pytest.approx(-IDEAL_TORQUE_EXTREME, rel=IDEAL_RTOL)
    assert float(stats["peak_slider_acceleration"]) == pytest.approx(
        IDEAL_SLIDER_ACCELERATION, rel=IDEAL_RTOL
    )
    # RMS from the steps (trapezoidal) against the RMS of a fine uniform grid over one period
    torque = np.asarray(traj.input_torque)
    grid_rms = np.sqrt(np.mean(torque[:-1] ** 2))
    assert float(stats["crank_torque_rms"]) == pytest.approx(grid_rms, rel=1e-2)
    slider = np.asarray(traj.accelerations("slider"))[:, 0]  # the slider moves along x only
    grid_rms = np.sqrt(np.mean(slider[:-1] ** 2))
    assert float(stats["rms_slider_acceleration"]) == pytest.approx(grid_rms, rel=1e-2)


def test_statistics_window():
    """Values over [start, t1] only: after a start-up half period the first impact's peak is out."""
    mech = _one_joint()
    full = jaxclear.simulate(mech, PERIOD, num_points=GRIDS[0], solver="fast")
    late = jaxclear.simulate(
        mech, PERIOD, num_points=GRIDS[0], solver="fast", statistics_start=0.5 * PERIOD
    )
    assert float(late.extremes.duration) == pytest.approx(0.5 * PERIOD, rel=1e-9)
    t = np.asarray(full.t)
    force = np.asarray(full.clearance["B"]["normal_force"])
    assert float(late.extremes.normal_force_max["B"]) >= np.max(force[t >= 0.5 * PERIOD])
    assert float(late.extremes.normal_force_max["B"]) <= float(full.extremes.normal_force_max["B"])


SAME_RTOL = 1e-12
"""statistics of a stacked pair of trajectories under jit(vmap) vs eagerly on each: the same
arithmetic compiled apart (sums in another order); ``abs=1e-12`` for the statistics at round-off
level (constraint violations)."""


def test_statistics_under_jit_and_vmap():
    """Pure JAX: ``statistics`` under ``jax.jit(jax.vmap(...))`` over a stack of two runs equals
    its eager value on each run. The runs are the ideal mechanism's at two speeds, which share the
    compiled solve of ``test_ideal_extremes_match_the_reference`` (gravity is an array leaf). The
    extremes of vmapped, jitted solves themselves (one compilation more here) are checked against
    single runs by tests/test_ensemble.py's ``test_members_equal_their_single_runs`` (every
    statistic of each member, with a clearance joint)."""
    runs = [
        jaxclear.simulate(slider_crank(rpm=rpm), PERIOD, num_points=GRIDS[0], solver="fast")
        for rpm in (3000.0, 6000.0)
    ]
    stacked = jax.tree_util.tree_map(lambda *x: jax.numpy.stack(x), *runs)
    batched = jax.jit(jax.vmap(jaxclear.analysis.statistics))(stacked)
    for k, traj in enumerate(runs):
        single = jaxclear.analysis.statistics(traj)
        assert set(batched) == set(single)
        for name, value in single.items():
            assert float(batched[name][k]) == pytest.approx(
                float(value), rel=SAME_RTOL, abs=1e-12
            ), name
    assert float(batched["crank_torque_max"][1]) > 3.0 * float(batched["crank_torque_max"][0])
