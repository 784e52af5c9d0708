"""Plots of one run (a single ``Trajectory``): any output column against the crank angle or time,
the constraint violation, the clearance joints' orbits and contact forces, the lubricated joints'
orbits in eccentricity ratios and film forces, the ideal joints' forces, the contact-mode
timeline, and the standard PNGs the ``run`` command writes.
"""

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MultipleLocator

from ..io import Column, clearance_joint_names, column_map
from ..mechanisms import is_slider_crank
from ..model import RevoluteJoint
from ._common import DPI, UNIT_LABELS, _new_axes, _title, save_figure

STANDARD_PLOTS = (
    ("slider_position.png", "slider_x", "angle"),
    ("slider_velocity.png", "slider_v", "angle"),
    ("slider_acceleration.png", "slider_a", "angle"),
    ("crank_torque.png", "crank_torque", "angle"),
    ("constraint_violation.png", "constraint_violation", "time"),
)
"""(file name, quantity, horizontal axis) written by ``save_standard_plots``."""

MAIN_STYLE: dict[str, Any] = dict(color="C0", linewidth=1.4, zorder=3)
REFERENCE_STYLE: dict[str, Any] = dict(color="0.55", linewidth=1.0, linestyle="--", zorder=2)


def _get(columns: dict[str, Column], quantity: str) -> Column:
    if quantity not in columns:
        raise ValueError(
            f"unknown quantity {quantity!r}; this trajectory has: {', '.join(columns)}."
        )
    return columns[quantity]


def _curve(traj, quantity: str, xaxis: str) -> tuple[Column, Column]:
    """(x column, y column) of one trajectory; ``xaxis`` is ``"angle"`` or ``"time"``."""
    columns = column_map(traj)
    if xaxis == "time":
        return columns["t"], _get(columns, quantity)
    mech = traj.mechanism
    if mech.driver is None:
        raise ValueError(
            "the mechanism has no driver, so there is no crank angle; use plot_vs_time."
        )
    return columns[f"{mech.driver.body}_angle"], _get(columns, quantity)


def _angle_label(traj) -> str:
    body = traj.mechanism.driver.body
    return f"{body.capitalize()} angle (°)"


def _axis_label(column: Column) -> str:
    title = _title(column.name)
    unit = UNIT_LABELS.get(column.unit, column.unit)
    return f"{title} ({unit})" if unit else title


def _speed_label(traj) -> str:
    """ " — 5000 rpm" for a constant-speed driver, else ""."""
    speed = getattr(traj.mechanism.driver, "speed", None)
    try:
        rpm = float(np.asarray(speed)) * 60.0 / (2.0 * np.pi)
    except (TypeError, ValueError):  # no driver, or a batched/traced speed
        return ""
    return f" — {rpm:g} rpm" if np.isfinite(rpm) else ""


def _finish(ax, xlabel, ycol, title, legend, traj):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(_axis_label(ycol))
    if title is None:
        title = _title(ycol.name) + _speed_label(traj)
    ax.set_title(title)
    ax.grid(True, which="major", alpha=0.5)
    if legend:
        ax.legend(loc="best")


def _references(reference) -> Sequence:
    if reference is None:
        return ()
    return reference if isinstance(reference, list | tuple) else (reference,)


def _angle_ticks(ax, angle) -> None:
    """Crank-angle axis: ticks every 90° (30° for short runs), limits at the ends of the data."""
    span = float(np.ptp(angle))
    if 0 < span <= 1440:
        ax.xaxis.set_major_locator(MultipleLocator(90 if span > 180 else 30))
    if (
        span > 0
    ):  # pad by a hair so ticks at the ends (720°) survive round-off in the integrated angle
        pad = 1e-6 * span
        ax.set_xlim(angle.min() - pad, angle.max() + pad)


