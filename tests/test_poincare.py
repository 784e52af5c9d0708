"""Poincaré sections, bifurcation diagrams, phase portraits (jaxclear.studies._poincare)."""

import jax
import numpy as np
import pytest

import jaxclear
from jaxclear.analysis import distinct_points, phase_portrait
from jaxclear.studies import bifurcation_points, poincare_section, section_times

RPM = 5000.0
PERIOD = 60.0 / RPM
R, L = 0.05, 0.12  # crank and rod lengths of the benchmark slider-crank (docs/model.md §6)

SECTION_RTOL = 1e-5
"""Scatter of the ideal slider-crank's section points, relative to each signal's scale: its motion
is prescribed by the crank (no degree of freedom), so the points differ only by the solver's error
(Tsit5 at rtol 1e-6: 6e-7 of the peak speed, peak to peak over 5 revolutions) and the Baumgarte drift, which stays below it."""

SCALES = {"slider_x": R + L, "slider_v": 28.41, "slider_a": 19419.0, "crank_torque": 138.5}
"""Peak magnitudes of the ideal responses at 5000 rpm (docs/model.md §6)."""

SIGNALS = tuple(SCALES)


@pytest.fixture(scope="module")
def ideal():
    return jaxclear.mechanisms.slider_crank(rpm=RPM, clearance_joints="")


def test_ideal_slider_crank_has_a_single_point(ideal):
    section = poincare_section(ideal, revolutions=4, skip_revolutions=1, signals=SIGNALS)
    np.testing.assert_allclose(section["t"], PERIOD * np.arange(1, 5), rtol=1e-12)
    for name in SIGNALS:
        x = np.asarray(section[name])
        assert x.shape == (4,)
        tolerance = SECTION_RTOL * SCALES[name]
        assert np.ptp(x) < tolerance, name
        assert distinct_points(x, tolerance) == 1
    # phase 0: outer dead centre, slider at r + l, at rest
    assert float(section["slider_x"][0]) == pytest.approx(R + L, abs=SECTION_RTOL * (R + L))
    assert abs(float(section["slider_v"][0])) < SECTION_RTOL * SCALES["slider_v"]


def test_section_from_t1_phase_and_dense_output(ideal):
    """Counting points from t1; the section values at phase π/2 are interpolated from the dense
    output at exactly θ = 90° (slider speed −r ω there), though no saved grid holds that instant."""
    section = poincare_section(
        ideal, 5 * PERIOD + 1e-4, skip_revolutions=1, phase=np.pi / 2, signals=SIGNALS
    )
    assert section["slider_v"].shape == (4,)  # instants 1.25 T .. 4.25 T
    np.testing.assert_allclose(section["t"], PERIOD * (np.arange(1, 5) + 0.25), rtol=1e-12)
    omega = RPM * np.pi / 30
    np.testing.assert_allclose(
        section["slider_v"], -R * omega, rtol=0, atol=SECTION_RTOL * SCALES["slider_v"]
    )


@pytest.mark.parametrize("engine", ["refill", "lockstep"])
def test_bifurcation_points_equal_single_sections(ideal, engine):
    """A sweep over the crank speed: one chunk, refilled (each member's own section instants as
    its output times) or a vmapped lockstep solve, equals the loop of single sections, and each
    value's points sit at its own quarter revolution (slider speed −r ω(rpm))."""
    rpms = np.array([3000.0, 4000.0, 6000.0])
    diagram = bifurcation_points(
        ideal,
        "rpm",
        rpms,
        4,
        phase=np.pi / 2,
        signals=["slider_v"],
        settings=jaxclear.EnsembleSettings(chunk_size=4, engine=engine, lanes=2),
    )
    assert diagram.points["slider_v"].shape == (3, 4)
    assert diagram.succeeded.all()
    np.testing.assert_allclose(
        diagram.points["slider_v"],
        np.repeat(-R * rpms[:, None] * np.pi / 30, 4, axis=1),
        atol=SECTION_RTOL * SCALES["slider_v"],
    )
    np.testing.assert_allclose(diagram.times[:, 0], 60.0 / rpms * 1.25, rtol=1e-12)
    single = poincare_section(
        jaxclear.with_parameters(ideal, {"rpm": rpms[1]}),
        revolutions=4,  # 4 output points: the compilation of the tests above
        phase=np.pi / 2,
        signals=["slider_v"],
    )
    np.testing.assert_allclose(diagram.points["slider_v"][1], single["slider_v"], rtol=1e-9)
    x, y = diagram.scatter("slider_v")
    assert x.shape == y.shape == (12,)
    np.testing.assert_array_equal(diagram.distinct("slider_v", 1e-3), [1, 1, 1])


