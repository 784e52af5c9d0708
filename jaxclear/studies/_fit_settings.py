"""What identification is set with and what it returns: ``FitSettings``, ``Estimate``,
``IdentificationResult``, and the noise-level bound of its verdict (the method: ``_identify.py``)."""

import dataclasses
import math
from typing import Any

import equinox as eqx
import numpy as np

from .._core._errors import ModelError
from ..solve._solver import SolverConfig

DEFAULT_HORIZONS = None
"""The growing windows by default: chosen from the data and a first simulation (the first up to
the first contacts, then twice as long each: ``_global_search``), not fixed fractions."""

INFORMATIVE_SPREAD = 1.0
"""Two scanned points whose losses differ by at most this (1 = the noise level) tie on a window."""

TIED_SHARE = 0.25
"""A window ties (tells the scanned points apart too little to pick one) when at least this share
of the other scanned points tie with the best (``INFORMATIVE_SPREAD``). Before the first impact
a clearance changes nothing, so most points tie exactly; a window that carries the parameter
separates its best point from all but its nearest neighbours."""

LOSS_GROWTH = 2.0
"""A window whose fitted loss exceeds this multiple of the best loss of the shorter windows is
beyond the horizon the model can follow (chaotic impact sequence, model error): the fit keeps
the estimate of the shorter windows and says so in ``status``."""

NOISE_LEVEL_LOSS = 2.0
"""Largest final loss of a fit that reaches the noise level, for the usual hundreds of residuals
(``noise_level_bound`` raises it for few). Why 2: at the noise level the loss is χ²/N (mean 1,
standard deviation √(2/N): for N = 100 residuals a loss of 2 is 7 standard deviations out); noise
levels estimated from the data (``Measurements``, third differences) are within about 15 % of the
truth (notebook 06), which moves the loss by a factor of up to 1.15² ≈ 1.3; and the smooth contact
model follows sharp impacts to within the noise (docs/identification.md, losses 0.7–1.3). A loss
above 2 means residuals 1.4 times the noise on average: the model does not follow the data. Equal
to ``LOSS_GROWTH``, the loss growth at which a window is dropped."""

NOISE_LEVEL_Z = 4.753
"""Standard normal quantile at 1 − 1e-6: the chi-square bound of ``noise_level_bound`` is exceeded
by a fit at the noise level once in a million."""

DEFAULT_SCAN_POINTS = 16
"""Points of the global scan's first design per fitted parameter (one solve each, vectorised in
chunks); the design is then refined to the basin width it measures (``DEFAULT_MAX_SCAN_POINTS``)."""

DEFAULT_MAX_SCAN_POINTS = 256
"""Most points the global scan may refine its design to, whatever the number of parameters (one
solve each over the first window). For one parameter the grid goes 16, 46, 136 points (the next,
406, is past it): steps of 2.1 % for a clearance scanned over a factor 16, against basins measured
at about ±2 % (200 and 5000 rpm, docs/identification.md). For several, up to 256 Halton points."""

DEFAULT_STARTS = 3
"""Levenberg–Marquardt runs on the first window, from the best scanned points of distinct basins."""

DEFAULT_SCAN_RTOL = 1e-6
"""Relative tolerance of the global scan's solves (absolute: 1e-3 of it), with the fit's method.
The scan only ranks points by their loss to find the basins; the refinement then solves at the
fit's own tolerance. Measured on the held-out and tuning records (docs/identification.md): the
same scanned basins and the same estimates to the last printed digit as at the fit's rtol 1e-12,
and the 200 rpm fit in 65 s instead of 109 s."""

SCAN_ATOL_FACTOR = 1e-3
"""The scan's absolute tolerance is this fraction of ``scan_rtol`` (as ``recommended_solver``'s)."""

SCAN_CHUNK = 8
"""Members per vectorised scan solve of the ``"lockstep"`` scan engine (bounds memory; one
compilation per chunk size)."""

SCAN_REFILL_CHUNK = 64
"""Members per chunk of the ``"refill"`` scan engine (solved on ``DEFAULT_LANES`` refilled lanes).
The README's fit (5000 rpm, joint B, 136 scanned points in designs of 16, 30 and 90), scan timed
in-process with a warm cache on 2026-11-28: 0.84–0.89 s with chunks of 32, 0.88–0.91 s with 64,
1.48 s with 256 (each chunk's trajectories cost their padding), against 2.57–3.17 s for lockstep
chunks of 8. A design of several parameters is larger (32 points at first for two)."""

