"""Plots of a Trajectory: files written, non-empty PNGs, reference overlay."""

import pytest
from matplotlib.figure import Figure

import jaxclear
from jaxclear import plot

# Same horizon and number of output points as tests/test_cli.py: one compilation for both files.
RPM = 5000.0
REVOLUTIONS = 0.25
NUM_POINTS = 10
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def traj():
    mechanism = jaxclear.mechanisms.slider_crank(rpm=RPM)
    return jaxclear.simulate(mechanism, REVOLUTIONS * 60 / RPM, num_points=NUM_POINTS, solver="fast")


def test_save_standard_plots(traj, tmp_path):
    paths = plot.save_standard_plots(traj, tmp_path / "plots")
    names = sorted(p.name for p in paths)
    assert names == sorted(name for name, _, _ in plot.STANDARD_PLOTS)
    for path in paths:
        data = path.read_bytes()
        assert data.startswith(PNG_SIGNATURE), path
        assert len(data) > 5_000, path  # axes, labels and a curve, not a blank canvas
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
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["ideal joints", "clearance"]


def test_unknown_quantity(traj):
    with pytest.raises(ValueError, match="unknown quantity 'slider_jerk'"):
        plot.plot_vs_crank_angle(traj, "slider_jerk")
