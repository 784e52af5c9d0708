"""Shared pieces of the plots: axis titles and units, figure size and resolution, new axes, the
atomic PNG writer ``save_figure``, and the parameter axes, panel grids and failure marks that the
ensemble and chaos plots have in common.
"""

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..solve import BODY_OUTPUTS, CLEARANCE_OUTPUTS

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

FIGSIZE = (7.0, 4.0)  # inches
DPI = 110  # ~770 x 440 px, a few tens of kB per PNG


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


def _new_axes(ax):
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=FIGSIZE, dpi=DPI, layout="constrained")
    return fig, fig.add_subplot()


def save_figure(fig, out_dir: Path, filename: str, dpi: int) -> Path:
    """Write ``fig`` as ``out_dir/filename`` (PNG at ``dpi``) through a temporary file renamed into
    place, so an interrupted write never leaves a truncated plot under the final name."""
    path = out_dir / filename
    tmp = out_dir / f".{filename}.tmp.png"
    fig.savefig(tmp, dpi=dpi)
    tmp.replace(path)
    return path


_SIGNAL_UNITS = {"slider_x": "m", "slider_v": "m/s", "slider_a": "m/s²"}


def _signal_unit(name: str) -> str:
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


# --- shared by the ensemble and chaos plots ------------------------------------------------------

ENSEMBLE_FAILED_STYLE: dict[str, Any] = dict(
    marker="x", color="C3", linestyle="none", markersize=6, zorder=4
)
SWEEP_LOG_RATIO = 50.0
"""A sweep over positive values spanning at least this ratio is drawn on a log axis."""
_LENGTH_FIELDS = ("bearing_radius", "journal_radius", "length", "free_length", "layer_thickness")
_MODULUS_FIELDS = ("young_modulus", "bearing_young", "journal_young", "foundation_modulus")


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


def _grid(count: int, columns: int, width: float = 3.4, height: float = 2.7):
    """A figure with ``count`` panels on a grid of ``columns`` columns (unused panels removed)."""
    columns = max(1, min(columns, count))
    rows = -(-count // columns)
    fig = Figure(figsize=(width * columns, height * rows + 0.5), dpi=DPI, layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax in axes[count:]:
        ax.remove()
    return fig, list(axes[:count])


def _mark_failed(ax, x: np.ndarray, label: str | None) -> None:
    """Red crosses just above the bottom of the axes at the parameter values of failed members."""
    if x.size:
        ax.plot(x, np.full(x.shape, 0.03), transform=ax.get_xaxis_transform(),
                label=label, **ENSEMBLE_FAILED_STYLE)  # fmt: skip


def _log_axis(x: np.ndarray) -> bool:
    """Positive values spanning at least ``SWEEP_LOG_RATIO``: drawn on a log axis."""
    return bool(np.all(x > 0) and x.max() >= SWEEP_LOG_RATIO * x.min())
