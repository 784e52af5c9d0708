"""Plots of the chaos studies: the bifurcation diagram (``studies.bifurcation_points``) and the
largest Lyapunov exponent against the swept parameter (``studies.lyapunov_sweep``).
"""

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from ._common import (
    UNIT_LABELS,
    _grid,
    _label,
    _log_axis,
    _mark_failed,
    _new_axes,
    _signal_unit,
    parameter_axis,
)


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
