"""Plots of a Trajectory: files written, non-empty PNGs, reference overlay, clearance-joint plots."""

import numpy as np
import pytest
from matplotlib.figure import Figure

import jaxclear
from jaxclear import plot
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import NoFriction

# Same horizon, number of output points and solver as tests/test_cli.py, and the same mechanisms as
# its ideal and cheap clearance runs: no compilation of its own when both files run in one process.
RPM = 5000.0
REVOLUTIONS = 0.25
NUM_POINTS = 91
CLEARANCE = 5e-4  # m
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _simulate(mechanism):
    return jaxclear.simulate(
        mechanism, REVOLUTIONS * 60 / RPM, num_points=NUM_POINTS, solver="fast"
    )


@pytest.fixture(scope="module")
def traj():
    return _simulate(jaxclear.mechanisms.slider_crank(rpm=RPM))


@pytest.fixture(scope="module")
def clearance_traj():
    mechanism = jaxclear.mechanisms.slider_crank(
        rpm=RPM,
        clearance_joints="B",
        clearance=CLEARANCE,
        contact_law=LankaraniNikravesh(),
        friction_law=NoFriction(),
    )
    return _simulate(mechanism)


def _check_png(path):
    data = path.read_bytes()
    assert data.startswith(PNG_SIGNATURE), path
    assert len(data) > 5_000, path  # axes, labels and a curve, not a blank canvas


def test_save_standard_plots(traj, tmp_path):
    paths = plot.save_standard_plots(traj, tmp_path / "plots")
    names = sorted(p.name for p in paths)
    assert names == sorted(name for name, _, _ in plot.STANDARD_PLOTS)
    for path in paths:
        _check_png(path)
    assert not list((tmp_path / "plots").glob(".*")), "temporary files left behind"


def test_save_standard_plots_with_clearance(clearance_traj, traj, tmp_path):
    paths = plot.save_standard_plots(clearance_traj, tmp_path / "plots", reference=traj)
    names = sorted(p.name for p in paths)
    assert names == sorted(
        [name for name, _, _ in plot.STANDARD_PLOTS] + ["normal_force.png", "orbit_B.png"]
    )
    for path in paths:
        _check_png(path)
    assert not list((tmp_path / "plots").glob(".*")), "temporary files left behind"


def test_plot_functions_return_figures(traj):
    fig = plot.plot_vs_crank_angle(traj, "slider_a")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "Crank angle (°)"
    assert "m/s²" in ax.get_ylabel()
    assert "5000 rpm" in ax.get_title()
    fig = plot.plot_constraint_violation(traj)
    assert fig.axes[0].get_yscale() == "log"


def test_reference_is_drawn_behind(traj):
    fig = plot.plot_vs_crank_angle(traj, "crank_torque", reference=traj, label="clearance")
    lines = fig.axes[0].get_lines()
    assert len(lines) == 2
    reference, main = lines
    assert reference.get_zorder() < main.get_zorder()
    assert reference.get_linestyle() == "--"
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["ideal joints", "clearance"]


def test_ideal_reference_behind_clearance_run(clearance_traj, traj):
    """As ``jaxclear run`` draws it: the ideal-joint curve dashed grey behind the clearance run."""
    fig = plot.plot_vs_crank_angle(clearance_traj, "slider_a", reference=traj)
    reference, main = fig.axes[0].get_lines()
    assert reference.get_linestyle() == "--" and reference.get_zorder() < main.get_zorder()
    np.testing.assert_allclose(
        reference.get_ydata(), np.asarray(traj.accelerations("slider"))[:, 0]
    )
    np.testing.assert_allclose(
        main.get_ydata(), np.asarray(clearance_traj.accelerations("slider"))[:, 0]
    )
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["ideal joints", "this run"]


def test_orbit_plot(clearance_traj):
    fig = plot.plot_orbit(clearance_traj, "B")
    ax = fig.axes[0]
    circle, orbit, contact = ax.get_lines()
    radius = np.hypot(circle.get_xdata(), circle.get_ydata())
    np.testing.assert_allclose(radius, CLEARANCE * 1e3)  # mm
    out = clearance_traj.clearance["B"]
    np.testing.assert_allclose(orbit.get_xdata(), np.asarray(out["ecc_x"]) * 1e3)
    assert len(contact.get_xdata()) == int(np.sum(np.asarray(out["penetration"]) > 0)) > 0
    assert ax.get_xlabel() == "Eccentricity x (mm)"
    assert "c = 0.5 mm" in ax.get_title()


