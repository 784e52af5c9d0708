"""Identification's global stage: the first window, the scan design, the measured basin width and
the starting points of the multi-start refinement (NumPy; the solves are ``_identify.py``'s).

Why: an impact sequence makes the loss a narrow well around the truth on a plateau (two responses
whose impacts fall at different instants differ by about the same amount however far apart their
parameters are). A scan coarser than that well lands beside it, and a local method started there
stalls on a wrong answer (issue 23: at 200 rpm the well around the true clearance is about
±5 % wide over the first 10 ms, and a 16-point scan over [0.125, 2] mm spaced 20 % apart missed
it). The stage therefore

1. fits first on the **shortest window that carries the parameters** (``first_window_end``): up
   to the end of the ``FIRST_CONTACTS``-th contact of a first simulation at the initial values,
   and at least as long after the instant where the data first depart from that simulation
   (the data's own first contact, when it comes earlier) as the simulation needed from its first
   contact to its ``FIRST_CONTACTS``-th. Longer windows hold more impacts and narrower wells;
2. scans a design (``Design``: a nested grid for one parameter, a scrambled Halton sequence for
   several) on that window with a **capped loss** (``scan_loss``: each squared residual at most
   ``SCAN_CAP``²; an impact sampled at one instant can be 2000 σ, and a model whose impact lands on
   a sample would otherwise rank by that one residual);
3. **measures the basin width** from the scanned responses themselves (``basin_widths``: for each
   point, how far away in the scan's unit coordinates another parameter value makes a response
   that differs from it by ``BASIN_LEVEL`` of its typical difference from the rest), and refines
   the design until its spacing is at most that width (``needs_refinement``), within
   ``FitSettings.max_scan_points``;
4. returns the best few points of distinct wells (``starting_points``) for Levenberg–Marquardt.
"""

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ._fit_settings import INFORMATIVE_SPREAD
from ._parameter_space import FitParameter, _halton

FIRST_CONTACTS = 3
"""Contacts the first window holds: the first carries the parameters (its instant), the next ones
their effect on the rebound, while the loss around the truth is still one smooth well."""

DEPARTURE = 5.0
"""A data sample whose residual against the first simulation exceeds this (in σ) marks where the
data first depart from it (5 σ: once in 1.7 million samples at the noise level)."""

SCAN_CAP = 10.0
"""Largest |residual| (σ) a sample contributes to the scan's loss and to the basin widths."""

BASIN_LEVEL = 0.5
"""The basin of a point ends where the capped difference of responses reaches this fraction of the
point's typical (median) difference from the other scanned points: the plateau level."""

FAR_SAMPLE = 32
"""Other points against which a point's typical difference is measured (the median over them)."""

REFINE_FACTOR = 3
"""A one-parameter grid is refined by this factor (3: the old points stay grid points)."""


def first_window_end(
    t0: float,
    t_end: float,
    contacts: Sequence[tuple[float, float]],
    departure: float | None,
    t_data: np.ndarray,
    min_samples: int,
) -> tuple[float, str]:
    """End of the first window (module doc, step 1).

    Args:
        t0, t_end: start of the simulation and end of the record, s.
        contacts: (onset, end) of the first simulation's contacts (all joints), s.
        departure: first data time where the data depart from the first simulation (``DEPARTURE``),
            or None.
        t_data: data times (increasing).
        min_samples: the window holds at least this many data instants.

    Returns:
        (end in s, a note saying how it was chosen).
    """
    contacts = sorted(contacts)
    if len(contacts) >= FIRST_CONTACTS:
        first, kth = contacts[0][0], contacts[FIRST_CONTACTS - 1][1]
        end = kth
        note = f"end of contact {FIRST_CONTACTS} of the first simulation at {kth:.6g} s"
        if departure is not None and departure + (kth - first) > end:
            end = departure + (kth - first)
            note = (
                f"the data depart from the first simulation at {departure:.6g} s; "
                f"{kth - first:.3g} s after it hold {FIRST_CONTACTS} contacts"
            )
    else:
        end = t_end
        note = f"the first simulation has {len(contacts)} contacts over the record"
    enough = float(t_data[min(max(min_samples, 1), len(t_data)) - 1])
    if enough > end:
        end, note = enough, f"{note}; lengthened to hold {min_samples} data instants"
    return min(max(end, float(t_data[0])), t_end), note


def window_ladder(t0: float, t_end: float, first: float, growth: float = 2.0) -> tuple[float, ...]:
    """Fractions of the record [t0, t_end] of the growing windows: first, growth × first, ...,
    then the whole record."""
    span = t_end - t0
    fractions, length = [], first - t0
    while length < span * (1 - 1e-9):
        fractions.append(length / span)
        length *= growth
    fractions.append(1.0)
    return tuple(fractions)