def plot_vs_crank_angle(
    traj,
    quantity: str,
    *,
    reference=None,
    label: str | None = None,
    reference_label: str = "ideal joints",
    title: str | None = None,
    ax=None,
) -> Figure:
    """A quantity against the crank (driven-body) angle in degrees.

    Args:
        traj: a single ``Trajectory`` of a driven mechanism.
        quantity: a column name of results.csv, e.g. ``"slider_a"`` or ``"crank_torque"``.
        reference: optional ``Trajectory`` (or list of them) drawn behind, grey and dashed.
        label: legend entry of ``traj`` (a legend is shown only with a reference or a label).
        reference_label: legend entry of the reference.
        title: axes title (default: the quantity's name and the crank speed).
        ax: draw into these axes instead of a new figure.

    Returns:
        The ``Figure``.
    """
    fig, ax = _new_axes(ax)
    refs = _references(reference)
    for k, ref in enumerate(refs):
        x, y = _curve(ref, quantity, "angle")
        ax.plot(x.values, y.values, label=reference_label if k == 0 else None, **REFERENCE_STYLE)
    angle, ycol = _curve(traj, quantity, "angle")
    ax.plot(angle.values, ycol.values, label=label or ("this run" if refs else None), **MAIN_STYLE)
    _angle_ticks(ax, angle.values)
    _finish(ax, _angle_label(traj), ycol, title, legend=bool(refs) or label is not None, traj=traj)
    return fig


def plot_vs_time(
    traj,
    quantity: str,
    *,
    reference=None,
    log: bool = False,
    label: str | None = None,
    reference_label: str = "ideal joints",
    title: str | None = None,
    ax=None,
) -> Figure:
    """A quantity against time in seconds; ``log=True`` plots |value| on a log axis.

    Args: as ``plot_vs_crank_angle``, plus ``log``. Non-positive values are left out of a log plot.

    Returns:
        The ``Figure``.
    """
    fig, ax = _new_axes(ax)
    refs = _references(reference)

    def values(column):
        y = column.values
        return np.where(np.abs(y) > 0, np.abs(y), np.nan) if log else y

    plotted = []
    for k, ref in enumerate(refs):
        x, y = _curve(ref, quantity, "time")
        plotted.append(values(y))
        ax.plot(x.values, plotted[-1], label=reference_label if k == 0 else None, **REFERENCE_STYLE)
    x, ycol = _curve(traj, quantity, "time")
    plotted.append(values(ycol))
    ax.plot(x.values, plotted[-1], label=label or ("this run" if refs else None), **MAIN_STYLE)
    if log and any(np.any(np.isfinite(p)) for p in plotted):
        ax.set_yscale("log")
    _finish(ax, "Time (s)", ycol, title, legend=bool(refs) or label is not None, traj=traj)
    return fig


def plot_constraint_violation(traj, *, reference=None, ax=None) -> Figure:
    """max |Φ| against time on a log axis: shows how well Baumgarte stabilisation holds the joints."""
    return plot_vs_time(traj, "constraint_violation", reference=reference, log=True, ax=ax)


def plot_orbit(traj, joint: str, *, ax=None) -> Figure:
    """Journal-centre orbit of a clearance joint relative to its bearing, with the clearance circle.

    Points in contact (penetration > 0) are drawn on top in a second colour.
    """
    fig, ax = _new_axes(ax)
    out = traj.clearance[joint]
    ex, ey = np.asarray(out["ecc_x"]) * 1e3, np.asarray(out["ecc_y"]) * 1e3
    c = float(
        traj.mechanism.clearance_joints[
            [j.name for j in traj.mechanism.clearance_joints].index(joint)
        ].geometry.clearance
    )
    circle = np.linspace(0, 2 * np.pi, 361)
    ax.plot(
        1e3 * c * np.cos(circle),
        1e3 * c * np.sin(circle),
        color="k",
        linestyle="--",
        linewidth=1.0,
        label="clearance circle",
    )
    ax.plot(ex, ey, color="C0", linewidth=0.8, label="journal centre")
    contact = np.asarray(out["penetration"]) > 0
    ax.plot(ex[contact], ey[contact], ".", color="C3", markersize=2, label="in contact")
    ax.set_aspect("equal")
    lim = 1.15e3 * max(c, float(np.max(np.hypot(ex, ey))) / 1e3)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("Eccentricity x (mm)")
    ax.set_ylabel("Eccentricity y (mm)")
    ax.set_title(f"Journal-centre orbit at clearance joint {joint} (c = {c * 1e3:g} mm)")
    ax.grid(True, alpha=0.3)
    ax.legend(
        loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small"
    )  # beside the square axes, off the orbit
    return fig


