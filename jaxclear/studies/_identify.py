"""Identification: fit mechanism parameters (clearances, contact, friction, masses) to measured signals.

Weighted least squares. With data y_s(t_i) for signals s (``slider_x``, ``slider_a``,
``crank_torque``, a joint's ``B_ecc_x``, ... the columns ``jaxclear run`` writes) and noise levels
σ_s, the residuals are r_si(θ) = (ŷ_s(t_i; θ) − y_s(t_i)) / σ_s, with ŷ from one ``simulate`` from
the data's start state (journals as the mechanism places them, centred by default), and the loss
is the mean of r² (≈ 1 at a fit to the noise level).

Why growing windows: the impact sequence makes the response after many impacts a rough function
of the parameters (docs/model.md §5b); a loss over the whole record has many local minima. The fit
therefore goes through ``FitSettings.horizons``: first over the start of the record, where the
loss is smooth around the truth, then over longer and longer windows, each started from the
previous estimate (continuation). Where the response is chaotic (the benchmark slider–crank at
200 rpm with gravity: the pin bounces round the whole clearance, and a 0.1 % change of clearance
moves the slider by 30 µm after 90 ms), no model follows a long record to its noise level; a
window whose fitted loss grows past ``LOSS_GROWTH`` times that of the shorter ones is not used,
and the result says up to which time the data were fitted (``window_end``).

Global scan (``_global_scan``): before the refinement, the loss of the first window is evaluated
at points spread over the bounds (one vectorised solve per chunk of ``SCAN_CHUNK``) and the best
point starts the refinement. A window on which the scanned points tie (``_separates``: a window
before the first impact says nothing about a clearance) is not used: the scan moves on to the next
window, and the refinement starts with the first window that tells the points apart. If none
does, the fit says so and is not a success.

Local refinement (``_refine_windows``) is Levenberg–Marquardt on the unconstrained variables
(``_parameter_space``), with the Jacobian of the residuals by forward-mode differentiation through
the solve (``jax.jacfwd``; cost ≈ (1 + 0.5 p) solves for p parameters), at solver settings whose
gradients match converged finite differences (``jaxclear.gradient_solver``).

Uncertainty (``_estimates``): the Gauss–Newton covariance at the optimum in the parameters' units,
C = s² (JᵀJ)⁻¹ + diag(Δθ²), with J = ∂r/∂θ over the windows used, s² = max(1, Σr² / (N − p)) and
Δθ the change of the estimate between the last two windows kept. The factor s² widens the interval
when the model does not reproduce the data to its noise level (model error or underestimated
noise); it never narrows it. Residuals of a model error are correlated in time, which s² cannot
see: the estimate then drifts as the window grows, and Δθ² adds that drift. A parameter the fitted
data do not constrain (a Jacobian of lower rank than the number of parameters) gets an infinite
covariance, and ``status`` says so. Every uncertainty is one standard deviation (1σ).

Verdict (``_verdict``): a fit is a success only when every estimate and standard deviation is
finite, a window told the scanned points apart, and the final loss reaches the noise level
(``noise_level_bound``); otherwise ``IdentificationResult.success`` is ``False`` and ``reason``
says why (``jaxclear fit`` then exits with code 3).
"""

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core._errors import DataError, ModelError
from .._core._progress import Progress, progress_bar
from ..analysis._signals import signal_names, signals
from ..io._measurements import Measurements
from ..model import Mechanism, with_parameters
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, gradient_solver, solver_config
from ._engine import EnsembleSettings, chunk_rows, map_members
from ._parameter_space import FitParameter, ParameterSpace, parse_parameters, scan_values