class Design:
    """Scan points in the unit cube of the scan's coordinates, nested under refinement.

    Coordinates: per parameter, log-uniform between its bounds when both are positive and span more
    than a factor 3, else uniform (an unbounded direction: initial ± 50 %). The initial point comes
    first. One parameter: the grid (i + ½)/n, refined by ``REFINE_FACTOR`` (the old points stay).
    Several: a scrambled Halton sequence, extended.
    """

    def __init__(self, specs: Sequence[FitParameter], count: int, seed: int = 0):
        self.specs = tuple(specs)
        self.seed = seed
        self.p = len(specs)
        ranges = []
        for q in specs:
            lo, hi = q.lower, q.upper
            if not (math.isfinite(lo) and math.isfinite(hi)):
                lo, hi = q.initial - 0.5 * abs(q.initial), q.initial + 0.5 * abs(q.initial)
            ranges.append((lo, hi, lo > 0 and hi / lo > 3.0))
        self.ranges = ranges
        self.grid = max(count - 1, 1)  # one parameter: points of the grid (the initial point aside)
        start = self.to_unit(np.array([[q.initial for q in specs]]))
        self.units = np.concatenate([start, self._points(0, self.grid)])

    def _points(self, old: int, new: int) -> np.ndarray:
        """Points old..new-1 of the design sequence (Halton), or the grid of ``new`` points."""
        if self.p == 1:
            return ((np.arange(new) + 0.5) / new)[:, None]
        return _halton(new, self.p, self.seed)[old:]

    def refine(self, count: int) -> np.ndarray:
        """Add points up to about ``count`` in all; returns the new points' unit coordinates."""
        if self.p == 1:
            factor = REFINE_FACTOR ** max(
                1, math.ceil(math.log(max(count - 1, 1) / self.grid) / math.log(REFINE_FACTOR))
            )
            new = self.grid * factor
            fresh = np.array([j for j in range(new) if j % factor != (factor - 1) // 2])
            added = ((fresh + 0.5) / new)[:, None]
            self.grid = new
        else:
            added = self._points(len(self.units) - 1, count - 1)
        self.units = np.concatenate([self.units, added])
        return added

    def next_count(self, current: int, spacing: float, width: float, budget: int) -> int:
        """Points needed for a spacing of ``width`` (at most ``budget``; at least one refinement)."""
        if self.p == 1:
            return min(budget, 1 + self.grid * REFINE_FACTOR)
        need = math.ceil(current * (spacing / width) ** self.p)
        return min(budget, max(need, 2 * current))

    def can_refine(self, budget: int) -> bool:
        if self.p == 1:
            return 1 + self.grid * REFINE_FACTOR <= budget
        return len(self.units) < budget

    def to_values(self, units: np.ndarray) -> np.ndarray:
        out = np.empty_like(units)
        for k, (lo, hi, log) in enumerate(self.ranges):
            s = units[:, k]
            out[:, k] = np.exp(np.log(lo) + s * np.log(hi / lo)) if log else lo + s * (hi - lo)
        return out

    def to_unit(self, values: np.ndarray) -> np.ndarray:
        out = np.empty_like(values, dtype=float)
        for k, (lo, hi, log) in enumerate(self.ranges):
            v = values[:, k]
            out[:, k] = np.log(v / lo) / np.log(hi / lo) if log else (v - lo) / (hi - lo)
        return out

    def spacing(self) -> float:
        """The design's spacing in unit coordinates: the grid step (one parameter), else the median
        distance from a point to its nearest neighbour."""
        if self.p == 1:
            return 1.0 / self.grid
        return float(np.median(nearest(self.units)[1]))


def nearest(units: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of and distance to each point's nearest other point (unit coordinates)."""
    d = np.sqrt(np.sum((units[:, None, :] - units[None, :, :]) ** 2, axis=-1))
    np.fill_diagonal(d, np.inf)
    j = np.argmin(d, axis=1)
    return j, d[np.arange(len(units)), j]


def scan_loss(residuals: np.ndarray, count: int | float) -> np.ndarray:
    """Capped loss of each scanned point: Σ min(r², ``SCAN_CAP``²) / count (inf: a failed solve).

    Args:
        residuals: (K, M) normalised residuals over the window (0 outside it).
        count: residuals in the window.
    """
    r2 = np.minimum(np.square(residuals), SCAN_CAP**2)
    loss = np.sum(r2, axis=1) / count
    return np.where(np.all(np.isfinite(residuals), axis=1), loss, np.inf)


def _difference(a: np.ndarray, b: np.ndarray, count: int | float) -> Any:
    """Capped mean squared difference of responses (rows), from their residuals (same data)."""
    return np.sum(np.minimum(np.square(a - b), SCAN_CAP**2), axis=-1) / count


def basin_widths(
    units: np.ndarray, residuals: np.ndarray, count: int | float, seed: int = 0
) -> np.ndarray:
    """Each scanned point's basin half-width in unit coordinates (module doc, step 3).

    A point's typical difference F is the median capped mean square difference (in σ²) of its
    response from up to ``FAR_SAMPLE`` other points; its basin ends where the difference reaches
    ``BASIN_LEVEL`` · F. Of its 2p + 2 nearest neighbours, one at distance d whose difference D is
    past that level puts the edge at about d √(``BASIN_LEVEL`` F / D) (the difference grows about
    quadratically inside a basin), but no nearer than a neighbour still inside it; with none past
    it, the basin reaches at least the farthest of them. So a scan coarser than the basin gives a
    width smaller than its spacing, and a finer one the distance where the responses part. NaN
    where the point tells nothing (F ≤ ``INFORMATIVE_SPREAD``: its response is like every other's,
    e.g. before any contact) or a solve failed.
    """
    k, p = units.shape
    ok = np.all(np.isfinite(residuals), axis=1)
    dist = np.sqrt(np.sum((units[:, None, :] - units[None, :, :]) ** 2, axis=-1))
    rng = np.random.default_rng(seed)
    out = np.full(k, np.nan)
    for i in np.flatnonzero(ok):
        others = np.flatnonzero(ok & (np.arange(k) != i))
        if others.size == 0:
            continue
        sample = (
            rng.choice(others, FAR_SAMPLE, replace=False) if others.size > FAR_SAMPLE else others
        )
        far = float(np.median(_difference(residuals[sample], residuals[i], count)))
        if not far > INFORMATIVE_SPREAD:
            continue
        level = BASIN_LEVEL * far
        near = others[np.argsort(dist[i, others], kind="stable")[: 2 * p + 2]]
        d, diff = dist[i, near], _difference(residuals[near], residuals[i], count)
        past = diff >= level
        if not np.any(past):
            out[i] = float(np.max(d))
            continue
        edge = d[past] * np.sqrt(level / diff[past])
        j = int(np.argmin(edge))
        inside = d[~past][d[~past] < d[past][j]]
        out[i] = max(float(edge[j]), float(np.max(inside)) if inside.size else 0.0)
    return out


def measured_width(widths: np.ndarray) -> float:
    """The basin width the scan must resolve: the median of the points' widths (NaN if none)."""
    w = widths[np.isfinite(widths)]
    return float(np.median(w)) if w.size else math.nan


def needs_refinement(spacing: float, width: float) -> bool:
    """Whether the design is coarser than the measured basin width: a basin of half-width w has a
    scan point within w/2 of its centre only if the spacing is at most w."""
    return math.isfinite(width) and spacing > width


def starting_points(
    units: np.ndarray, loss: np.ndarray, count: int, separation: float
) -> list[int]:
    """Indices of the best ``count`` points of distinct basins: in order of loss, each more than
    ``separation`` (unit coordinates) from those taken before."""
    chosen: list[int] = []
    for i in np.argsort(loss, kind="stable"):
        if not np.isfinite(loss[i]) or len(chosen) == count:
            break
        if all(np.linalg.norm(units[i] - units[c]) > separation for c in chosen):
            chosen.append(int(i))
    return chosen


def resolve_basins(
    design: Design,
    residuals: np.ndarray,
    evaluate: Callable[[np.ndarray], np.ndarray],
    count: int | float,
    budget: int,
) -> tuple[np.ndarray, float, float]:
    """Refine ``design`` until its spacing is at most the basin width measured on its responses
    (module doc, step 3), or its size would pass ``budget``.

    Args:
        design: the scanned design (refined in place).
        residuals: (K, M) normalised residuals of its K points over the window.
        evaluate: residuals (k, M) of new points given in unit coordinates (k, p).
        count: residuals in the window.
        budget: most points.

    Returns:
        (residuals of all points, in the design's order; measured half-width; spacing), both in unit
        coordinates; the width is NaN where no point told anything.
    """
    while True:
        width, spacing = (
            measured_width(basin_widths(design.units, residuals, count)),
            design.spacing(),
        )
        if not needs_refinement(spacing, width) or not design.can_refine(budget):
            return residuals, width, spacing
        added = design.refine(design.next_count(len(design.units), spacing, width, budget))
        residuals = np.concatenate([residuals, evaluate(added)])
