"""Plots of a ``Trajectory`` with matplotlib.

Every function returns a ``matplotlib.figure.Figure`` built without ``pyplot`` (no global state,
no GUI; saving uses the Agg renderer), so it works headless, in scripts and in notebooks. The
quantities are the columns of ``results.csv`` (see ``jaxclear.io.result_columns``), e.g.
``"slider_x"``, ``"slider_a"``, ``"crank_torque"``, ``"A_Fx"``, ``"constraint_violation"``.

Each plotting function takes an optional ``reference`` trajectory (for instance the ideal-joint run)
drawn first, thin and grey, behind the main curve::

    ideal = jaxclear.simulate(jaxclear.mechanisms.slider_crank(), t1)
    fig = plot_vs_crank_angle(clearance_run, "slider_a", reference=ideal)
    fig.savefig("slider_acceleration.png")
"""

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MultipleLocator

from .io import Column, clearance_joint_names, column_map
from .mechanisms import is_slider_crank
from .model import RevoluteJoint
from .solve._trajectory import BODY_OUTPUTS

QUANTITY_LABELS = {
    "slider_x": "Slider position",
    "slider_v": "Slider velocity",
    "slider_a": "Slider acceleration",
    "crank_torque": "Crank input torque",
    "crank_angle": "Crank angle",
    "constraint_violation": "Constraint violation max |Φ|",
    "velocity_violation": "Velocity constraint violation max |Φ̇|",
    "t": "Time",
}
"""Axis titles of the common quantities; other columns are labelled by their name."""

BODY_LABELS = {
    "x": "x",
    "y": "y",
    "phi": "angle",
    "vx": "velocity x",
    "vy": "velocity y",
    "omega": "angular velocity",
    "ax": "acceleration x",
    "ay": "acceleration y",
    "alpha": "angular acceleration",
}
"""Axis titles of the per-body columns ``<body>_<output>`` of a general mechanism."""

UNIT_LABELS = {"m/s^2": "m/s²", "N m": "N·m", "deg": "°", "rad/s^2": "rad/s²"}

STANDARD_PLOTS = (
    ("slider_position.png", "slider_x", "angle"),
    ("slider_velocity.png", "slider_v", "angle"),
    ("slider_acceleration.png", "slider_a", "angle"),
    ("crank_torque.png", "crank_torque", "angle"),
    ("constraint_violation.png", "constraint_violation", "time"),
)
"""(file name, quantity, horizontal axis) written by ``save_standard_plots``."""

FIGSIZE = (7.0, 4.0)  # inches
DPI = 110  # ~770 x 440 px, a few tens of kB per PNG
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


def _title(name: str) -> str:
    """Human title of a column: ``QUANTITY_LABELS``, per-body outputs, driven-body torque."""
    if name in QUANTITY_LABELS:
        return QUANTITY_LABELS[name]
    for output, *_ in BODY_OUTPUTS:
        if name.endswith(f"_{output}"):
            body = name[: -len(output) - 1]
            return f"{body.capitalize()} {BODY_LABELS[output]}"
    if name.endswith("_torque"):
        return f"{name[:-7].capitalize()} input torque"
    return name


def _angle_label(traj) -> str:
    body = traj.mechanism.driver.body
    return f"{body.capitalize()} angle (°)"


def _axis_label(column: Column) -> str:
    title = _title(column.name)
    unit = UNIT_LABELS.get(column.unit, column.unit)
    return f"{title} ({unit})" if unit else title


def _new_axes(ax):
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=FIGSIZE, dpi=DPI, layout="constrained")
    return fig, fig.add_subplot()


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
    from .analysis import CONTINUOUS, IMPACT, contact_events

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


def save_figure(fig, out_dir: Path, filename: str, dpi: int) -> Path:
    """Write ``fig`` as ``out_dir/filename`` (PNG at ``dpi``) through a temporary file renamed into
    place, so an interrupted write never leaves a truncated plot under the final name."""
    path = out_dir / filename
    tmp = out_dir / f".{filename}.tmp.png"
    fig.savefig(tmp, dpi=dpi)
    tmp.replace(path)
    return path