DEFAULT_HORIZONS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0)
"""Fractions of the record fitted in turn (module doc, "growing windows")."""

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
model follows sharp impacts to within the noise (docs/identification.md, losses 0.7–1.1). A loss
above 2 means residuals 1.4 times the noise on average: the model does not follow the data. Equal
to ``LOSS_GROWTH``, the loss growth at which a window is dropped."""

NOISE_LEVEL_Z = 4.753
"""Standard normal quantile at 1 − 1e-6: the chi-square bound of ``noise_level_bound`` is exceeded
by a fit at the noise level once in a million."""

DEFAULT_SCAN_POINTS = 16
"""Points of the global scan per fitted parameter (one solve each, vectorised in chunks)."""

SCAN_CHUNK = 8
"""Members per vectorised scan solve (bounds memory; one compilation per chunk size)."""

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
        horizons: increasing fractions of the record in (0, 1], the last 1: the growing windows
            (module doc).
        scan_points: global-scan size; ``None``: ``DEFAULT_SCAN_POINTS`` per parameter; 0 (or 1):
            no scan, the refinement starts from the initial values.
        max_iterations: Levenberg–Marquardt iterations per window (≥ 1).
        tolerance: relative decrease of the loss (and relative step) below which a window's
            refinement has converged (≥ 0).

    Raises:
        ModelError: a field out of its range, naming the field and what is allowed.
    """

    horizons: tuple[float, ...] = eqx.field(
        static=True, default=DEFAULT_HORIZONS, converter=_fractions
    )
    scan_points: int | None = eqx.field(static=True, default=None, converter=_whole)
    max_iterations: int = eqx.field(static=True, default=DEFAULT_MAX_ITERATIONS, converter=_whole)
    tolerance: float = eqx.field(static=True, default=DEFAULT_TOLERANCE, converter=_number)

    def __check_init__(self):
        horizons = self.horizons
        if (
            not isinstance(horizons, tuple)
            or not horizons
            or not all(isinstance(h, float) for h in horizons)
            or any(not 0.0 < h <= 1.0 for h in horizons)
            or horizons[-1] != 1.0
        ):
            raise ModelError(
                f"horizons must be increasing fractions of the record in (0, 1] ending with 1, "
                f"e.g. (0.25, 0.5, 1.0); got {horizons!r}."
            )
        if any(b <= a for a, b in zip(horizons, horizons[1:], strict=False)):
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

    def scan_count(self, parameters: int) -> int:
        """Points of the global scan for ``parameters`` fitted parameters (≤ 1: no scan)."""
        return DEFAULT_SCAN_POINTS * parameters if self.scan_points is None else self.scan_points


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
    "between the last two windows"
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
        scan: ``{"values": (K, p), "loss": (K,)}`` of the global scan (empty if none).
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
            "scan": {k: np.asarray(v).tolist() for k, v in self.scan.items()},
            "solver": {
                "method": self.solver.method,
                "rtol": self.solver.rtol,
                "atol": self.solver.atol,
            },
        }


@eqx.filter_jit
def _residuals(mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, mask, adjoint):
    """Normalised residuals (S·N,) of one parameter vector ``u`` (unconstrained), zero outside
    ``mask``; inf where the solve failed."""
    values = params.values(u)
    traj = simulate(
        with_parameters(mechanism, values),
        t1,
        t0=t0,
        ts=jnp.minimum(ts, t1),
        solver=solver,
        extremes=False,
        adjoint=adjoint,
    )
    out = signals(traj, names)
    model = jnp.stack([out[n] for n in names])
    r = (model - data) * inv_sigma[:, None] * mask[None, :]
    return jnp.where(traj.succeeded, r, jnp.inf).ravel()


@eqx.filter_jit
def _residuals_and_jacobian(mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, mask):
    def f(u):
        r = _residuals(
            mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, mask, "forward"
        )
        return r, r

    jac, r = jax.jacfwd(f, has_aux=True)(u)
    return r, jac


def _scan_member(u, mechanism, params, names, solver, t0, t1, ts, data, inv_sigma, mask):
    """Residuals of one scanned point: a member of the ensemble engine's ``map_members``."""
    return _residuals(
        mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, mask, "reverse"
    )