SCAN_ENGINES = ("refill", "lockstep")
"""How the global scan solves its points (``FitSettings.scan_engine``)."""

DEFAULT_MAX_ITERATIONS = 20
"""Levenberg–Marquardt iterations per window."""

DEFAULT_TOLERANCE = 1e-6
"""Relative decrease of the loss (and relative step) at which a window's refinement has converged."""


def noise_level_bound(count: int | float, parameters: int) -> float:
    """Largest loss (mean squared normalised residual) of a fit that reaches the noise level.

    The larger of ``NOISE_LEVEL_LOSS`` and the chi-square bound: at the noise level Σr² follows a
    chi-square law with ν = count − parameters degrees of freedom, whose quantile at 1 − 1e-6
    (``NOISE_LEVEL_Z``) is about ν (1 − 2/(9ν) + z √(2/(9ν)))³ (Wilson–Hilferty: at most 5 %
    above the exact quantile from ν = 5 on, more lenient below), divided by ``count``. It governs
    only for a few tens of residuals or fewer, where chance alone can double the loss.

    Args:
        count: number of residuals (signals × instants in the windows used).
        parameters: number of fitted parameters.
    """
    dof = max(float(count) - parameters, 1.0)
    a = 2.0 / (9.0 * dof)
    quantile = dof * (1.0 - a + NOISE_LEVEL_Z * math.sqrt(a)) ** 3
    return max(NOISE_LEVEL_LOSS, quantile / max(float(count), 1.0))


def _fractions(horizons: Any) -> Any:
    """``horizons`` as a tuple of floats; anything that is not a sequence of numbers unchanged,
    for ``__check_init__`` to refuse."""
    if isinstance(horizons, str | bytes):
        return horizons
    try:
        return tuple(float(h) for h in horizons)
    except (TypeError, ValueError):
        return horizons


def _whole(value: Any) -> Any:
    """A whole number (``4``, ``4.0``, ``np.int64(4)``) as an ``int``; anything else unchanged."""
    if isinstance(value, bool | np.bool_) or not isinstance(
        value, int | float | np.integer | np.floating
    ):
        return value
    return int(value) if math.isfinite(value) and int(value) == value else value


def _number(value: Any) -> Any:
    """A real number as a ``float``; anything else unchanged."""
    if isinstance(value, bool | np.bool_) or not isinstance(
        value, int | float | np.integer | np.floating
    ):
        return value
    return float(value)


