"""Plots of a translational clearance joint (docs/model.md §2c): the slider's tilt and lateral
offset, the four corner gaps and the four corner normal forces, against the crank angle.

The horizontal axis is the driven body's angle for a driven mechanism, the crank's angle for a
free slider–crank (a body named ``crank``), time otherwise. Quantities come from
``Trajectory.clearance[joint]`` (``TranslationalClearanceOutputs``).
"""

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..io._columns import translational_clearance_joint_names
from ..model._translational_clearance import CORNER_NAMES
from ._common import DPI, _new_axes, save_figure


def _joint(traj, joint: str | None):
    names = translational_clearance_joint_names(traj)
    if not names:
        raise ValueError(
            "the trajectory has no translational clearance joint "
            "(Mechanism.translational_clearance_joints); nothing to plot."
        )
    if joint is None:
        return names[0], traj.mechanism.translational_clearance_joints[0]
    if joint not in names:
        raise ValueError(
            f"{joint!r} is not a translational clearance joint of the trajectory; "
            f"choose one of {', '.join(names)}."
        )
    return joint, traj.mechanism.translational_clearance_joints[names.index(joint)]


def _abscissa(traj) -> tuple[np.ndarray, str]:
    """(x values, label): driven angle, else the crank's angle, in degrees; else time in ms."""
    mech = traj.mechanism
    body = mech.driver.body if mech.driver is not None else None
    if body is None and "crank" in mech.body_names:
        body = "crank"
    if body is None:
        return np.asarray(traj.t, dtype=float) * 1e3, "Time (ms)"
    phi = np.asarray(traj.coordinates(body))[:, 2]
    return np.degrees(np.unwrap(phi)), f"{body.capitalize()} angle (°)"


def plot_slider_tilt(traj, joint: str | None = None, *, ax=None) -> Figure:
    """Slider tilt θ (mrad) and lateral offset y/c of a translational clearance joint against the
    crank angle; the dashed lines mark |y/c| = 1, the guide faces.

    Args:
        traj: a single ``Trajectory``.
        joint: the joint's name (default: the first translational clearance joint).
        ax: optional axes to draw the tilt into (the offset goes on a twin axis).
    """
    name, element = _joint(traj, joint)
    out = traj.clearance[name]
    x, xlabel = _abscissa(traj)
    c = float(element.clearance)
    fig, ax = _new_axes(ax)
    ax.plot(x, np.asarray(out["tilt"]) * 1e3, color="C0", linewidth=1.0, label="tilt θ")
    ax.set_ylabel("Slider tilt θ (mrad)", color="C0")
    twin = ax.twinx()
    twin.plot(x, np.asarray(out["offset"]) / c, color="C1", linewidth=1.0, label="offset y/c")
    for level in (-1.0, 1.0):
        twin.axhline(level, color="0.5", linestyle="--", linewidth=0.8)
    twin.set_ylabel("Lateral offset y/c", color="C1")
    ax.set_xlabel(xlabel)
    ax.set_title(f"Slider tilt and offset at {name} (c = {c * 1e3:g} mm)")
    ax.grid(True, alpha=0.3)
    return fig


def plot_corner_gaps(traj, joint: str | None = None, *, ax=None) -> Figure:
    """Gap g_k = −δ_k (µm) between each corner and its guide face against the crank angle;
    below zero the corner is in contact.

    Args:
        traj: a single ``Trajectory``.
        joint: the joint's name (default: the first translational clearance joint).
        ax: optional axes.
    """
    name, element = _joint(traj, joint)
    gaps = -np.asarray(traj.clearance[name]["corner_penetration"]) * 1e6
    x, xlabel = _abscissa(traj)
    fig, ax = _new_axes(ax)
    for k, corner in enumerate(CORNER_NAMES):
        ax.plot(x, gaps[:, k], color=f"C{k}", linewidth=1.0, label=corner.replace("_", " "))
    ax.axhline(0.0, color="0.3", linewidth=0.8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Corner gap (µm)")
    ax.set_title(f"Corner gaps at {name} (c = {float(element.clearance) * 1e3:g} mm)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def plot_corner_forces(traj, joint: str | None = None, *, ax=None) -> Figure:
    """Normal contact force F_N,k of each corner against the crank angle.

    Args:
        traj: a single ``Trajectory``.
        joint: the joint's name (default: the first translational clearance joint).
        ax: optional axes.
    """
    name, _ = _joint(traj, joint)
    forces = np.asarray(traj.clearance[name]["corner_normal_force"])
    x, xlabel = _abscissa(traj)
    fig, ax = _new_axes(ax)
    for k, corner in enumerate(CORNER_NAMES):
        ax.plot(x, forces[:, k], color=f"C{k}", linewidth=1.0, label=corner.replace("_", " "))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Corner normal force (N)")
    ax.set_title(f"Corner normal forces at {name}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def save_translational_plots(traj, out_dir, *, dpi: int = DPI) -> list[Path]:
    """Write ``slider_tilt_<J>.png``, ``corner_gaps_<J>.png`` and ``corner_forces_<J>.png`` for
    every translational clearance joint J of ``traj`` into ``out_dir`` (created if missing);
    nothing for a trajectory without one.

    Returns:
        Paths of the files written.
    """
    names = translational_clearance_joint_names(traj)
    if not names:
        return []
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name in names:
        for prefix, plot in (
            ("slider_tilt", plot_slider_tilt),
            ("corner_gaps", plot_corner_gaps),
            ("corner_forces", plot_corner_forces),
        ):
            written.append(save_figure(plot(traj, name), out_dir, f"{prefix}_{name}.png", dpi))
    return written