def check_identification(
    mechanism: Mechanism,
    data: Measurements,
    parameters: "Mapping[str, Any] | Sequence[str | FitParameter]",
    t0: float = 0.0,
    t1: float | None = None,
) -> tuple[tuple[FitParameter, ...], float]:
    """Every check ``identify`` makes on its data and parameters before its first solve
    (arguments as there; ``FitSettings`` checks itself when it is made).

    Returns:
        (parameter specs, end of the simulated span in s).

    Raises:
        DataError, ModelError: as ``identify``.
    """
    specs = tuple(parse_parameters(mechanism, parameters))
    valid = signal_names(mechanism)
    for name in data.signals:
        if name not in valid:
            raise DataError(
                f"{data.source}: column {name!r} is not a signal of this mechanism; "
                f"use some of: {', '.join(valid)}."
            )
    t_end = float(np.asarray(data.t)[-1]) if t1 is None else float(t1)
    data.check_span(t0, t_end)
    data.check_enough(len(specs))
    return specs, t_end


@dataclasses.dataclass(frozen=True)
class _Windows:
    """The data as the solves take them, and the growing windows over them.

    Attributes:
        static: (mechanism, ``ParameterSpace``, signal names, solver): the compiled part.
        t0: start of the simulation, s; t_start: the same as an array (not a Python float: one
            compilation for all windows). ts: data times (N,). data: (S, N) measured signals. inv_sigma: (S,).
        noise: σ per signal.
        ends: end of each window, s. masks: (N,) 1 inside each window. counts: residuals in each.
    """

    static: tuple
    t0: float
    t_start: jax.Array
    ts: jax.Array
    data: jax.Array
    inv_sigma: jax.Array
    noise: dict[str, float]
    ends: list[float]
    masks: list[jax.Array]
    counts: list[float]

    @classmethod
    def of(cls, mechanism, data, specs, config, t0, t_end, horizons) -> "_Windows":
        names = tuple(data.signals)
        t_data = np.asarray(data.t, dtype=float)
        noise = {n: float(data.noise[n]) for n in names}
        span = t_end - t0
        ends = [t0 + h * span for h in horizons]
        masks = [jnp.asarray((t_data <= e + 1e-12 * span).astype(float)) for e in ends]
        return cls(
            static=(mechanism, ParameterSpace.of(specs), names, config),
            t0=t0,
            t_start=jnp.asarray(t0, dtype=float),
            ts=jnp.asarray(t_data),
            data=jnp.asarray(np.stack([np.asarray(data.signals[n], dtype=float) for n in names])),
            inv_sigma=jnp.asarray([1.0 / noise[n] for n in names]),
            noise=noise,
            ends=ends,
            masks=masks,
            counts=[float(np.sum(np.asarray(m))) * len(names) for m in masks],
        )

    @property
    def names(self) -> tuple[str, ...]:
        """The fitted signals, in the order of the residuals' rows."""
        return self.static[2]

    def args(self, k: int) -> tuple:
        """The arguments after ``u`` of ``_residuals`` over window ``k``."""
        return (*self.static, *self._window(k))

    def residuals_and_jacobian(self, u, k: int):
        """Residuals (S·N,) and their Jacobian (S·N, p) in u over window ``k``."""
        mechanism, params, names, solver = self.static
        t_start, t1, ts, data, inv_sigma, mask = self._window(k)
        return _residuals_and_jacobian(
            mechanism, params, names, solver, jnp.asarray(u), t_start, t1, ts, data, inv_sigma, mask
        )

    def _window(self, k: int) -> tuple:
        return (
            self.t_start,
            jnp.asarray(self.ends[k]),
            self.ts,
            self.data,
            self.inv_sigma,
            self.masks[k],
        )


def _separates(losses: np.ndarray) -> bool:
    """Whether a window tells the scanned points apart: fewer than ``TIED_SHARE`` of the other
    points whose solve succeeded lie within ``INFORMATIVE_SPREAD`` of the lowest loss."""
    finite = np.sort(losses[np.isfinite(losses)])
    if finite.size < 2:
        return False
    ties = int(np.sum(finite[1:] - finite[0] <= INFORMATIVE_SPREAD))
    return ties < TIED_SHARE * (finite.size - 1)