class FitSettings(eqx.Module):
    """How ``identify`` fits: the growing windows, the global scan and the optimiser (all static).

    Attributes:
        horizons: increasing fractions of the record in (0, 1], the last 1: the growing windows;
            ``None`` (default): chosen from the data and a first simulation, the first up to the
            first contacts, then twice as long each.
        scan_points: size of the global scan's first design; ``None``: ``DEFAULT_SCAN_POINTS``
            per parameter; 0 (or 1): no scan, the refinement starts from the initial values.
        max_scan_points: most points the scan refines its design to, following the basin width it
            measures; ``None``: ``DEFAULT_MAX_SCAN_POINTS`` (never fewer than the first design).
        starts: Levenberg–Marquardt runs on the first window, from the best scanned points of
            distinct basins (≥ 1).
        max_iterations: Levenberg–Marquardt iterations per window (≥ 1).
        tolerance: relative decrease of the loss (and relative step) below which a window's
            refinement has converged (≥ 0).
        scan_rtol: relative tolerance of the global scan's solves (absolute tolerance 1e-3 of
            it; the fit's method and other settings); ``None``: the fit's own solver settings.
        scan_engine: how the scan solves its points: ``"refill"`` (default; chunks of
            ``SCAN_REFILL_CHUNK`` on refilled lanes, ``jaxclear.solve.solve_members``) or
            ``"lockstep"`` (vmapped ``simulate`` in chunks of ``SCAN_CHUNK``, each waiting for its
            slowest point). Both give the same losses to the scan's tolerance.

    Raises:
        ModelError: a field out of its range, naming the field and what is allowed.
    """

    horizons: tuple[float, ...] | None = eqx.field(
        static=True, default=DEFAULT_HORIZONS, converter=_fractions
    )
    scan_points: int | None = eqx.field(static=True, default=None, converter=_whole)
    max_scan_points: int | None = eqx.field(static=True, default=None, converter=_whole)
    starts: int = eqx.field(static=True, default=DEFAULT_STARTS, converter=_whole)
    max_iterations: int = eqx.field(static=True, default=DEFAULT_MAX_ITERATIONS, converter=_whole)
    tolerance: float = eqx.field(static=True, default=DEFAULT_TOLERANCE, converter=_number)
    scan_rtol: float | None = eqx.field(static=True, default=DEFAULT_SCAN_RTOL, converter=_number)
    scan_engine: str = eqx.field(static=True, default="refill")

    def __check_init__(self):
        horizons = self.horizons
        if horizons is not None and (
            not isinstance(horizons, tuple)
            or not horizons
            or not all(isinstance(h, float) for h in horizons)
            or any(not 0.0 < h <= 1.0 for h in horizons)
            or horizons[-1] != 1.0
        ):
            raise ModelError(
                f"horizons must be None (from the first contacts) or increasing fractions of the "
                f"record in (0, 1] ending with 1, e.g. (0.25, 0.5, 1.0); got {horizons!r}."
            )
        if horizons is not None and any(
            b <= a for a, b in zip(horizons, horizons[1:], strict=False)
        ):
            raise ModelError(
                f"horizons must be increasing (each window longer than the one before), got "
                f"{horizons!r}."
            )
        n = self.scan_points
        if n is not None and (not isinstance(n, int) or isinstance(n, bool) or n < 0):
            raise ModelError(
                f"scan_points must be None ({DEFAULT_SCAN_POINTS} per parameter), 0 (no scan: "
                f"start from the initial values) or a positive whole number, got {n!r}."
            )
        n = self.max_scan_points
        if n is not None and (not isinstance(n, int) or isinstance(n, bool) or n < 0):
            raise ModelError(
                f"max_scan_points must be None ({DEFAULT_MAX_SCAN_POINTS}) or a whole number of at "
                f"least 0 (most points the scan refines its design to), got {n!r}."
            )
        n = self.starts
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise ModelError(
                f"starts must be a whole number of at least 1 (Levenberg–Marquardt runs from the "
                f"best scanned points), got {n!r}."
            )
        n = self.max_iterations
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise ModelError(
                f"max_iterations must be a whole number of at least 1 (Levenberg–Marquardt "
                f"iterations per window), got {n!r}."
            )
        tol = self.tolerance
        if not isinstance(tol, float) or not math.isfinite(tol) or tol < 0:
            raise ModelError(
                f"tolerance must be a finite number of at least 0 (relative decrease of the loss "
                f"at which a window has converged, e.g. 1e-6), got {tol!r}."
            )

        rtol = self.scan_rtol
        if rtol is not None and (not isinstance(rtol, float) or not 0.0 < rtol < 1.0):
            raise ModelError(
                f"scan_rtol must be None (the fit's solver) or a relative tolerance in (0, 1) for "
                f"the global scan's solves, e.g. 1e-6; got {rtol!r}."
            )
        if not isinstance(self.scan_engine, str) or self.scan_engine not in SCAN_ENGINES:
            raise ModelError(
                f"scan_engine must be 'refill' (refilled lanes, the default) or 'lockstep' (how the "
                f"global scan solves its points), got {self.scan_engine!r}."
            )

    def scan_count(self, parameters: int) -> int:
        """Points of the global scan for ``parameters`` fitted parameters (≤ 1: no scan)."""
        return DEFAULT_SCAN_POINTS * parameters if self.scan_points is None else self.scan_points

    def scan_budget(self, parameters: int) -> int:
        """Most points the scan may refine to (at least its first design)."""
        most = DEFAULT_MAX_SCAN_POINTS if self.max_scan_points is None else self.max_scan_points
        return max(most, self.scan_count(parameters))


@dataclasses.dataclass(frozen=True)
class Estimate:
    """One fitted parameter.

    Attributes:
        value: the estimate. std: its standard deviation (1σ) from the Gauss–Newton covariance
            (module doc). initial, lower, upper: the start and bounds of the fit. unit: SI unit.
    """

    value: float
    std: float
    initial: float
    lower: float
    upper: float
    unit: str

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


