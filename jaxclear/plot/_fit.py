"""Plots of an identification (``jaxclear.identify``): measured against fitted signals, and the
loss history.
"""

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ._common import DPI, _signal_unit, save_figure


def plot_fit(result) -> Figure:
    """Measured and fitted signals of an identification (``jaxclear.identify``), one panel each.

    The measured points are dots, the fitted model a line; the shaded span is the part of the
    record the estimate was fitted to (``result.window_end``); the title gives the estimates
    ± one standard deviation (1σ), and says so when the fit is not a success (``result.success``).
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
    estimates = _lines(
        [f"{n} = {e.value:.6g} ± {e.std:.2g} {e.unit} (1σ)" for n, e in result.parameters.items()]
    )
    if result.success:
        fig.suptitle(estimates, fontsize=9)
    else:
        note = "not a fit (see its reason): the estimates and their ± are unreliable"
        fig.suptitle(f"{estimates}\n{note}", fontsize=9, color="C3")
    return fig


TITLE_WIDTH = 90
"""Characters per title line at the title's font size: the width of the 7-inch figure (three
estimates on one line ran past both edges of fit.png)."""


def _lines(items: list[str]) -> str:
    """``items`` joined by ", ", starting a new line where one would pass ``TITLE_WIDTH``."""
    lines: list[str] = []
    for item in items:
        if lines and len(lines[-1]) + 2 + len(item) <= TITLE_WIDTH:
            lines[-1] += ", " + item
        else:
            lines.append(item)
    return "\n".join(lines)


def plot_loss(result) -> Figure:
    """Loss history of an identification: the scan's best point, then per window (and start) the
    starting point and each accepted Levenberg–Marquardt iteration (log scale; ≈ 1 is a fit to the
    noise level). Rejected trial steps are not entries of the history."""
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
    ax.set_xlabel("step of the fit (scan's best point; each start and accepted iteration)")
    ax.set_ylabel("loss (mean squared residual / noise²)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return fig


def save_fit_plots(result, out_dir, *, dpi: int = DPI) -> list[Path]:
    """Write fit.png (``plot_fit``) and loss.png (``plot_loss``) into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [
        save_figure(plot_fit(result), out_dir, "fit.png", dpi),
        save_figure(plot_loss(result), out_dir, "loss.png", dpi),
    ]