@dataclasses.dataclass(frozen=True)
class _Scan:
    """What the global scan found.

    Attributes:
        u: the start of the refinement (unconstrained). first: the window it starts with.
        separated: a window told the scanned points apart (else ``u`` is the initial point and the
            refinement is skipped). table: ``{"values": (K, p), "loss": (K,)}`` (empty: no scan).
    """

    u: np.ndarray
    first: int
    separated: bool
    table: dict[str, np.ndarray]


def _global_scan(windows: _Windows, specs, count: int, bar: Progress, record) -> _Scan:
    """Scan ``count`` points over the bounds on the first window that tells them apart.

    Each window tried costs one progress step per vectorised chunk; the windows after the one
    used are counted as done unscanned.

    Raises:
        ModelError: every scanned point failed to simulate.
    """
    u = np.array([q.to_unconstrained(q.initial) for q in specs], dtype=float)
    if count <= 1:
        return _Scan(u, 0, True, {})
    points = scan_values(specs, count)
    us = np.stack(
        [[float(q.to_unconstrained(v)) for q, v in zip(specs, row, strict=True)] for row in points]
    )
    settings = EnsembleSettings(chunk_size=SCAN_CHUNK)
    first, losses, separated = 0, np.full(len(us), np.inf), False
    for first in range(len(windows.ends)):
        r = map_members(
            _scan_member,
            windows.args(first),
            us,
            settings=settings,
            on_chunk=lambda start, stop: bar.update(1),
        )
        losses = np.sum(r**2, axis=1) / windows.counts[first]
        separated = _separates(losses)
        if separated:
            break
    bar.update(_scan_chunks(count) * (len(windows.ends) - 1 - first))
    losses = np.where(np.isfinite(losses), losses, np.inf)
    best = int(np.argmin(losses))
    if not np.isfinite(losses[best]):
        raise ModelError(
            "every point of the global scan failed to simulate; check the bounds and the solver "
            "(a failed solve reports its time and state when run alone with jaxclear.simulate)."
        )
    table = {"values": points, "loss": losses}
    if separated:
        u, best_loss = us[best], float(losses[best])
    else:  # say so, rather than pick one of the tied points: the initial point stays
        best_loss = float(losses[0])
    record(
        {
            "stage": "scan",
            "horizon": windows.ends[first],
            "iteration": 0,
            "loss": best_loss,
            "values": _values(specs, u),
        }
    )
    return _Scan(u, first, separated, table)


def _scan_chunks(count: int) -> int:
    """Vectorised solves of a scan of ``count`` points over one window (progress steps)."""
    return (
        math.ceil(count / chunk_rows(EnsembleSettings(chunk_size=SCAN_CHUNK))) if count > 1 else 0
    )


@dataclasses.dataclass(frozen=True)
class _Refinement:
    """What the Levenberg–Marquardt stage kept.

    Attributes:
        u: the estimate (unconstrained). used: the longest window kept. kept: the estimate after
        each kept window. iterations: over all windows. converged, status: of the last window kept.
    """

    u: np.ndarray
    used: int
    kept: list[np.ndarray]
    iterations: int
    converged: bool
    status: str


def _refine_windows(
    windows: _Windows, specs, u, first: int, settings: FitSettings, bar: Progress, record
) -> _Refinement:
    """Levenberg–Marquardt over the growing windows from ``first`` on, while the model follows the
    record (``LOSS_GROWTH``).

    Each window is ``max_iterations`` + 1 progress steps (the start and each iteration); what a
    window does not use, and the windows skipped or not reached, are counted as done.
    """
    budget = settings.max_iterations + 1
    iterations, converged, status = 0, False, ""
    kept: list[np.ndarray] = []  # the estimate (u) after each kept window
    best_loss = math.inf
    used = first
    for k, (end, n) in enumerate(zip(windows.ends, windows.counts, strict=True)):
        if k < first:
            bar.update(budget)
            continue  # before the first window that carries information on the parameters
        stage = f"window {k + 1}/{len(windows.ends)}"
        steps = []

        def report(it, loss, u, stage=stage, end=end, steps=steps):
            record(
                {
                    "stage": stage,
                    "horizon": end,
                    "iteration": it,
                    "loss": loss,
                    "values": _values(specs, u),
                }
            )
            steps.append(it)
            bar.update(1)

        u_new, its, conv, stat, loss = _levenberg_marquardt(
            lambda u, k=k: windows.residuals_and_jacobian(u, k),
            u,
            n,
            settings.max_iterations,
            settings.tolerance,
            report,
        )
        iterations += its
        bar.update(budget - len(steps))
        if k > first and not loss <= LOSS_GROWTH * best_loss:
            status = (
                f"{stat}; the model does not follow the record beyond {windows.ends[used]:.6g} s "
                f"(loss {loss:.3g} over {end:.6g} s against {best_loss:.3g}): estimate from the "
                f"first {windows.ends[used] - windows.t0:.6g} s"
            )
            bar.update(budget * (len(windows.ends) - 1 - k))
            break
        u, converged, status, used = u_new, conv, stat, k
        kept.append(np.asarray(u_new, dtype=float))
        best_loss = min(best_loss, loss)
    return _Refinement(u, used, kept, iterations, converged, status)