UNCERTAINTY = (
    "std is one standard deviation (1σ) of each estimate: the Gauss–Newton covariance over the "
    "windows used, scaled by the reduced chi-square when above 1, plus the drift of the estimate "
    "between the last two windows, plus for a clearance the contact model's smoothing width"
)
"""What ``std`` is, as fit.json says it (``IdentificationResult.summary``)."""


@dataclasses.dataclass
class IdentificationResult:
    """What ``identify`` found.

    Attributes:
        parameters: ``{name: Estimate}``.
        values: ``{name: value}`` (the estimates; pass to ``jaxclear.with_parameters``).
        covariance: (p, p) covariance of the estimates, in their units (module doc).
        loss: final mean squared normalised residual over the windows used (≈ 1 at the noise
            level). loss_whole_record: the same over the whole record.
        window_end: end of the longest window whose fit was kept, s: the estimate and its
            covariance come from the data up to this time (``LOSS_GROWTH``).
        chi2_scale: s² used in the covariance (≥ 1).
        noise: σ per signal used for the weights; noise_estimated: whether it was estimated.
        history: one dict per evaluation that changed the estimate or ended a stage:
            ``stage`` (``"scan"``, ``"window 1/3"``, ...), ``horizon`` (s), ``iteration``, ``loss``.
        iterations: Levenberg–Marquardt iterations over all windows.
        converged: the last window's refinement met its tolerance. status: one line; on a failed
            fit it starts with ``NOT_A_FIT`` and ``reason``.
        success: the estimates and their standard deviations are finite, a window told the
            scanned points apart, and ``loss`` reaches the noise level (``noise_level_bound``).
            reason: why not, with what to try (empty on success). A result that is not a success
            is no estimate of the parameters: its ``std`` are not reliable either.
        time: wall time of the fit, s (compilation included).
        scan: the global scan (empty if none): ``values`` (K, p), their capped ``loss`` (K,)
            (``_global_search.scan_loss``), the design's ``spacing`` and the ``basin_width`` it
            measured (unit coordinates; None if not measured), the scanned window's
            ``window_end`` (s).
        t: data times, s. measured, fitted: ``{signal: (N,)}`` at ``t``.
        solver: the ``SolverConfig`` used.
    """

    parameters: dict[str, Estimate]
    covariance: np.ndarray
    loss: float
    loss_whole_record: float
    window_end: float
    chi2_scale: float
    noise: dict[str, float]
    noise_estimated: dict[str, bool]
    history: list[dict[str, Any]]
    iterations: int
    converged: bool
    status: str
    success: bool
    reason: str
    time: float
    scan: dict[str, np.ndarray]
    t: np.ndarray
    measured: dict[str, np.ndarray]
    fitted: dict[str, np.ndarray]
    solver: SolverConfig

    @property
    def values(self) -> dict[str, float]:
        return {name: e.value for name, e in self.parameters.items()}

    def summary(self) -> dict[str, Any]:
        """A JSON-ready dict (what ``jaxclear fit`` writes as fit.json)."""
        return {
            "success": self.success,
            "reason": self.reason,
            "parameters": {n: e.as_dict() for n, e in self.parameters.items()},
            "uncertainty": UNCERTAINTY,
            "covariance": self.covariance.tolist(),
            "loss": self.loss,
            "loss_whole_record": self.loss_whole_record,
            "window_end_s": self.window_end,
            "chi2_scale": self.chi2_scale,
            "noise": self.noise,
            "noise_estimated": self.noise_estimated,
            "iterations": self.iterations,
            "converged": self.converged,
            "status": self.status,
            "time_s": self.time,
            "history": self.history,
            "scan": {k: _json_ready(v) for k, v in self.scan.items()},
            "solver": {
                "method": self.solver.method,
                "rtol": self.solver.rtol,
                "atol": self.solver.atol,
            },
        }


def _json_ready(value: Any) -> Any:
    """An array as nested lists; a float that is not finite (a basin width not measured) as None."""
    if np.ndim(value) == 0 and isinstance(value, float | np.floating) and not math.isfinite(value):
        return None
    return np.asarray(value).tolist()
