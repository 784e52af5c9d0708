"""Plots of an ensemble (``EnsembleResult`` of a Monte Carlo study or a sweep): histograms,
statistics against drawn or swept parameters, contact modes against the swept parameter, the
statistics' axis titles and units, and the PNGs the ``montecarlo`` and ``sweep`` commands write.
"""

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ._common import (
    DPI,
    UNIT_LABELS,
    _grid,
    _label,
    _log_axis,
    _mark_failed,
    _signal_unit,
    _title,
    parameter_axis,
    save_figure,
)


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
        _statistic_panel(ax, x, ok, k, stat_axis, par_axis)
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
        _statistic_panel(ax, x, ok, k, stat_axis, par_axis)
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


def _statistic_panel(ax, x, ok, k: int, stat_axis, par_axis) -> None:
    """The common finish of a statistic-against-parameter panel: failed members as red crosses
    (legend on the first panel only), axes labelled, grid."""
    _mark_failed(ax, x[~ok], "failed" if k == 0 else None)
    _panel(ax, stat_axis, "y")
    ax.set_xlabel(_label(par_axis))
    ax.grid(True, alpha=0.3)
    if k == 0 and (~ok).any():
        ax.legend(fontsize="x-small", loc="best")