def lubricated_joint_names(traj) -> list[str]:
    """Names of ``traj``'s lubricated clearance joints (those with film-force outputs), in the
    mechanism's order."""
    return [n for n in clearance_joint_names(traj) if "film_force_x" in traj.clearance[n]]


def _clearance_joint(traj, joint: str):
    joints = traj.mechanism.clearance_joints
    return joints[[j.name for j in joints].index(joint)]


def plot_eccentricity_orbit(traj, joint: str, *, ax=None) -> Figure:
    """Journal-centre orbit of a clearance joint in eccentricity ratios ε = e/c.

    The bearing wall is the circle ε = 1 (solid). For a lubricated joint (docs/model.md §3b) the
    circle ε = ε₀ where the film starts to hand over to the dry contact law is drawn dashed, and
    ε₀ + Δ, from where the dry law acts alone, dotted if it lies inside the wall. Instants with
    penetration (ε > 1, the dry law acting) are drawn on top in a second colour.
    """
    fig, ax = _new_axes(ax)
    out = traj.clearance[joint]
    element = _clearance_joint(traj, joint)
    c = float(element.geometry.clearance)
    ex, ey = np.asarray(out["ecc_x"]) / c, np.asarray(out["ecc_y"]) / c
    circle = np.linspace(0, 2 * np.pi, 361)
    ax.plot(np.cos(circle), np.sin(circle), color="k", linewidth=1.0, label="wall, ε = 1")
    film = element.lubrication
    if film is not None:
        e0 = float(film.transition_eccentricity)
        e1 = e0 + float(film.transition_width)
        ax.plot(
            e0 * np.cos(circle),
            e0 * np.sin(circle),
            color="0.4",
            linestyle="--",
            linewidth=1.0,
            label=f"film fades out, ε₀ = {e0:g}",
        )
        if e1 < 1.0 - 1e-9:
            ax.plot(
                e1 * np.cos(circle),
                e1 * np.sin(circle),
                color="0.4",
                linestyle=":",
                linewidth=1.0,
                label=f"dry only, ε₀ + Δ = {e1:g}",
            )
    ratio = np.hypot(ex, ey)
    peak = float(np.max(ratio)) if ratio.size else 0.0
    ax.plot(ex, ey, color="C0", linewidth=0.8, label=f"journal, max ε = {peak:.3g}")
    contact = np.asarray(out["penetration"]) > 0
    ax.plot(ex[contact], ey[contact], ".", color="C3", markersize=2, label="in contact")
    ax.set_aspect("equal")
    lim = 1.15 * max(1.0, peak)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("Eccentricity ratio εx = ex / c")
    ax.set_ylabel("Eccentricity ratio εy = ey / c")
    kind = "lubricated " if film is not None else ""
    ax.set_title(f"Journal orbit at {kind}joint {joint} (c = {c * 1e3:g} mm)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small")
    return fig