def save_standard_plots(traj, out_dir, *, reference=None, dpi: int = DPI) -> list[Path]:
    """Write the standard PNGs of a run into ``out_dir`` (created if missing).

    Files (``standard_plots``): for the slider–crank slider_position.png, slider_velocity.png,
    slider_acceleration.png, crank_torque.png (against crank angle); for another driven mechanism
    <driven>_torque.png, <body>_angle.png and <body>_angular_acceleration.png per other body and
    joint_forces.png (ideal revolute joints); always constraint_violation.png (against time, log
    axis); with clearance joints also normal_force.png (against the driven angle) and
    orbit_<joint>.png per joint. Plots whose quantity the mechanism lacks (no driver) are skipped.
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
    if traj.clearance and traj.mechanism.driver is not None:
        written.append(save_figure(plot_contact_forces(traj), out_dir, "normal_force.png", dpi))
        for name in clearance_joint_names(traj):
            written.append(save_figure(plot_orbit(traj, name), out_dir, f"orbit_{name}.png", dpi))
    return written


def save_mode_timeline(traj, out_dir, *, events=None, start=None, dpi: int = DPI) -> Path:
    """Write ``mode_timeline.png`` (``plot_mode_timeline``) into ``out_dir``; returns its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig = plot_mode_timeline(traj, events=events, start=start)
    return save_figure(fig, out_dir, "mode_timeline.png", dpi)


def plot_fit(result) -> Figure:
    """Measured and fitted signals of an identification (``jaxclear.identify``), one panel each.

    The measured points are dots, the fitted model a line; the shaded span is the part of the
    record the estimate was fitted to (``result.window_end``); the title gives the estimates.
    """
    names = list(result.measured)
    fig = Figure(figsize=(7.0, 2.2 * len(names) + 0.6), layout="constrained")
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    t_ms = 1e3 * np.asarray(result.t)
    for ax, name in zip(axes, names, strict=True):
        ax.plot(t_ms, result.measured[name], ".", ms=2.5, color="0.45", label="measured")
        ax.plot(t_ms, result.fitted[name], "-", lw=1.0, color="C3", label="fitted")
        ax.axvspan(t_ms[0], 1e3 * result.window_end, color="C0", alpha=0.06, lw=0)
        ax.set_ylabel(f"{name} [{_signal_unit(name)}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time [ms] (shaded: fitted span)")
    estimates = ", ".join(
        f"{n} = {e.value:.6g} ± {2 * e.std:.2g} {e.unit} (2σ)" for n, e in result.parameters.items()
    )
    fig.suptitle(estimates, fontsize=9)
    return fig