def _estimates(
    windows: _Windows, specs, fit: _Refinement
) -> tuple[dict[str, Estimate], np.ndarray, float, float, str]:
    """The estimates with their standard deviations over the windows used (module doc,
    "Uncertainty").

    Returns:
        (``{name: Estimate}``, covariance (p, p) in the parameters' units, loss over the windows
        used, s², a note for the status: ``""`` or why the covariance is infinite).
    """
    p = len(specs)
    u, used = fit.u, fit.used
    r, jac_u = (np.asarray(a) for a in windows.residuals_and_jacobian(u, used))
    dtheta = np.array(
        [float(jax.grad(q.from_unconstrained)(jnp.asarray(u[i]))) for i, q in enumerate(specs)]
    )
    jac = jac_u / dtheta[None, :]
    dof = max(windows.counts[used] - p, 1.0)
    scale = max(1.0, float(np.sum(r**2)) / dof)
    information = jac.T @ jac
    note = ""
    if np.linalg.matrix_rank(jac) < p:  # a parameter (or combination) the data do not constrain
        covariance = np.full((p, p), np.inf)
        note = "; not identifiable from the data fitted: the covariance is infinite"
    else:
        covariance = scale * np.linalg.inv(information)
    values = _values(specs, u)
    # window-to-window change of the estimate: model or numerical error that the residuals'
    # covariance cannot see (correlated residuals) shows as a drift of the estimate with the span
    previous = _values(specs, fit.kept[-2]) if len(fit.kept) >= 2 else values
    drift = np.array([values[q.name] - previous[q.name] for q in specs])
    covariance = covariance + np.diag(drift**2)
    std = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    estimates = {
        q.name: Estimate(values[q.name], float(std[i]), q.initial, q.lower, q.upper, q.unit)
        for i, q in enumerate(specs)
    }
    loss = float(np.sum(r**2)) / windows.counts[used]
    return estimates, covariance, loss, scale, note


def _whole_record(windows: _Windows, data: Measurements, u) -> tuple[float, dict[str, np.ndarray]]:
    """The model at ``u`` over the whole record, also past the windows used (for plots and
    fit.csv): (loss over the whole record, ``{signal: fitted (N,)}``)."""
    last = len(windows.ends) - 1
    r_all = np.asarray(windows.residuals_and_jacobian(u, last)[0])
    fitted_r = r_all.reshape(len(windows.names), -1)
    fitted = {
        n: np.asarray(data.signals[n], dtype=float) + fitted_r[i] * windows.noise[n]
        for i, n in enumerate(windows.names)
    }
    return float(np.sum(r_all**2)) / windows.counts[last], fitted


NOT_A_FIT = "not a fit"
"""How ``status`` starts when the fit is not a success (then ``reason`` follows)."""

TRY = (
    "try other bounds or initial values, more scan points, or a record with more impacts, and "
    "check the model (contact and friction laws, start state) and the noise levels"
)
"""What ``reason`` suggests when a fit is not a success."""


def _verdict(
    estimates: dict[str, Estimate],
    loss: float,
    count: float,
    separated: bool,
    fitted_span: float,
) -> tuple[bool, str]:
    """Whether the fit is a success (module doc, "Verdict"), and if not, why.

    Args:
        estimates: the estimates with their standard deviations.
        loss: the loss over the windows used. count: residuals in them.
        separated: a window told the scanned points apart (or there was no scan).
        fitted_span: length of the windows used, s.

    Returns:
        (success, reason): reason is ``""`` on success, else one line saying why and what to try.
    """
    problems = []
    if not separated:
        problems.append(
            "no window of the record tells the global scan's points apart (their losses tie): the "
            "data do not constrain the parameters within their bounds, and the estimates are the "
            "initial values"
        )
    else:
        loose = [
            n for n, e in estimates.items() if not (math.isfinite(e.value) and math.isfinite(e.std))
        ]
        if loose:
            problems.append(
                f"{', '.join(loose)}: no finite standard deviation (the first {fitted_span:.6g} s "
                f"of the record do not constrain {'it' if len(loose) == 1 else 'them'})"
            )
    bound = noise_level_bound(count, len(estimates))
    if not loss <= bound:
        problems.append(
            f"the loss {loss:.4g} over the first {fitted_span:.6g} s is above the noise level "
            f"(1 = noise level; a fit reaches at most {bound:.3g})"
        )
    if not problems:
        return True, ""
    return False, f"{'; '.join(problems)}; {TRY}"


def identify(
    mechanism: Mechanism,
    data: Measurements,
    parameters: "Mapping[str, Any] | Sequence[str | FitParameter]",
    *,
    t0: float = 0.0,
    t1: float | None = None,
    solver: "str | SolverConfig | None" = None,
    settings: FitSettings = FitSettings(),
    progress: bool = False,
    callback: Callable[[dict[str, Any]], None] | None = None,
) -> IdentificationResult:
    """Fit named parameters of ``mechanism`` to measured signals (module doc for the method).

    Args:
        mechanism: the model with every parameter not fitted at its known value, and the
            operating point (speed, gravity, start state) of the measurement.
        data: ``Measurements`` (``Measurements.from_csv``): times, signals named as the columns
            ``jaxclear run`` writes, noise levels (given or estimated).
        parameters: names (``"B.clearance"``), or ``{name: initial}``, ``{name: (initial, lower,
            upper)}``, ``{name: {"initial": ..., "lower": ..., "upper": ...}}`` or
            ``FitParameter``s; missing values from the mechanism and ``parse_parameters``.
        t0: time at which the simulation starts from the mechanism's assembled state, s (≤ the
            first data time).
        t1: end of the simulated span, s (default the last data time); data after it are an error.
        solver: ``SolverConfig`` or name; default ``jaxclear.gradient_solver(mechanism)``
            (settings whose derivatives match converged finite differences).
        settings: ``FitSettings``: the growing windows (``horizons``), the global scan
            (``scan_points``) and the optimiser (``max_iterations``, ``tolerance``).
        progress: print a progress bar (tqdm) over the fit's evaluations: per window, the scan's
            vectorised solves and the Levenberg–Marquardt iterations.
        callback: called with each ``history`` entry as it is made.

    Returns:
        An ``IdentificationResult``; ``success`` says whether it is a fit to the noise level, and
        ``reason`` why not.

    Raises:
        DataError: data outside the simulated span, fewer data points than parameters, a signal
            this mechanism does not have.
        ModelError: an unknown parameter name or bad bounds; ``settings`` not a ``FitSettings``;
            every point of the global scan failed to simulate.
    """
    started = time.perf_counter()
    if not isinstance(settings, FitSettings):
        raise ModelError(
            f"settings must be a FitSettings, e.g. jaxclear.FitSettings(horizons=(0.25, 0.5, 1.0), "
            f"scan_points=16, max_iterations=20, tolerance=1e-6); got {type(settings).__name__}."
        )
    specs, t_end = check_identification(mechanism, data, parameters, t0, t1)
    config = gradient_solver(mechanism) if solver is None else solver_config(solver, mechanism)
    windows = _Windows.of(mechanism, data, specs, config, t0, t_end, settings.horizons)

    history: list[dict[str, Any]] = []

    def record(entry):
        history.append(entry)
        if callback is not None:
            callback(entry)

    count = settings.scan_count(len(specs))
    per_window = _scan_chunks(count) + settings.max_iterations + 1  # scan chunks, LM evaluations
    with progress_bar(progress, len(windows.ends) * per_window, "fit") as bar:
        scan = _global_scan(windows, specs, count, bar, record)
        if scan.separated:
            fit = _refine_windows(windows, specs, scan.u, scan.first, settings, bar, record)
        else:
            bar.update(len(windows.ends) * (settings.max_iterations + 1))
            last = len(windows.ends) - 1
            fit = _Refinement(scan.u, last, [], 0, False, "not refined: the scanned points tie")

    estimates, covariance, loss, scale, note = _estimates(windows, specs, fit)
    loss_whole_record, fitted = _whole_record(windows, data, fit.u)
    fitted_span = windows.ends[fit.used] - windows.t0
    success, reason = _verdict(
        estimates, loss, windows.counts[fit.used], scan.separated, fitted_span
    )
    status = fit.status + note
    return IdentificationResult(
        parameters=estimates,
        covariance=covariance,
        loss=loss,
        loss_whole_record=loss_whole_record,
        window_end=windows.ends[fit.used],
        chi2_scale=scale,
        noise=windows.noise,
        noise_estimated={n: bool(data.noise_estimated.get(n, False)) for n in windows.names},
        history=history,
        iterations=fit.iterations,
        converged=fit.converged,
        status=status if success else f"{NOT_A_FIT}: {reason}; {status}",
        success=success,
        reason=reason,
        time=time.perf_counter() - started,
        scan=scan.table,
        t=np.asarray(data.t, dtype=float),
        measured={n: np.asarray(data.signals[n], dtype=float) for n in windows.names},
        fitted=fitted,
        solver=config,
    )


def _values(specs: Sequence[FitParameter], u) -> dict[str, float]:
    return {q.name: float(q.from_unconstrained(jnp.asarray(u[i]))) for i, q in enumerate(specs)}


def _levenberg_marquardt(evaluate, u, count, max_iterations, tolerance, report):
    """Minimise Σr² over u with damped Gauss–Newton steps (Marquardt's diagonal scaling).

    Returns (u, iterations, converged, status, loss)."""
    r, jac = (np.asarray(a) for a in evaluate(u))
    loss = float(np.sum(r**2)) / count
    if not np.isfinite(loss):
        return u, 0, False, "the solve failed at the starting point of this window", loss
    report(0, loss, u)
    damping = 1e-3
    for it in range(1, max_iterations + 1):
        g = jac.T @ r
        h = jac.T @ jac
        diag = np.maximum(np.diag(h), 1e-12 * max(float(np.max(np.diag(h))), 1e-300))
        while True:
            try:
                step = np.linalg.solve(h + damping * np.diag(diag), -g)
            except np.linalg.LinAlgError:
                step = np.zeros_like(u)
            u_new = u + step
            r_new, jac_new = (np.asarray(a) for a in evaluate(u_new))
            loss_new = float(np.sum(r_new**2)) / count
            if np.isfinite(loss_new) and loss_new <= loss:
                break
            damping *= 4.0
            if damping > 1e10:
                return u, it, True, "converged: no step lowers the loss further", loss
        decrease = (loss - loss_new) / max(loss, 1e-300)
        small_step = float(np.linalg.norm(step)) <= tolerance * (
            float(np.linalg.norm(u)) + tolerance
        )
        u, r, jac, loss = u_new, r_new, jac_new, loss_new
        damping = max(damping / 3.0, 1e-9)
        report(it, loss, u)
        if decrease <= tolerance or small_step:
            return (
                u,
                it,
                True,
                f"converged: relative decrease {decrease:.1e} after {it} iterations",
                loss,
            )
    return (
        u,
        max_iterations,
        False,
        f"stopped after {max_iterations} iterations (max_iterations)",
        loss,
    )