def plot_film_forces(traj, *, ax=None) -> Figure:
    """Film force magnitude of every lubricated clearance joint against the driven angle.

    Each joint's dry contact normal force is drawn thin and dashed in the same colour: the film
    carries the load while the journal stays inside ε₀ + Δ, the dry law once it reaches the wall
    (docs/model.md §3b). Both are taken at the saved instants.

    Raises:
        ValueError: ``traj`` has no lubricated joint, or its mechanism no driver.
    """
    names = lubricated_joint_names(traj)
    if not names:
        raise ValueError(
            "the trajectory has no lubricated clearance joint (ClearanceJoint.lubrication); "
            "plot_contact_forces draws the dry contact forces."
        )
    fig, ax = _new_axes(ax)
    columns = column_map(traj)
    for k, name in enumerate(names):
        angle, fx = _curve(traj, f"{name}_film_force_x", "angle")
        film = np.hypot(fx.values, columns[f"{name}_film_force_y"].values)
        ax.plot(angle.values, film, color=f"C{k}", linewidth=1.2, label=f"joint {name} film")
        ax.plot(
            angle.values,
            columns[f"{name}_normal_force"].values,
            color=f"C{k}",
            linewidth=0.8,
            linestyle="--",
            alpha=0.7,
            label=f"joint {name} dry contact normal force",
        )
        _angle_ticks(ax, angle.values)
    ax.set_xlabel(_angle_label(traj))
    ax.set_ylabel("Force (N)")
    ax.set_title(f"Hydrodynamic film force |F|{_speed_label(traj)}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def plot_contact_forces(traj, *, ax=None) -> Figure:
    """Normal contact force of every clearance joint against crank angle.

    With ``traj.extremes`` (the default), a dotted line per joint marks its peak taken from the
    solver's steps over the statistics window: impacts last microseconds, so the saved instants
    drawn as the curve can miss most of a peak (docs/outputs.md).
    """
    fig, ax = _new_axes(ax)
    for k, name in enumerate(clearance_joint_names(traj)):
        angle, force = _curve(traj, f"{name}_normal_force", "angle")
        ax.plot(
            angle.values, force.values / 1e3, color=f"C{k}", linewidth=1.0, label=f"joint {name}"
        )
        if traj.extremes is not None:
            peak = float(traj.extremes.normal_force_max[name]) / 1e3
            ax.axhline(
                peak,
                color=f"C{k}",
                linestyle=":",
                linewidth=1.0,
                label=f"joint {name} peak from the solver's steps, {peak:.3g} kN",
            )
        _angle_ticks(ax, angle.values)
    ax.set_xlabel(_angle_label(traj))
    ax.set_ylabel("Normal contact force (kN)")
    ax.set_title(f"Normal contact force{_speed_label(traj)}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def plot_joint_forces(traj, *, ax=None) -> Figure:
    """Force magnitude of every ideal revolute joint against the driven body's angle."""
    fig, ax = _new_axes(ax)
    columns = column_map(traj)
    angle = columns[f"{traj.mechanism.driver.body}_angle"].values
    joints = [j.name for j in traj.mechanism.joints if isinstance(j, RevoluteJoint)]
    for k, name in enumerate(joints):
        force = np.hypot(columns[f"{name}_Fx"].values, columns[f"{name}_Fy"].values)
        ax.plot(angle, force, color=f"C{k}", linewidth=1.0, label=f"joint {name}")
    _angle_ticks(ax, angle)
    ax.set_xlabel(_angle_label(traj))
    ax.set_ylabel("Joint force magnitude (N)")
    ax.set_title(f"Ideal joint forces{_speed_label(traj)}")
    ax.grid(True, alpha=0.3)
    if joints:
        ax.legend(fontsize="small")
    return fig


MODE_STYLE: dict[str, dict[str, Any]] = {
    "impact": dict(color="C3", linewidth=1.2),
    "continuous": dict(color="C0", alpha=0.85),
}
"""How ``plot_mode_timeline`` draws the two contact modes (free flight is left blank)."""


def plot_mode_timeline(
    traj,
    *,
    continuous_fraction: float | None = None,
    start: float | None = None,
    events: dict | None = None,
    ax=None,
) -> Figure:
    """Contact-mode timeline: one row per clearance joint, against the driven angle (or time).

    Continuous contacts are drawn as bars over their duration, impacts (contacts shorter than
    ``continuous_fraction`` of the crank period; microseconds long, too short to show as bars) as a
    tick at their onset; free flight is blank. The contacts are those located from the solver's
    steps (``analysis.contact_events``), so a contact shorter than the output interval is drawn too.
    The legend gives each joint's counts and time shares.

    Args:
        traj: a single ``Trajectory`` simulated with ``contact_events=K`` (and extremes on).
        continuous_fraction: the impact/continuous threshold as a fraction of the crank period
            (default that of ``analysis.contact_events``, 2 %).
        start: first time shown, s (default the statistics window's start).
        events: the output of ``analysis.contact_events`` if already computed (then
            ``continuous_fraction`` and ``start`` are not used to recompute it).
        ax: draw into these axes instead of a new figure.

    Returns:
        The ``Figure``.

    Raises:
        ValueError: ``traj`` has no recorded contact events (the message says how to record them).
    """
    from ..analysis import CONTINUOUS, IMPACT, contact_events

    if events is None:
        options = (
            {} if continuous_fraction is None else {"continuous_fraction": continuous_fraction}
        )
        events = contact_events(traj, start=start, **options)
    fig, ax = _new_axes(ax)
    t = np.asarray(traj.t)
    t_first = float(traj.extremes.start) if start is None else float(start)
    t_last = float(traj.t_final)
    driver = traj.mechanism.driver
    if driver is not None:
        angle = column_map(traj)[f"{driver.body}_angle"].values

        def x_of(times):  # the driven angle is smooth in t: interpolation between instants is exact
            return np.interp(np.asarray(times, dtype=float), t, angle)  # to the angle's curvature

        xlabel = _angle_label(traj)
    else:

        def x_of(times):
            return 1e3 * np.asarray(times, dtype=float)

        xlabel = "Time (ms)"
    order = [j.name for j in traj.mechanism.clearance_joints]
    names = [n for n in order if n in events] + [n for n in events if n not in order]
    span = t_last - t_first
    for row, name in enumerate(names):
        e = events[name]
        y = len(names) - 1 - row  # first joint on top
        impact = e["mode"] == IMPACT
        continuous = e["mode"] == CONTINUOUS
        bars = [
            (float(x_of(a)), float(x_of(b) - x_of(a)))
            for a, b in zip(e["onset"][continuous], e["end"][continuous])
        ]
        ax.broken_barh(bars, (y - 0.3, 0.6), **MODE_STYLE["continuous"])
        ax.vlines(x_of(e["onset"][impact]), y - 0.35, y + 0.35, **MODE_STYLE["impact"])
        share = np.sum(e["end"][continuous] - e["onset"][continuous]) / span if span > 0 else 0.0
        ax.text(
            1.01,
            y,
            f"{int(impact.sum())} impacts\n{int(continuous.sum())} continuous ({share:.0%} of time)",
            transform=ax.get_yaxis_transform(),
            va="center",
            fontsize="x-small",
        )
    ax.set_yticks(range(len(names)), [f"joint {n}" for n in reversed(names)])
    ax.set_ylim(-0.7, len(names) - 0.3)
    x0, x1 = x_of([t_first, t_last])
    if driver is not None:
        _angle_ticks(ax, np.array([x0, x1]))
    ax.set_xlim(x0, x1)
    ax.set_xlabel(xlabel)
    handles = [
        Line2D([], [], label="impact (onset)", **MODE_STYLE["impact"]),
        Patch(label="continuous contact", **MODE_STYLE["continuous"]),
    ]
    ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(0.0, -0.18),
        ncol=2,
        fontsize="small",
        frameon=False,
    )
    ax.set_title(f"Contact modes (blank: free flight){_speed_label(traj)}")
    ax.grid(True, axis="x", alpha=0.3)
    return fig


def standard_plots(traj) -> list[tuple[str, str, str]]:
    """(file name, quantity, horizontal axis) of the standard plots of ``traj``'s mechanism.

    The benchmark slider–crank gets ``STANDARD_PLOTS``; any other driven mechanism the driven
    body's input torque and, per other body, its angle and angular acceleration (against the driven
    angle); every mechanism the constraint violation (against time).
    """
    mech = traj.mechanism
    if is_slider_crank(mech) or mech.driver is None:
        return list(STANDARD_PLOTS)
    driven = mech.driver.body
    plots = [(f"{driven}_torque.png", f"{driven}_torque", "angle")]
    for body in mech.body_names:
        if body != driven:
            plots += [
                (f"{body}_angle.png", f"{body}_phi", "angle"),
                (f"{body}_angular_acceleration.png", f"{body}_alpha", "angle"),
            ]
    return plots + [("constraint_violation.png", "constraint_violation", "time")]


def save_standard_plots(traj, out_dir, *, reference=None, dpi: int = DPI) -> list[Path]:
    """Write the standard PNGs of a run into ``out_dir`` (created if missing).

    Files (``standard_plots``): for the slider–crank slider_position.png, slider_velocity.png,
    slider_acceleration.png, crank_torque.png (against crank angle); for another driven mechanism
    <driven>_torque.png, <body>_angle.png and <body>_angular_acceleration.png per other body and
    joint_forces.png (ideal revolute joints); always constraint_violation.png (against time, log
    axis); with clearance joints also normal_force.png (against the driven angle) and
    orbit_<joint>.png per joint; with lubricated joints also film_force.png (film force
    magnitude against the driven angle) and film_orbit_<joint>.png per lubricated joint (the orbit
    in ε = e/c inside the wall ε = 1, with the film's transition circle ε₀). Plots whose quantity the mechanism lacks (no driver) are skipped.
    The y-ranges follow the instants in ``traj``: pass the kept window (``jaxclear.solve.window``) to
    leave a start-up transient out.

    Args:
        traj: a single ``Trajectory``.
        out_dir: folder for the PNGs.
        reference: optional reference ``Trajectory`` drawn behind each curve.
        dpi: resolution.

    Returns:
        Paths of the files written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    available = column_map(traj)
    written = []
    for filename, quantity, xaxis in standard_plots(traj):
        if quantity not in available:
            continue
        if xaxis == "angle":
            if traj.mechanism.driver is None:
                continue
            fig = plot_vs_crank_angle(traj, quantity, reference=reference)
        elif quantity == "constraint_violation":
            fig = plot_constraint_violation(traj, reference=reference)
        else:
            fig = plot_vs_time(traj, quantity, reference=reference)
        written.append(save_figure(fig, out_dir, filename, dpi))
    mech = traj.mechanism
    if (
        mech.driver is not None
        and not is_slider_crank(mech)
        and any(isinstance(j, RevoluteJoint) for j in mech.joints)
    ):
        written.append(save_figure(plot_joint_forces(traj), out_dir, "joint_forces.png", dpi))
    if clearance_joint_names(traj) and traj.mechanism.driver is not None:
        written.append(save_figure(plot_contact_forces(traj), out_dir, "normal_force.png", dpi))
        for name in clearance_joint_names(traj):
            written.append(save_figure(plot_orbit(traj, name), out_dir, f"orbit_{name}.png", dpi))
        lubricated = lubricated_joint_names(traj)
        if lubricated:
            written.append(save_figure(plot_film_forces(traj), out_dir, "film_force.png", dpi))
        for name in lubricated:
            fig = plot_eccentricity_orbit(traj, name)
            written.append(save_figure(fig, out_dir, f"film_orbit_{name}.png", dpi))
    return written


def save_mode_timeline(traj, out_dir, *, events=None, start=None, dpi: int = DPI) -> Path:
    """Write ``mode_timeline.png`` (``plot_mode_timeline``) into ``out_dir``; returns its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig = plot_mode_timeline(traj, events=events, start=start)
    return save_figure(fig, out_dir, "mode_timeline.png", dpi)
