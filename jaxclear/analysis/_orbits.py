"""Orbits of one result: phase portraits and the distinct points of a Poincaré section."""

import numpy as np
from jaxtyping import Array, Float

from ._signals import checked_signal_names, signals


def phase_portrait(
    traj, x: str, y: str, *, start: float | None = None
) -> tuple[Float[Array, "*batch N"], Float[Array, "*batch N"]]:
    """Two signals of a trajectory against each other, e.g. ``("slider_x", "slider_v")`` or a
    journal orbit ``("B_ecc_x", "B_ecc_y")``: a closed curve for a periodic response.

    Args:
        traj: a ``Trajectory``.
        x, y: signal names (``jaxclear.signal_names``).
        start: leave out the samples before this time, s (start-up).

    Returns:
        ``(x values, y values)`` in SI units.

    Raises:
        ValueError: an unknown name, or ``start`` after the last sample.
    """
    names = checked_signal_names(traj.mechanism, (x, y), "x, y")
    values = signals(traj, names)
    xs, ys = values[x], values[y]
    if start is not None:
        t = np.asarray(traj.t)
        t = t.reshape(-1, t.shape[-1])[0]
        keep = np.flatnonzero(t >= start)
        if keep.size == 0:
            raise ValueError(f"start = {start} s is after the last sample ({t[-1]} s).")
        xs, ys = xs[..., keep], ys[..., keep]
    return xs, ys


def distinct_points(points, tolerance: float) -> np.ndarray:
    """Number of distinct values among section points, per row: 1 for a periodic response
    (period 1), k for period k, about the number of points for a quasi-periodic or chaotic one.

    Values closer than ``tolerance`` (absolute, in the signal's unit) after sorting are one value;
    choose it above the solver's scatter of a periodic orbit (docs/chaos.md) and below the
    separation of the branches you want to tell apart. NaN points are ignored (0 for a row of NaN).

    Args:
        points: (..., revolutions) section values (array-like).
        tolerance: ≥ 0.

    Returns:
        Integer array of the leading shape.
    """
    if not tolerance >= 0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance!r}.")
    x = np.asarray(points, dtype=float)
    rows = x.reshape(-1, x.shape[-1]) if x.ndim else x.reshape(1, 1)
    counts = []
    for row in rows:
        row = np.sort(row[np.isfinite(row)])
        counts.append(0 if row.size == 0 else 1 + int(np.sum(np.diff(row) > tolerance)))
    return np.asarray(counts, dtype=int).reshape(x.shape[:-1])