def plot_loss(result) -> Figure:
    """Loss history of an identification: the scan's best point and each Levenberg–Marquardt
    iteration per window (log scale; ≈ 1 is a fit to the noise level)."""
    fig = Figure(figsize=(6.4, 3.6), layout="constrained")
    ax = fig.subplots()
    stages = list(dict.fromkeys(h["stage"] for h in result.history))
    x = 0
    for k, stage in enumerate(stages):
        losses = [h["loss"] for h in result.history if h["stage"] == stage]
        xs = np.arange(x, x + len(losses))
        ax.semilogy(xs, losses, "o-", ms=3, color=f"C{k % 10}", label=stage)
        x += len(losses)
    ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
    ax.set_xlabel("evaluation")
    ax.set_ylabel("loss (mean squared residual / noise²)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return fig


_SIGNAL_UNITS = {"slider_x": "m", "slider_v": "m/s", "slider_a": "m/s²"}


def _signal_unit(name: str) -> str:
    from .solve._trajectory import CLEARANCE_OUTPUTS

    if name in _SIGNAL_UNITS:
        return _SIGNAL_UNITS[name]
    if name.endswith("_torque") or name.endswith("_moment"):
        return "N m"
    if name.endswith(("_Fx", "_Fy", "_normal")):
        return "N"
    for key, (unit, _) in CLEARANCE_OUTPUTS.items():
        if name.endswith("_" + key):
            return unit
    return ""


def save_fit_plots(result, out_dir, *, dpi: int = DPI) -> list[Path]:
    """Write fit.png (``plot_fit``) and loss.png (``plot_loss``) into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [
        save_figure(plot_fit(result), out_dir, "fit.png", dpi),
        save_figure(plot_loss(result), out_dir, "loss.png", dpi),
    ]


# --- ensembles (Monte Carlo, sweeps) ----------------------------------------------------------------

ENSEMBLE_FAILED_STYLE: dict[str, Any] = dict(
    marker="x", color="C3", linestyle="none", markersize=6, zorder=4
)
SWEEP_LOG_RATIO = 50.0
"""A sweep over positive values spanning at least this ratio is drawn on a log axis."""
_LENGTH_FIELDS = ("bearing_radius", "journal_radius", "length", "free_length", "layer_thickness")
_MODULUS_FIELDS = ("young_modulus", "bearing_young", "journal_young", "foundation_modulus")


def statistic_axis(name: str) -> tuple[str, str, float]:
    """(title, unit, scale) of an ensemble statistic (``EnsembleResult.statistics``) for plots and
    printed summaries: the value shown is ``scale`` times the SI value, in ``unit``."""
    if name.endswith("_peak_normal_force"):
        return f"{name[: -len('_peak_normal_force')]} peak normal force", "kN", 1e-3
    if name.endswith("_peak_penetration"):
        return f"{name[: -len('_peak_penetration')]} peak penetration", "µm", 1e6
    if name.startswith("peak_") and name.endswith("_acceleration"):
        return f"Peak {name[5 : -len('_acceleration')]} acceleration", "m/s²", 1.0
    if name.startswith("rms_") and name.endswith("_acceleration"):
        return f"RMS {name[4 : -len('_acceleration')]} acceleration", "m/s²", 1.0
    for suffix, what in (("_torque_rms", "RMS"), ("_torque_min", "min"), ("_torque_max", "max")):
        if name.endswith(suffix):
            return f"{name[: -len(suffix)].capitalize()} torque {what}", "N·m", 1.0
    if name == "torque_fluctuation":
        return "Torque fluctuation, RMS about mean", "N·m", 1.0
    if name.endswith("_deviation"):  # RMS of (member − ideal-joint mechanism)
        signal = name[: -len("_deviation")]
        unit = _signal_unit(signal)
        return f"{_title(signal)} − ideal, RMS", UNIT_LABELS.get(unit, unit), 1.0
    if name.startswith("combination_") and name.endswith("_share"):
        return f"Combination {name[len('combination_') : -len('_share')]} share", "%", 100.0
    for mode in ("free", "impact", "continuous"):
        if name.endswith(f"_{mode}_share"):
            return f"{name[: -len(mode) - 7]} {mode}-mode share", "%", 100.0
    if name.endswith("_impacts"):
        return f"{name[: -len('_impacts')]} impacts", "count", 1.0
    if name.endswith("_continuous_contacts"):
        return f"{name[: -len('_continuous_contacts')]} continuous contacts", "count", 1.0
    if name == "contact_modes_located":
        return "Contact modes from located contacts (1) or the grid (0)", "", 1.0
    if name == "max_constraint_violation":
        return "Max constraint violation", "m", 1.0
    if name in ("statistics_start", "statistics_duration"):
        return name.replace("_", " ").capitalize(), "s", 1.0
    return name, "", 1.0


def parameter_axis(name: str) -> tuple[str, str, float]:
    """(title, unit, scale) of a drawn or swept parameter (``jaxclear.parameter_names``)."""
    owner, _, field = name.rpartition(".")
    joint = f"{owner} " if owner else ""
    if field == "clearance":
        return f"{joint}radial clearance", "µm", 1e6
    if field in _LENGTH_FIELDS or field.endswith(("_com_x", "_com_y")):
        return f"{joint}{field.replace('_', ' ')}", "mm", 1e3
    if field in _MODULUS_FIELDS:
        return f"{joint}{field.replace('_', ' ')}", "GPa", 1e-9
    if field.endswith("_mass"):
        return f"{field[:-5].capitalize()} mass", "kg", 1.0
    if field.endswith("_inertia"):
        return f"{field[:-8].capitalize()} moment of inertia", "kg·m²", 1.0
    if name == "rpm":
        return "Driver speed", "rpm", 1.0
    return name, "", 1.0


def _label(axis: tuple[str, str, float]) -> str:
    title, unit, _ = axis
    return f"{title} ({unit})" if unit else title


def _number(value: float) -> str:
    """4 significant digits, without an exponent up to 10⁷."""
    return f"{value:.0f}" if 1e4 <= abs(value) < 1e7 else f"{value:.4g}"


def _panel(ax, axis: tuple[str, str, float], where: str) -> None:
    """Statistic's title above the panel, its unit on the ``where`` ("x" or "y") axis."""
    title, unit, _ = axis
    ax.set_title(title, fontsize="medium")
    (ax.set_xlabel if where == "x" else ax.set_ylabel)(unit)


def main_ensemble_statistics(result) -> list[str]:
    """The statistics an ensemble's plots and printed summary show, in this order: each clearance
    joint's peak normal force, the peak slider acceleration (slider–crank), the input torque's RMS
    and fluctuation, and the RMS deviations from the ideal mechanism; without any of these (no
    driver, no clearance joint), the bodies' peak accelerations."""
    stats = list(result.statistics)
    names = [n for n in stats if n.endswith("_peak_normal_force")]
    names += [n for n in ("peak_slider_acceleration",) if n in stats]
    names += [n for n in stats if n.endswith("_torque_rms")]
    names += [n for n in ("torque_fluctuation",) if n in stats]
    names += [n for n in stats if n.endswith("_deviation")]
    return names or [n for n in stats if n.startswith("peak_")]


def _statistic_names(result, names) -> list[str]:
    names = main_ensemble_statistics(result) if names is None else list(names)
    unknown = [n for n in names if n not in result.statistics]
    if unknown:
        raise ValueError(
            f"unknown statistic(s) {', '.join(map(repr, unknown))}; this ensemble has: "
            f"{', '.join(result.statistics)}."
        )
    if not names:
        raise ValueError("no statistics to plot; pass names (see result.statistics).")
    return names


def _grid(count: int, columns: int, width: float = 3.4, height: float = 2.7):
    """A figure with ``count`` panels on a grid of ``columns`` columns (unused panels removed)."""
    columns = max(1, min(columns, count))
    rows = -(-count // columns)
    fig = Figure(figsize=(width * columns, height * rows + 0.5), dpi=DPI, layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax in axes[count:]:
        ax.remove()
    return fig, list(axes[:count])


def _ok_values(result, name: str) -> np.ndarray:
    x = np.asarray(result.statistics[name], dtype=float)[np.asarray(result.succeeded)]
    return x[np.isfinite(x)]


def _members_text(result) -> str:
    ok = int(np.sum(result.succeeded))
    failed = len(result) - ok
    return f"{ok} of {len(result)} members" + (f", {failed} failed" if failed else "")


def plot_ensemble_histograms(result, names: Sequence[str] | None = None) -> Figure:
    """Histograms of ensemble statistics over the members that succeeded, one panel each, with the
    median (solid) and the 5 and 95 % percentiles (dashed).

    Args:
        result: an ``EnsembleResult`` (``jaxclear.montecarlo``, ``jaxclear.run_ensemble``).
        names: statistics to show (default ``main_ensemble_statistics(result)``).

    Returns:
        The ``Figure``.
    """
    names = _statistic_names(result, names)
    fig, axes = _grid(len(names), 3)
    for ax, name in zip(axes, names, strict=True):
        axis = statistic_axis(name)
        x = _ok_values(result, name) * axis[2]
        _panel(ax, axis, "x")
        ax.set_ylabel("members")
        ax.grid(True, alpha=0.3)
        if x.size == 0:
            ax.text(0.5, 0.5, "no member succeeded", ha="center", transform=ax.transAxes)
            continue
        bins = int(np.clip(np.sqrt(x.size), 5, 40))
        ax.hist(x, bins=bins, color="C0", alpha=0.8, edgecolor="white", linewidth=0.5)
        p5, p50, p95 = np.percentile(x, [5, 50, 95])
        ax.axvline(p50, color="C3", linewidth=1.4, label=f"median {_number(p50)} {axis[1]}")
        ax.axvline(p5, color="0.3", linewidth=1.0, linestyle="--", label="5 and 95 %")
        ax.axvline(p95, color="0.3", linewidth=1.0, linestyle="--")
        ax.legend(fontsize="x-small", loc="upper right")
    fig.suptitle(
        f"Monte Carlo over {', '.join(result.names)}: {_members_text(result)}", fontsize=10
    )
    return fig


def _mark_failed(ax, x: np.ndarray, label: str | None) -> None:
    """Red crosses just above the bottom of the axes at the parameter values of failed members."""
    if x.size:
        ax.plot(x, np.full(x.shape, 0.03), transform=ax.get_xaxis_transform(),
                label=label, **ENSEMBLE_FAILED_STYLE)  # fmt: skip


def plot_ensemble_scatter(result, names: Sequence[str] | None = None) -> Figure:
    """Each statistic against each drawn parameter, one panel per pair (rows: statistics, columns:
    parameters; with one parameter the panels wrap on a grid). Failed members are red crosses at
    the bottom of each panel, at their drawn values.

    Args:
        result: an ``EnsembleResult``.
        names: statistics to show (default ``main_ensemble_statistics(result)``).

    Returns:
        The ``Figure``.
    """
    names = _statistic_names(result, names)
    params = list(result.names)
    pairs = [(s, p) for s in names for p in range(len(params))]
    fig, axes = _grid(len(pairs), len(params) if len(params) > 1 else 3)
    ok = np.asarray(result.succeeded)
    values = np.asarray(result.values, dtype=float)
    for k, (ax, (name, p)) in enumerate(zip(axes, pairs, strict=True)):
        stat_axis, par_axis = statistic_axis(name), parameter_axis(params[p])
        y = np.asarray(result.statistics[name], dtype=float) * stat_axis[2]
        x = values[:, p] * par_axis[2]
        ax.plot(x[ok], y[ok], ".", color="C0", markersize=4, alpha=0.7)
        _mark_failed(ax, x[~ok], "failed" if k == 0 else None)
        _panel(ax, stat_axis, "y")
        ax.set_xlabel(_label(par_axis))
        ax.grid(True, alpha=0.3)
        if k == 0 and (~ok).any():
            ax.legend(fontsize="x-small", loc="best")
    fig.suptitle(
        f"Monte Carlo: statistics against drawn parameters, {_members_text(result)}", fontsize=10
    )
    return fig


def plot_sweep(result, names: Sequence[str] | None = None) -> Figure:
    """Each statistic against the swept parameter (``jaxclear.sweep``), one panel each; values
    whose member failed are red crosses at the bottom of every panel. Positive values spanning at
    least ``SWEEP_LOG_RATIO`` are drawn on a log axis.

    Args:
        result: an ``EnsembleResult`` of one parameter.
        names: statistics to show (default ``main_ensemble_statistics(result)``).

    Returns:
        The ``Figure``.
    """
    names = _statistic_names(result, names)
    par_axis, x, keep, log = _sweep_x(result)
    ok = np.asarray(result.succeeded)
    fig, axes = _grid(len(names), 3)
    for k, (ax, name) in enumerate(zip(axes, names, strict=True)):
        stat_axis = statistic_axis(name)
        if log:
            ax.set_xscale("log")
        y = np.asarray(result.statistics[name], dtype=float) * stat_axis[2]
        ax.plot(x[keep], y[keep], "o-", color="C0", markersize=3.5, linewidth=1.2)
        _mark_failed(ax, x[~ok], "failed" if k == 0 else None)
        _panel(ax, stat_axis, "y")
        ax.set_xlabel(_label(par_axis))
        ax.grid(True, alpha=0.3)
        if k == 0 and (~ok).any():
            ax.legend(fontsize="x-small", loc="best")
    fig.suptitle(
        f"Sweep of {result.names[0]}: {_members_text(result).replace('members', 'values')}",
        fontsize=10,
    )
    return fig


def save_ensemble_plots(result, out_dir, *, kind: str = "montecarlo", dpi: int = DPI) -> list[Path]:
    """Write an ensemble's PNGs into ``out_dir`` (created if missing).

    Args:
        result: an ``EnsembleResult``.
        out_dir: folder for the PNGs.
        kind: ``"montecarlo"``: histograms.png (``plot_ensemble_histograms``) and scatter.png
            (``plot_ensemble_scatter``); ``"sweep"``: sweep.png (``plot_sweep``).
        dpi: resolution.

    Returns:
        Paths of the files written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if kind == "montecarlo":
        return [
            save_figure(plot_ensemble_histograms(result), out_dir, "histograms.png", dpi),
            save_figure(plot_ensemble_scatter(result), out_dir, "scatter.png", dpi),
        ]
    if kind == "sweep":
        written = [save_figure(plot_sweep(result), out_dir, "sweep.png", dpi)]
        if any(n.startswith("combination_") for n in result.statistics):
            written.append(save_figure(plot_sweep_modes(result), out_dir, "sweep_modes.png", dpi))
        return written
    raise ValueError(f"kind must be 'montecarlo' or 'sweep', got {kind!r}.")


MODE_COLOURS = {"free": "0.85", "impact": "C3", "continuous": "C0"}
"""Colours of the three contact modes in ``plot_sweep_modes``."""
COMBINATION_MIN_SHARE = 0.01
"""``plot_sweep_modes`` names the combinations that reach this time share at some value; the
others are drawn together as "other"."""


def _sweep_x(result):
    if len(result.names) != 1:
        raise ValueError(
            f"a sweep plot needs an ensemble of one parameter, got {', '.join(result.names)}; use "
            "plot_ensemble_scatter."
        )
    par_axis = parameter_axis(result.names[0])
    x = np.asarray(result.values, dtype=float)[:, 0] * par_axis[2]
    order = np.argsort(x, kind="stable")
    keep = order[np.asarray(result.succeeded)[order]]
    return par_axis, x, keep, _log_axis(x)


def _log_axis(x: np.ndarray) -> bool:
    """Positive values spanning at least ``SWEEP_LOG_RATIO``: drawn on a log axis."""
    return bool(np.all(x > 0) and x.max() >= SWEEP_LOG_RATIO * x.min())


def plot_sweep_modes(result) -> Figure:
    """Contact modes against the swept parameter (``jaxclear.sweep``): per clearance joint the time
    shares of free flight, impact and continuous contact stacked to 100 %, and the shares of the
    combinations of all joints' modes (``C-I-F``: first joint in continuous contact, second in an
    impact, third in free flight); combinations under ``COMBINATION_MIN_SHARE`` everywhere are
    drawn together as "other". The shares come from the contacts located in each member's solve,
    over the statistics window.

    Args:
        result: an ``EnsembleResult`` of one parameter with contact-mode statistics.

    Returns:
        The ``Figure``.
    """
    par_axis, x, keep, log = _sweep_x(result)
    stats = result.statistics
    joints = [n[: -len("_free_share")] for n in stats if n.endswith("_free_share")]
    combos = [n for n in stats if n.startswith("combination_") and n.endswith("_share")]
    if not joints or not combos:
        raise ValueError("the ensemble has no contact-mode statistics (no clearance joint).")
    fig, axes = _grid(len(joints) + 1, 2, width=4.2, height=3.0)
    xs = x[keep]
    for ax, joint in zip(axes, joints):
        shares = [np.asarray(stats[f"{joint}_{m}_share"])[keep] * 100 for m in MODE_COLOURS]
        ax.stackplot(xs, shares, labels=list(MODE_COLOURS), colors=list(MODE_COLOURS.values()))
        ax.set_title(f"joint {joint}", fontsize="medium")
    ax = axes[-1]
    shown = [
        c
        for c in combos
        if np.nanmax(np.asarray(stats[c])[keep], initial=0.0) >= COMBINATION_MIN_SHARE
    ]
    other = sum((np.asarray(stats[c])[keep] for c in combos if c not in shown), np.zeros(len(keep)))
    layers = [np.asarray(stats[c])[keep] * 100 for c in shown] + [other * 100]
    labels = [c[len("combination_") : -len("_share")] for c in shown] + ["other"]
    ax.stackplot(
        xs, layers, labels=labels, colors=[f"C{k % 10}" for k in range(len(shown))] + ["0.6"]
    )
    ax.set_title(f"combinations ({'-'.join(joints)})", fontsize="medium")
    for k, ax in enumerate(axes):
        if log:
            ax.set_xscale("log")
        ax.set_xlabel(_label(par_axis))
        ax.set_ylabel("time share (%)")
        ax.set_ylim(0, 100)
        ax.grid(True, alpha=0.3)
        if k == 0 or k == len(axes) - 1:
            ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    failed = len(result) - int(np.sum(result.succeeded))
    fig.suptitle(
        f"Contact modes against {result.names[0]} (located contacts"
        f"{f'; {failed} failed values left out' if failed else ''})",
        fontsize=10,
    )
    return fig


def plot_bifurcation(diagram, signals: Sequence[str] | None = None) -> Figure:
    """Bifurcation diagram (``studies.bifurcation_points``): each value's Poincaré section points
    (once per crank revolution) against the swept parameter, one panel per signal. A periodic
    response is one point per value, period k is k points, scatter is quasi-periodic or chaotic.

    Args:
        diagram: a ``BifurcationDiagram``.
        signals: the signals to show (default all in the diagram).

    Returns:
        The ``Figure``.
    """
    names = list(diagram.points) if signals is None else list(signals)
    unknown = [n for n in names if n not in diagram.points]
    if unknown or not names:
        raise ValueError(
            f"signals {unknown or names} not in the diagram; it has {list(diagram.points)}."
        )
    par_axis = parameter_axis(diagram.parameter)
    values = np.asarray(diagram.values, dtype=float) * par_axis[2]
    log = _log_axis(values)
    fig, axes = _grid(len(names), 2, width=4.2, height=3.0)
    revolutions = np.asarray(diagram.times).shape[-1]
    for ax, name in zip(axes, names, strict=True):
        unit = _signal_unit(name)
        scale, unit = (
            (1e6, "µm") if unit == "m" and "_ecc_" in name else (1.0, UNIT_LABELS.get(unit, unit))
        )
        y = np.asarray(diagram.points[name], dtype=float) * scale
        ax.plot(
            np.repeat(values, y.shape[1]), y.reshape(-1), ".", color="C0", markersize=2.5, alpha=0.7
        )
        failed = ~np.asarray(diagram.succeeded)
        if failed.any():
            _mark_failed(ax, values[failed], "failed")
            ax.legend(fontsize="x-small")
        if log:
            ax.set_xscale("log")
        ax.set_xlabel(_label(par_axis))
        ax.set_ylabel(f"{name} ({unit})" if unit else name)
        ax.grid(True, alpha=0.3)
    fig.suptitle(
        f"Bifurcation diagram: Poincaré section once per crank revolution, {revolutions} "
        f"revolutions per value",
        fontsize=10,
    )
    return fig


def plot_lyapunov_sweep(sweep) -> Figure:
    """The largest Lyapunov exponent against the swept parameter (``studies.lyapunov_sweep``),
    with each estimate's convergence spread as an error bar; λ < 0 is a stable (periodic)
    response, λ > 0 a chaotic one (docs/chaos.md on what λ means with impacts).

    Args:
        sweep: a ``LyapunovSweep``.

    Returns:
        The ``Figure``.
    """
    fig, ax = _new_axes(None)
    par_axis = parameter_axis(sweep.parameter)
    x = np.asarray(sweep.values, dtype=float) * par_axis[2]
    ok = np.asarray(sweep.succeeded)
    order = np.argsort(x, kind="stable")
    keep = order[ok[order]]
    ax.errorbar(
        x[keep],
        np.asarray(sweep.exponents)[keep],
        yerr=np.asarray(sweep.spread)[keep],
        fmt="o-",
        markersize=4,
        capsize=3,
        label="λ (error bar: spread of the running estimate)",
    )
    ax.axhline(0.0, color="k", linewidth=0.8, linestyle="--", label="λ = 0 (chaos above)")
    if (~ok).any():
        _mark_failed(ax, x[~ok], "failed")
    if _log_axis(x):
        ax.set_xscale("log")
    ax.set_xlabel(_label(par_axis))
    ax.set_ylabel("Largest Lyapunov exponent λ (1/s)")
    ax.set_title(
        f"Largest Lyapunov exponent, renormalised every {sweep.interval * 1e3:.4g} ms after "
        f"{sweep.transient * 1e3:.4g} ms",
        fontsize="medium",
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig
