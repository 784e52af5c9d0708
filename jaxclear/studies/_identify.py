"""Identification: fit mechanism parameters (clearances, contact, friction, masses) to measured signals.

Weighted least squares. With data y_s(t_i) for signals s (``slider_x``, ``slider_a``,
``crank_torque``, a joint's ``B_ecc_x``, ... the columns ``jaxclear run`` writes) and noise levels
σ_s, the residuals are r_si(θ) = (ŷ_s(t_i; θ) − y_s(t_i)) / σ_s, with ŷ from one ``simulate`` from
the data's start state (journals as the mechanism places them, centred by default), and the loss
is the mean of r² (≈ 1 at a fit to the noise level).

Why growing windows: the impact sequence makes the response after many impacts a rough function
of the parameters (docs/model.md §5b); a loss over the whole record has many local minima. The fit
therefore goes through ``horizons``: first over the start of the record, where the loss is smooth
around the truth, then over longer and longer windows, each started from the previous estimate
(continuation). Where the response is chaotic (the benchmark slider–crank at 200 rpm with gravity:
the pin bounces round the whole clearance, and a 0.1 % change of clearance moves the slider by
30 µm after 90 ms), no model follows a long record to its noise level; a window whose fitted loss
grows past ``LOSS_GROWTH`` times that of the shorter ones is not used, and the result says up to
which time the data were fitted (``window_end``). Before that a global scan evaluates the first window's loss at points spread over
the bounds (one vectorised ``simulate_batch``-style solve per chunk) and starts from the best.

Local refinement is Levenberg–Marquardt on the unconstrained variables (``_parameter_space``), with
the Jacobian of the residuals by forward-mode differentiation through the solve
(``jax.jacfwd``; cost ≈ (1 + 0.5 p) solves for p parameters), at solver settings whose gradients
match converged finite differences (``jaxclear.gradient_solver``).

Uncertainty: the Gauss–Newton covariance at the optimum in the parameters' units,
C = s² (JᵀJ)⁻¹ + diag(Δθ²), with J = ∂r/∂θ over the windows used, s² = max(1, Σr² / (N − p)) and
Δθ the change of the estimate between the last two windows kept. The factor s² widens the interval
when the model does not reproduce the data to its noise level (model error or underestimated
noise); it never narrows it. Residuals of a model error are correlated in time, which s² cannot
see: the estimate then drifts as the window grows, and Δθ² adds that drift. A parameter the fitted
data do not constrain (a Jacobian of lower rank than the number of parameters) gets an infinite
covariance, and ``status`` says so.
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
from .._core._progress import progress_bar
from ..analysis._signals import signal_names, signals
from ..io._measurements import Measurements
from ..model import Mechanism, with_parameters
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, gradient_solver, solver_config
from ._engine import EnsembleSettings, map_members
from ._parameter_space import FitParameter, ParameterSpace, parse_parameters, scan_values

DEFAULT_HORIZONS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0)
"""Fractions of the record fitted in turn (module doc, "growing windows")."""

INFORMATIVE_SPREAD = 1.0
"""The scan moves on to the next window while its losses differ by less than this over the scanned
points (a window before the first impact says nothing about a clearance): the refinement starts
with the first window whose loss tells the points apart."""

LOSS_GROWTH = 2.0
"""A window whose fitted loss exceeds this multiple of the best loss of the shorter windows is
beyond the horizon the model can follow (chaotic impact sequence, model error): the fit keeps
the estimate of the shorter windows and says so in ``status``."""

DEFAULT_SCAN_POINTS = 16
"""Points of the global scan per fitted parameter (one solve each, vectorised in chunks)."""

SCAN_CHUNK = 8
"""Members per vectorised scan solve (bounds memory; one compilation per chunk size)."""


@dataclasses.dataclass(frozen=True)
class Estimate:
    """One fitted parameter.

    Attributes:
        value: the estimate. std: its standard deviation from the Gauss–Newton covariance (module
            doc). initial, lower, upper: the start and bounds of the fit. unit: SI unit.
    """

    value: float
    std: float
    initial: float
    lower: float
    upper: float
    unit: str

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


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
        converged: the last window's refinement met its tolerance. status: one line.
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
            "parameters": {n: e.as_dict() for n, e in self.parameters.items()},
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
    horizons: Sequence[float] = DEFAULT_HORIZONS,
) -> tuple[tuple[FitParameter, ...], float, tuple[float, ...]]:
    """Every check ``identify`` makes before its first solve (arguments as there).

    Returns:
        (parameter specs, end of the simulated span in s, horizons).

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
    horizons = tuple(float(h) for h in horizons)
    if not horizons or any(not 0.0 < h <= 1.0 for h in horizons) or horizons[-1] != 1.0:
        raise ModelError(
            f"horizons must be increasing fractions in (0, 1] ending with 1, got {horizons}."
        )
    if any(b <= a for a, b in zip(horizons, horizons[1:], strict=False)):
        raise ModelError(f"horizons must be increasing, got {horizons}.")
    return specs, t_end, horizons


def identify(
    mechanism: Mechanism,
    data: Measurements,
    parameters: "Mapping[str, Any] | Sequence[str | FitParameter]",
    *,
    t0: float = 0.0,
    t1: float | None = None,
    solver: "str | SolverConfig | None" = None,
    horizons: Sequence[float] = DEFAULT_HORIZONS,
    scan_points: int | None = None,
    max_iterations: int = 20,
    tolerance: float = 1e-6,
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
        horizons: increasing fractions of the record in (0, 1], the last 1: the growing windows.
        scan_points: global-scan size (default 16 per parameter; 0: start from the initial values).
        max_iterations: Levenberg–Marquardt iterations per window.
        tolerance: relative decrease of the loss (and relative step) below which a window's
            refinement has converged.
        progress: print a progress bar (tqdm) over the fit's evaluations.
        callback: called with each ``history`` entry as it is made.

    Returns:
        An ``IdentificationResult``.

    Raises:
        DataError: data outside the simulated span, fewer data points than parameters, a signal
            this mechanism does not have.
        ModelError: an unknown parameter name or bad bounds.
    """
    started = time.perf_counter()
    specs, t_end, horizons = check_identification(mechanism, data, parameters, t0, t1, horizons)
    names = tuple(data.signals)
    t_data = np.asarray(data.t, dtype=float)
    config = gradient_solver(mechanism) if solver is None else solver_config(solver, mechanism)
    p = len(specs)
    count = DEFAULT_SCAN_POINTS * p if scan_points is None else int(scan_points)

    noise = {n: float(data.noise[n]) for n in names}
    ts = jnp.asarray(t_data)
    y = jnp.asarray(np.stack([np.asarray(data.signals[n], dtype=float) for n in names]))
    inv_sigma = jnp.asarray([1.0 / noise[n] for n in names])
    span = t_end - t0
    ends = [t0 + h * span for h in horizons]
    t_start = jnp.asarray(
        t0, dtype=float
    )  # arrays, not Python floats: one compilation for all windows
    masks = [jnp.asarray((t_data <= e + 1e-12 * span).astype(float)) for e in ends]
    counts = [float(np.sum(np.asarray(m))) * len(names) for m in masks]
    static = (mechanism, ParameterSpace.of(specs), names, config)

    history: list[dict[str, Any]] = []

    def record(entry):
        history.append(entry)
        if callback is not None:
            callback(entry)

    total = (math.ceil(count / SCAN_CHUNK) if count > 1 else 0) + len(ends) * max_iterations
    bar = progress_bar(progress, total, "fit")

    # 1. global scan over the first window that tells the scanned points apart
    u = np.array([q.to_unconstrained(q.initial) for q in specs], dtype=float)
    scan = {}
    first = 0  # the window the refinement starts with
    if count > 1:
        points = scan_values(specs, count)
        us = np.stack(
            [
                [float(q.to_unconstrained(v)) for q, v in zip(specs, row, strict=True)]
                for row in points
            ]
        )
        losses = np.full(len(us), np.inf)
        for first in range(len(ends)):
            losses = np.full(len(us), np.inf)
            r = map_members(
                _scan_member,
                (
                    *static,
                    t_start,
                    jnp.asarray(ends[first]),
                    ts,
                    y,
                    inv_sigma,
                    masks[first],
                ),
                us,
                settings=EnsembleSettings(chunk_size=SCAN_CHUNK),
                on_chunk=lambda start, stop: bar.update(1),
            )
            losses = np.sum(r**2, axis=1) / counts[first]
            finite = losses[np.isfinite(losses)]
            if finite.size and np.max(finite) - np.min(finite) > INFORMATIVE_SPREAD:
                break
        losses = np.where(np.isfinite(losses), losses, np.inf)
        best = int(np.argmin(losses))
        if not np.isfinite(losses[best]):
            raise ModelError(
                "every point of the global scan failed to simulate; check the bounds and the solver "
                "(a failed solve reports its time and state when run alone with jaxclear.simulate)."
            )
        u = us[best]
        scan = {"values": points, "loss": losses}
        record(
            {
                "stage": "scan",
                "horizon": ends[first],
                "iteration": 0,
                "loss": float(losses[best]),
                "values": _values(specs, u),
            }
        )

    # 2. Levenberg–Marquardt over growing windows, while the model follows the record
    iterations, converged, status = 0, False, ""
    kept: list[np.ndarray] = []  # the estimate (u) after each kept window
    best_loss = math.inf
    used = first
    for k, (end, mask, n) in enumerate(zip(ends, masks, counts, strict=True)):
        if k < first:
            bar.update(max_iterations)
            continue  # before the first window that carries information on the parameters
        stage = f"window {k + 1}/{len(ends)}"
        u_new, its, conv, stat, loss = _levenberg_marquardt(
            lambda u, end=end, mask=mask: _residuals_and_jacobian(
                *static, jnp.asarray(u), t_start, jnp.asarray(end), ts, y, inv_sigma, mask
            ),
            u,
            n,
            max_iterations,
            tolerance,
            lambda it, loss, u, stage=stage, end=end: (
                record(
                    {
                        "stage": stage,
                        "horizon": end,
                        "iteration": it,
                        "loss": loss,
                        "values": _values(specs, u),
                    }
                ),
                bar.update(1),
            ),
        )
        iterations += its
        bar.update(max_iterations - its)
        if k > first and not loss <= LOSS_GROWTH * best_loss:
            status = (
                f"{stat}; the model does not follow the record beyond {ends[used]:.6g} s (loss "
                f"{loss:.3g} over {end:.6g} s against {best_loss:.3g}): estimate from the first "
                f"{ends[used] - t0:.6g} s"
            )
            break
        u, converged, status, used = u_new, conv, stat, k
        kept.append(np.asarray(u_new, dtype=float))
        best_loss = min(best_loss, loss)
    bar.close()

    # 3. covariance over the windows used, in the parameters' units
    r, jac_u = (
        np.asarray(a)
        for a in _residuals_and_jacobian(
            *static, jnp.asarray(u), t_start, jnp.asarray(ends[used]), ts, y, inv_sigma, masks[used]
        )
    )
    dtheta = np.array(
        [float(jax.grad(q.from_unconstrained)(jnp.asarray(u[i]))) for i, q in enumerate(specs)]
    )
    jac = jac_u / dtheta[None, :]
    dof = max(counts[used] - p, 1.0)
    scale = max(1.0, float(np.sum(r**2)) / dof)
    information = jac.T @ jac
    if np.linalg.matrix_rank(jac) < p:  # a parameter (or combination) the data do not constrain
        covariance = np.full((p, p), np.inf)
        status += "; not identifiable from the data fitted: the covariance is infinite"
    else:
        covariance = scale * np.linalg.inv(information)
    values = _values(specs, u)
    # window-to-window change of the estimate: model or numerical error that the residuals'
    # covariance cannot see (correlated residuals) shows as a drift of the estimate with the span
    previous = _values(specs, kept[-2]) if len(kept) >= 2 else values
    drift = np.array([values[q.name] - previous[q.name] for q in specs])
    covariance = covariance + np.diag(drift**2)
    std = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    estimates = {
        q.name: Estimate(values[q.name], float(std[i]), q.initial, q.lower, q.upper, q.unit)
        for i, q in enumerate(specs)
    }
    # the model over the whole record (for plots and fit.csv), also past the windows used
    r_all = np.asarray(
        _residuals_and_jacobian(
            *static, jnp.asarray(u), t_start, jnp.asarray(ends[-1]), ts, y, inv_sigma, masks[-1]
        )[0]
    )
    fitted_r = r_all.reshape(len(names), -1)
    fitted = {
        n: np.asarray(data.signals[n], dtype=float) + fitted_r[i] * noise[n]
        for i, n in enumerate(names)
    }
    return IdentificationResult(
        parameters=estimates,
        covariance=covariance,
        loss=float(np.sum(r**2)) / counts[used],
        loss_whole_record=float(np.sum(r_all**2)) / counts[-1],
        window_end=ends[used],
        chi2_scale=scale,
        noise=noise,
        noise_estimated={n: bool(data.noise_estimated.get(n, False)) for n in names},
        history=history,
        iterations=iterations,
        converged=converged,
        status=status,
        time=time.perf_counter() - started,
        scan=scan,
        t=t_data,
        measured={n: np.asarray(data.signals[n], dtype=float) for n in names},
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