def test_contact_force_plot(clearance_traj):
    fig = plot.plot_contact_forces(clearance_traj)
    ax = fig.axes[0]
    line, peak = ax.get_lines()
    np.testing.assert_allclose(
        line.get_ydata(), np.asarray(clearance_traj.clearance["B"]["normal_force"]) / 1e3
    )  # kN
    # the dotted line: the peak from the solver's steps, at or above every saved instant
    peak_kn = float(clearance_traj.extremes.normal_force_max["B"]) / 1e3
    np.testing.assert_allclose(peak.get_ydata(), [peak_kn, peak_kn])
    assert peak_kn >= 0.999 * np.max(
        line.get_ydata()
    )  # 0.1 %: the sampled peak estimate (tests/test_statistics.py)
    assert "kN" in ax.get_ylabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0] == "joint B" and labels[1].startswith("joint B peak from the solver's steps")


def test_unknown_quantity(traj):
    with pytest.raises(ValueError, match="unknown quantity 'slider_jerk'"):
        plot.plot_vs_crank_angle(traj, "slider_jerk")


def test_window_keeps_the_later_instants(clearance_traj):
    from jaxclear.solve import window

    t = np.asarray(clearance_traj.t)
    start = t[NUM_POINTS // 2]
    kept = window(clearance_traj, start)
    np.testing.assert_array_equal(np.asarray(kept.t), t[NUM_POINTS // 2 :])
    np.testing.assert_array_equal(
        np.asarray(kept.q), np.asarray(clearance_traj.q)[NUM_POINTS // 2 :]
    )
    np.testing.assert_array_equal(
        np.asarray(kept.clearance["B"]["normal_force"]),
        np.asarray(clearance_traj.clearance["B"]["normal_force"])[NUM_POINTS // 2 :],
    )
    # the plots of the kept window: x from the window's first angle, y-range from the window's values
    fig = plot.plot_vs_crank_angle(kept, "slider_a")
    (line,) = fig.axes[0].get_lines()
    angle = np.degrees(np.asarray(clearance_traj.coordinates("crank"))[:, 2])
    assert line.get_xdata()[0] == pytest.approx(angle[NUM_POINTS // 2])
    low, high = fig.axes[0].get_ylim()
    values = np.asarray(kept.accelerations("slider"))[:, 0]
    span = values.max() - values.min()
    assert (
        low >= values.min() - 0.1 * span and high <= values.max() + 0.1 * span
    )  # matplotlib's 5 % margins


@pytest.fixture(scope="module")
def four_bar_traj():
    mechanism = jaxclear.mechanisms.four_bar()
    return jaxclear.simulate(mechanism, 0.25 * 60 / 60.0, num_points=NUM_POINTS, solver="fast")


def test_standard_plots_follow_the_mechanism(four_bar_traj, tmp_path):
    paths = plot.save_standard_plots(four_bar_traj, tmp_path)
    names = sorted(p.name for p in paths)
    assert names == sorted(
        [
            "crank_torque.png",
            "coupler_angle.png",
            "coupler_angular_acceleration.png",
            "rocker_angle.png",
            "rocker_angular_acceleration.png",
            "constraint_violation.png",
            "joint_forces.png",
        ]
    )
    for path in paths:
        _check_png(path)
    fig = plot.plot_vs_crank_angle(four_bar_traj, "rocker_alpha")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "Crank angle (°)"
    assert ax.get_ylabel() == "Rocker angular acceleration (rad/s²)"
    fig = plot.plot_joint_forces(four_bar_traj)
    lines = fig.axes[0].get_lines()
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == [
        "joint O2",
        "joint A",
        "joint B",
        "joint O4",
    ]
    np.testing.assert_allclose(
        lines[3].get_ydata(), np.linalg.norm(np.asarray(four_bar_traj.joint_force("O4")), axis=1)
    )


def test_fit_title_stays_inside_the_figure():
    """Three estimates in fit.png's title: on one line they ran past both edges of the figure
    (a result of the 1000 rpm three-unknown fit); they now break onto lines that fit."""
    from types import SimpleNamespace

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from jaxclear.plot import plot_fit

    def estimate(value, std, unit):
        return SimpleNamespace(value=value, std=std, unit=unit)

    t = np.linspace(0.0, 0.03, 20)
    result = SimpleNamespace(
        measured={"slider_x": t},
        fitted={"slider_x": t},
        t=t,
        window_end=0.015,
        parameters={
            "A.clearance": estimate(0.0002997035582871541, 2.0971666736501104e-07, "m"),
            "A.restitution": estimate(0.7513800684520329, 0.0009018169836597218, ""),
            "A.friction_coefficient": estimate(0.050022060596130395, 2.5709366782594948e-05, ""),
        },
        success=True,
    )
    fig = plot_fit(result)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    box = fig._suptitle.get_window_extent(canvas.get_renderer())
    assert box.x0 >= 0 and box.x1 <= fig.bbox.width