def test_section_times_trace_under_vmap(ideal):
    def times(rpm):
        return section_times(jaxclear.with_parameters(ideal, {"rpm": rpm}), 3, phase=np.pi)

    out = jax.vmap(times)(np.array([3000.0, 6000.0]))
    np.testing.assert_allclose(out[1], 60 / 6000 * np.array([1.5, 2.5, 3.5]), rtol=1e-12)


def test_distinct_points():
    assert distinct_points([1.0, 1.0 + 1e-9, 1.0], 1e-6) == 1
    np.testing.assert_array_equal(
        distinct_points([[1.0, 2.0, 1.0, 2.0], [0.0, 1.0, 2.0, 3.0], [np.nan] * 4], 0.1), [2, 4, 0]
    )
    with pytest.raises(ValueError, match="tolerance"):
        distinct_points([1.0], -1.0)


def test_phase_portrait(ideal):
    # 4 output points: the solve poincare_section compiled above
    traj = jaxclear.simulate(ideal, 3 * PERIOD, num_points=4, extremes=False)
    x, v = phase_portrait(traj, "slider_x", "slider_v", start=PERIOD)
    assert x.shape == v.shape == (3,)
    np.testing.assert_allclose(x, R + L, rtol=SECTION_RTOL)  # a revolution apart: dead centre
    with pytest.raises(ValueError, match="not signals"):
        phase_portrait(traj, "slider_x", "piston_v")
    with pytest.raises(ValueError, match="after the last"):
        phase_portrait(traj, "slider_x", "slider_v", start=1.0)


def test_argument_errors(ideal):
    with pytest.raises(ValueError, match="t1 .* or revolutions"):
        poincare_section(ideal)
    with pytest.raises(ValueError, match="no section point"):
        poincare_section(ideal, 0.5 * PERIOD)
    with pytest.raises(ValueError, match="ends before the last"):
        poincare_section(ideal, 2 * PERIOD, revolutions=3)
    with pytest.raises(ValueError, match="skip_revolutions"):
        poincare_section(ideal, revolutions=2, skip_revolutions=-1)
    with pytest.raises(ValueError, match="revolutions"):
        poincare_section(ideal, revolutions=0)
    with pytest.raises(ValueError, match="phase"):
        poincare_section(ideal, revolutions=2, phase=7.0)
    with pytest.raises(ValueError, match="signals"):
        poincare_section(ideal, revolutions=2, signals=["B_ecc_x"])
    with pytest.raises(TypeError, match="sequence"):
        poincare_section(ideal, revolutions=2, signals="slider_v")
    free = jaxclear.mechanisms.four_bar(rpm=None)
    with pytest.raises(ValueError, match="constant-speed driver"):
        poincare_section(free, revolutions=2)
    with pytest.raises(ValueError, match="not a parameter"):
        bifurcation_points(ideal, "crank_speed", [1.0], 2)
    with pytest.raises(ValueError, match="values"):
        bifurcation_points(ideal, "rpm", [[1.0]], 2)
    with pytest.raises(ValueError, match="revolutions"):
        jax.vmap(
            lambda rpm: poincare_section(jaxclear.with_parameters(ideal, {"rpm": rpm}), 2 * PERIOD)[
                "slider_v"
            ]
        )(np.array([3000.0]))
