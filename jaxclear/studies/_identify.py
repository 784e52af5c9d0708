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

Windows (``_automatic_windows``, when ``FitSettings.horizons`` is None): the first ends after the
first contacts of a first simulation at the initial values and of the data
(``_global_search.first_window_end``), the next ones are twice as long each.

Global scan (``_global_scan``, the method in ``_global_search``): before the refinement, a design
over the bounds is scanned with a capped loss on the first window (chunks of ``SCAN_REFILL_CHUNK``
points on refilled lanes, ``_scan_chunk``; or with ``FitSettings.scan_engine = "lockstep"`` one
vmapped solve per chunk of ``SCAN_CHUNK``). A window on which the scanned points tie
(``_separates``: before the first contact a clearance changes nothing) is not used: the scan moves
on to the next window, and if none tells the points apart the fit says so and is not a success.
The design is then refined until its spacing resolves the basin width measured on its own
responses, and the best points of distinct basins start the refinement.

Local refinement (``_refine_windows``) is Levenberg–Marquardt on the unconstrained variables
(``_parameter_space``), from each start on the first window and then from the best one over the
longer windows, with the Jacobian of the residuals by forward-mode differentiation through the
solve (``jax.jacfwd``; cost ≈ (1 + 0.5 p) solves for p parameters): from the error-controlled
sensitivities (``jacobian_adjoint``), at Lawson–Tsit5 rtol 1e-8 by default with Coulomb-type
friction (``default_fit_solver``), or diffrax's discrete derivatives at ``gradient_solver``
settings, where they match converged finite differences (the default otherwise).

Uncertainty (``_estimates``): the Gauss–Newton covariance at the optimum in the parameters' units,
C = s² (JᵀJ)⁻¹ + diag(Δθ² + ρ²), with J = ∂r/∂θ over the windows used, s² = max(1, Σr² / (N − p)),
Δθ the change of the estimate between the last two windows kept and ρ the model's resolution
(``_resolution``: a clearance's contact smoothing width). The factor s² widens the interval
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
from .._core._executable_cache import stored_jit
from .._core._progress import Progress, progress_bar
from ..analysis._modes import contact_joints, corner_pair_channels
from ..analysis._signals import signal_names, signals
from ..io._measurements import Measurements
from ..model import Mechanism, get_parameter, with_parameters
from ..solve._lanes import DEFAULT_LANES, _Program, batched_trajectories, members_solution
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, gradient_solver, recommended_solver, solver_config
from ._engine import EnsembleSettings, chunk_rows, map_members
from ._fit_settings import (
    INFORMATIVE_SPREAD,
    LOSS_GROWTH,
    SCAN_ATOL_FACTOR,
    SCAN_CHUNK,
    SCAN_REFILL_CHUNK,
    TIED_SHARE,
    Estimate,
    FitSettings,
    IdentificationResult,
    noise_level_bound,
)
from ._global_search import (
    DEPARTURE,
    FIRST_CONTACTS,
    Design,
    first_window_end,
    needs_refinement,
    resolve_basins,
    scan_loss,
    starting_points,
    window_ladder,
)
from ._parameter_space import FitParameter, ParameterSpace, parse_parameters


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
    return _masked_residuals(traj, names, data, inv_sigma, mask)


def _masked_residuals(traj, names, data, inv_sigma, mask):
    """(S·N,) normalised residuals of a trajectory's signals ``names`` against ``data`` (S, N),
    zero outside ``mask``; inf where the solve failed (one point; the scan vmaps it)."""
    out = signals(traj, names)
    model = jnp.stack([out[n] for n in names])
    r = (model - data) * inv_sigma[:, None] * mask[None, :]
    return jnp.where(traj.succeeded, r, jnp.inf).ravel()


def default_fit_solver(mechanism) -> SolverConfig:
    """``identify``'s default settings. With clearance joints whose solver would be Tsit5
    (Coulomb-type friction): Lawson–Tsit5 at rtol 1e-8, atol 1e-11, the default settings of
    ``simulate``'s sensitivity solve, which gives the fit's Jacobian (``jacobian_adjoint``). On
    the three fits of docs/identification.md this gave the estimates of ``gradient_solver``
    settings (Lawson–Tsit5 at 1e-12 with diffrax's discrete derivatives) to 2e-8 in 16–38 % less
    time. Otherwise (LuGre, ideal joints; not measured) ``gradient_solver``."""
    if mechanism.clearance_joints and recommended_solver(mechanism).method == "tsit5":
        return SolverConfig(method="lawson-tsit5", rtol=1e-8, atol=1e-11)
    return gradient_solver(mechanism)


def jacobian_adjoint(mechanism, solver: SolverConfig) -> str:
    """How a fit differentiates its residuals: diffrax's discrete forward mode at exactly
    ``gradient_solver`` settings (the default of fits with LuGre friction), where it was
    measured right (docs/differentiation.md, "Settings for gradients"); the error-controlled
    forward sensitivities at any other settings (``default_fit_solver``'s with Coulomb-type
    friction, or a user's), where the discrete derivatives are not controlled."""
    return "discrete-forward" if solver == gradient_solver(mechanism) else "forward"


@stored_jit
def _residuals_and_jacobian(mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, mask):
    def f(u):
        r = _residuals(
            mechanism,
            params,
            names,
            solver,
            u,
            t0,
            t1,
            ts,
            data,
            inv_sigma,
            mask,
            jacobian_adjoint(mechanism, solver),
        )
        return r, r

    jac, r = jax.jacfwd(f, has_aux=True)(u)
    return r, jac


def _scan_member(u, mechanism, params, names, solver, t0, t1, ts, data, inv_sigma, mask):
    """Residuals of one scanned point: a member of the ensemble engine's ``map_members``."""
    return _residuals(
        mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, mask, "discrete-reverse"
    )


@stored_jit
def _scan_solve(
    us, count, ends, starts, mechanism, params, names, solver, t0, ts, data, inv_sigma, mask, lanes
):
    """Residuals (C, S·N) of the first ``count`` rows of ``us`` (C, p), solved on ``lanes``
    refilled lanes (``jaxclear.solve.solve_members``) as ``_scan_member`` solves one; rows past
    ``count`` pad the chunk and are not solved (their residuals are meaningless). ``ends``,
    ``starts``: (C,) each member's end time and (unused) statistics start, s."""
    values = jax.vmap(params.values)(us)
    keys = tuple(values)
    rows = jnp.stack([jnp.asarray(values[n], dtype=float) for n in keys], axis=1)
    program = _Program(mechanism=mechanism, names=keys, config=solver, track=False, max_events=0)
    solved = members_solution(program, rows, t0, ends, starts, None, lanes, ts, count)
    return jax.vmap(lambda traj: _masked_residuals(traj, names, data, inv_sigma, mask))(
        batched_trajectories(solved)
    )


def _scan_chunk(
    us, count, mechanism, params, names, solver, t0, t1, ts, data, inv_sigma, mask, lanes
):
    """A chunk of scanned points on refilled lanes (``map_members(..., batched=True)``)."""
    n = us.shape[0]
    # per-member end and start times made here, as ``run_ensemble``'s refilled chunks do
    ends, starts = np.full(n, float(t1)), np.full(n, float(t0))
    return _scan_solve(
        us,
        count,
        ends,
        starts,
        mechanism,
        params,
        names,
        solver,
        t0,
        ts,
        data,
        inv_sigma,
        mask,
        lanes,
    )


@stored_jit
def _first_simulation(mechanism, params, names, solver, u, t0, t1, ts, data, inv_sigma, events):
    """The first simulation (at ``u``, up to ``t1``): residuals (S, N) (meaningful where
    ts <= t1), whether the solve succeeded, and each clearance joint's first ``events`` finished
    contacts (the ``Extremes`` event buffer of (onset, end) rows, and how many it saw)."""
    traj = simulate(
        with_parameters(mechanism, params.values(u)),
        t1,
        t0=t0,
        ts=jnp.minimum(ts, t1),
        solver=solver,
        extremes=True,
        contact_events=events,
    )
    out = signals(traj, names)
    model = jnp.stack([out[n] for n in names])
    x = traj.extremes
    return (model - data) * inv_sigma[:, None], traj.succeeded, x.events, x.event_count


PROBE_START = 1 / 64
"""The first simulation runs over this fraction of the record first, then over 4 times longer
spans until it has ``FIRST_CONTACTS`` contacts (or reaches the end of the record)."""


def _automatic_windows(
    mechanism, data, specs, config, t0: float, t_end: float
) -> tuple[tuple[float, ...], str]:
    """The growing windows when ``FitSettings.horizons`` is None: the first up to the first
    contacts (``_global_search.first_window_end``), then twice as long each, up to the record's end.

    Returns:
        (fractions of the record, a note on how the first window was chosen).
    """
    if not contact_joints(mechanism):  # no contacts to wait for: the record is one window
        return (1.0,), "one window: the mechanism has no clearance joint"
    probe = _Windows.of(mechanism, data, specs, config, t0, t_end, (1.0,))
    mech, params, names, solver = probe.static
    u = jnp.asarray([float(q.to_unconstrained(q.initial)) for q in specs])
    t_data = np.asarray(data.t, dtype=float)
    span, length = t_end - t0, (t_end - t0) * PROBE_START
    while True:
        t1 = min(t0 + length, t_end)
        r, ok, events, counts = _first_simulation(
            mech,
            params,
            names,
            solver,
            u,
            probe.t_start,
            jnp.asarray(t1),
            probe.ts,
            probe.data,
            probe.inv_sigma,
            FIRST_CONTACTS,
        )
        contacts = []
        pairs = set(
            corner_pair_channels(mechanism)
        )  # a guide's contacts count once, as the joint's
        for joint, buffer in events.items():
            if joint in pairs:
                continue
            rows = np.asarray(buffer)[: min(int(counts[joint]), FIRST_CONTACTS)]
            contacts += [(float(a), float(b)) for a, b in rows]
        if not bool(ok):
            contacts = []  # a failed first simulation: fall back on the ladder over the record
            break
        if len(contacts) >= FIRST_CONTACTS or t1 >= t_end:
            break
        length *= 4.0
    inside = t_data <= t1 + 1e-12 * span
    departed = np.flatnonzero(inside & np.any(np.abs(np.asarray(r)) > DEPARTURE, axis=0))
    departure = float(t_data[departed[0]]) if departed.size else None
    end, note = first_window_end(
        t0, t_end, contacts, departure, t_data, MIN_SAMPLES_PER_PARAMETER * len(specs)
    )
    if not bool(ok):
        note = "the first simulation failed; " + note
    return window_ladder(t0, t_end, end), f"first window to {end:.6g} s: {note}"


MIN_SAMPLES_PER_PARAMETER = 10
"""The first window holds at least this many data instants per fitted parameter."""


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
        probed: the first simulation's program is compiled (``_automatic_windows`` ran it):
            ``residuals`` uses it.
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
    probed: bool = False

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

    def residuals(self, u, k: int) -> np.ndarray | None:
        """Residuals (S·N,) over window ``k`` without the Jacobian, from the first simulation's
        program (compiled already; 3.4 times cheaper than ``residuals_and_jacobian`` with three
        parameters); ``None`` when that program was not compiled (``probed`` False)."""
        if not self.probed:
            return None
        mechanism, params, names, solver = self.static
        r, ok, _, _ = _first_simulation(
            mechanism,
            params,
            names,
            solver,
            jnp.asarray(u),
            self.t_start,
            jnp.asarray(self.ends[k]),
            self.ts,
            self.data,
            self.inv_sigma,
            FIRST_CONTACTS,
        )
        mask = np.asarray(self.masks[k])[None, :]
        return np.where(bool(ok), np.asarray(r) * mask, np.inf).ravel()

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
        starts: the starts of the refinement (unconstrained), best first. first: the window it
            starts with. separated: a window told the scanned points apart (else ``starts`` is the
            initial point and the refinement is skipped). table: ``{"values": (K, p), "loss": (K,),
            "spacing", "basin_width", "window_end"}`` (empty: no scan). note: ``""`` or why the scan
            could not resolve the measured basin width (for the status).
    """

    starts: list[np.ndarray]
    first: int
    separated: bool
    table: dict[str, Any]
    note: str = ""

    @property
    def u(self) -> np.ndarray:
        return self.starts[0]


def _advance(bar: Progress, n: int) -> None:
    """Count ``n`` steps, never past the bar's total (the scan's refinements are not known ahead)."""
    bar.update(max(0, min(int(n), bar.total - bar.count)))


def _global_scan(windows: _Windows, specs, settings: FitSettings, bar: Progress, record) -> _Scan:
    """The global stage (``_global_search``): scan a design on the first window that tells its
    points apart, refine it until its spacing resolves the measured basin width (within
    ``settings.max_scan_points``), and return the best points of distinct basins.

    Raises:
        ModelError: every scanned point failed to simulate.
    """
    p = len(specs)
    u0 = np.array([q.to_unconstrained(q.initial) for q in specs], dtype=float)
    count = settings.scan_count(p)
    if count <= 1:
        return _Scan([u0], 0, True, {})
    design = Design(specs, count)
    refill = settings.scan_engine == "refill"
    chunks = EnsembleSettings(chunk_size=SCAN_REFILL_CHUNK if refill else SCAN_CHUNK)
    if settings.scan_rtol is not None:  # the scan ranks points: an ordinary tolerance will do
        mechanism, space, names, config = windows.static
        rtol = settings.scan_rtol
        scan_config = config.replace(rtol=rtol, atol=rtol * SCAN_ATOL_FACTOR)
        windows = dataclasses.replace(windows, static=(mechanism, space, names, scan_config))

    def evaluate(units, k, with_start):
        values = design.to_values(units)
        if with_start:
            values[0] = [q.initial for q in specs]  # exactly, not through the unit coordinates
        us = np.stack(
            [
                [float(q.to_unconstrained(v)) for q, v in zip(specs, row, strict=True)]
                for row in values
            ]
        )
        r = map_members(
            _scan_chunk if refill else _scan_member,
            (*windows.args(k), DEFAULT_LANES) if refill else windows.args(k),
            us,
            settings=chunks,
            on_chunk=lambda start, stop: _advance(bar, 1),
            batched=refill,
        )
        return values, us, np.asarray(r)

    first, separated = 0, False
    for first in range(len(windows.ends)):
        values, us, r = evaluate(design.units, first, True)
        loss = scan_loss(r, windows.counts[first])
        separated = _separates(loss)
        if separated:
            break
    if not np.any(np.isfinite(loss)):
        raise ModelError(
            "every point of the global scan failed to simulate; check the bounds and the solver "
            "(a failed solve reports its time and state when run alone with jaxclear.simulate)."
        )
    n = windows.counts[first]
    width, spacing = math.nan, design.spacing()
    if separated:
        added = []

        def more(units):
            added.append(evaluate(units, first, False))
            return added[-1][2]

        r, width, spacing = resolve_basins(design, r, more, n, settings.scan_budget(p))
        values = np.concatenate([values, *(a[0] for a in added)])
        us = np.concatenate([us, *(a[1] for a in added)])
        loss = scan_loss(r, n)
    table = {
        "values": values,
        "loss": loss,
        "spacing": spacing,
        "basin_width": width,
        "window_end": windows.ends[first],
    }
    note = ""
    if separated and needs_refinement(spacing, width):
        note = (
            f"; the scan's spacing {spacing:.3g} is wider than the basin width {width:.3g} it "
            f"measured (scan coordinates; raise max_scan_points above {len(values)})"
        )
    if separated:
        separation = 2.0 * max(width, spacing) if math.isfinite(width) else 1.5 * spacing
        best = starting_points(design.units, loss, settings.starts, separation)
        starts = [us[i] for i in best]
        best_loss = float(loss[best[0]])
    else:  # say so, rather than pick one of the tied points: the initial point stays
        starts, best_loss = [u0], float(loss[0])
    record(
        {
            "stage": "scan",
            "horizon": windows.ends[first],
            "iteration": 0,
            "loss": best_loss,
            "values": _values(specs, starts[0]),
            "points": len(values),
            "spacing": spacing,
            "basin_width": width,
        }
    )
    return _Scan(starts, first, separated, table, note)


CONTINUATION_PATIENCE = 3
"""Levenberg–Marquardt iterations after which a window longer than the first stops if its loss is
still above ``LOSS_GROWTH`` times the best of the shorter windows (it would be dropped). Started
from the shorter windows' estimate, every window kept in the fits of docs/identification.md was
below that bound after 1 iteration (2 in an earlier version of the fit); a window where the model
parts from the data costs the most Jacobians of a fit (the longest solves): the three-unknown
record's 30 ms window took 12 of that fit's 53 evaluations, 33 s of 55 s, with patience 5."""


STALL_SHARE = 0.5
"""A window longer than the first also stops when an iteration, with the loss still above the
bound, closed less than this share of the gap between the loss and the bound: Levenberg–Marquardt
converging towards a minimum above the bound. In the fits of docs/identification.md every window
kept closed the gap in its first iteration (439.8 → 1.67 against a bound of 1.88); the dropped
ones closed 2–20 % of it (9.96 → 9.74 against 1.88; 102.4 → 100.2 against 1.79)."""


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
    windows: _Windows, specs, starts, first: int, settings: FitSettings, bar: Progress, record
) -> _Refinement:
    """Levenberg–Marquardt over the growing windows from ``first`` on, while the model follows the
    record (``LOSS_GROWTH``). On the first window it runs from each of ``starts`` and continues
    from the one that ends lowest (multi-start).

    Each window is ``max_iterations`` + 1 progress steps per start (the start and each iteration);
    what a window does not use, and the windows skipped or not reached, are counted as done.
    """
    budget = settings.max_iterations + 1
    iterations, converged, status = 0, False, ""
    kept: list[np.ndarray] = []  # the estimate (u) after each kept window
    best_loss = math.inf
    used = first
    u = starts[0]

    def hopeless(it, loss, previous):
        """Still above the loss at which the window is dropped, after a while or with an
        iteration that closed less than ``STALL_SHARE`` of the gap to it."""
        bound = LOSS_GROWTH * best_loss
        if loss <= bound:
            return False
        return it >= CONTINUATION_PATIENCE or previous - loss < STALL_SHARE * (previous - bound)

    for k, (end, n) in enumerate(zip(windows.ends, windows.counts, strict=True)):
        if k < first:
            _advance(bar, budget)
            continue  # before the first window that carries information on the parameters
        runs = []
        for j, u_start in enumerate(starts if k == first else [u]):
            stage = f"window {k + 1}/{len(windows.ends)}"
            if k == first and len(starts) > 1:
                stage += f", start {j + 1}/{len(starts)}"
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
                _advance(bar, 1)

            runs.append(
                _levenberg_marquardt(
                    lambda u, k=k: windows.residuals_and_jacobian(u, k),
                    u_start,
                    n,
                    settings.max_iterations,
                    settings.tolerance,
                    report,
                    None if k == first else hopeless,
                )
            )
            iterations += runs[-1][1]
            _advance(bar, budget - len(steps))
        finite = [run for run in runs if np.isfinite(run[4])] or runs
        u_new, its, conv, stat, loss = min(finite, key=lambda run: run[4])
        if k == first and len(starts) > 1:
            losses = ", ".join(f"{run[4]:.4g}" for run in runs)
            stat = f"{stat} (best of {len(starts)} starts, losses {losses})"
        if k > first and not loss <= LOSS_GROWTH * best_loss:
            status = (
                f"{stat}; the model does not follow the record beyond {windows.ends[used]:.6g} s "
                f"(loss {loss:.3g} over {end:.6g} s against {best_loss:.3g}): estimate from the "
                f"first {windows.ends[used] - windows.t0:.6g} s"
            )
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
    dof = max(windows.counts[used] - p, 1.0)
    scale = max(1.0, float(np.sum(r**2)) / dof)
    covariance, note = _covariance(specs, jac_u, dtheta, scale)
    values = _values(specs, u)
    # window-to-window change of the estimate: model or numerical error that the residuals'
    # covariance cannot see (correlated residuals) shows as a drift of the estimate with the span
    previous = _values(specs, fit.kept[-2]) if len(fit.kept) >= 2 else values
    drift = np.array([values[q.name] - previous[q.name] for q in specs])
    covariance = covariance + np.diag(drift**2 + _resolution(windows.static[0], specs) ** 2)
    std = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    estimates = {
        q.name: Estimate(values[q.name], float(std[i]), q.initial, q.lower, q.upper, q.unit)
        for i, q in enumerate(specs)
    }
    loss = float(np.sum(r**2)) / windows.counts[used]
    return estimates, covariance, loss, scale, note


def _resolution(mechanism: Mechanism, specs) -> np.ndarray:
    """The model's own resolution of each parameter, added to its variance: for a clearance, the
    joint's contact smoothing width (the larger of ``penetration_width`` and ``memory_width``,
    docs/model.md §5). The smooth law spreads the onset of contact over that width, so data from a
    sharp contact (or a real joint) place the wall only to within about it; measured, the fits of
    docs/identification.md land 1e-8 to 5e-8 m from the truth at the default 1e-7 m. 0 for other
    parameters."""
    out = np.zeros(len(specs))
    for i, q in enumerate(specs):
        joint, _, field = q.name.rpartition(".")
        if joint and field == "clearance":
            out[i] = max(
                float(get_parameter(mechanism, f"{joint}.{w}"))
                for w in ("penetration_width", "memory_width")
            )
    return out


CORRELATED = 0.99
"""|correlation| between two estimates above which they are reported as not separately
identifiable (the data constrain a combination of them, not each one)."""


def _covariance(specs, jac_u, dtheta, scale: float) -> tuple[np.ndarray, str]:
    """Gauss–Newton covariance s² (JᵀJ)⁻¹ in the parameters' units, with J = (∂r/∂u) / (∂θ/∂u),
    and a note for the status (``""`` if none).

    Infinite, never NaN, where it is not defined: a parameter pressed against a bound of its
    range (the transform's slope ∂θ/∂u is 0 there, in floating point), residuals or a Jacobian
    that are not finite (a failed solve), or a rank-deficient J. Estimates correlated beyond
    ``CORRELATED`` are named in the note.
    """
    p = len(specs)
    infinite = np.full((p, p), np.inf)
    at_bound = [
        q.name for q, d in zip(specs, dtheta, strict=True) if not (np.isfinite(d) and d != 0)
    ]
    if at_bound:
        return infinite, (
            f"; {', '.join(at_bound)} at a bound of {'its' if len(at_bound) == 1 else 'their'} "
            "range: the covariance is infinite (widen the bounds or start elsewhere)"
        )
    jac = jac_u / dtheta[None, :]
    if not np.all(np.isfinite(jac)):
        return infinite, "; the Jacobian is not finite (a solve failed): the covariance is infinite"
    if np.linalg.matrix_rank(jac) < p:  # a parameter (or combination) the data do not constrain
        return infinite, "; not identifiable from the data fitted: the covariance is infinite"
    covariance = scale * np.linalg.inv(jac.T @ jac)
    sd = np.sqrt(np.diag(covariance))
    pairs = [
        f"{specs[i].name} and {specs[j].name} ({covariance[i, j] / (sd[i] * sd[j]):+.3f})"
        for i in range(p)
        for j in range(i + 1, p)
        if abs(covariance[i, j]) > CORRELATED * sd[i] * sd[j]
    ]
    note = (
        f"; not separately identifiable, correlation beyond {CORRELATED}: {', '.join(pairs)}"
        if pairs
        else ""
    )
    return covariance, note


def _whole_record(windows: _Windows, data: Measurements, u) -> tuple[float, dict[str, np.ndarray]]:
    """The model at ``u`` over the whole record, also past the windows used (for plots and
    fit.csv): (loss over the whole record, ``{signal: fitted (N,)}``); without the Jacobian where
    the first simulation's program is compiled (the last window's Jacobian took a fifth of a 200
    rpm fit's time)."""
    last = len(windows.ends) - 1
    r_all = windows.residuals(u, last)
    if r_all is None:
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
        solver: ``SolverConfig`` or name; default ``default_fit_solver(mechanism)``: with
            Coulomb-type friction Lawson–Tsit5 at rtol 1e-8, atol 1e-11, the Jacobian from the
            error-controlled sensitivities (``simulate``'s ``adjoint="forward"``); otherwise
            ``jaxclear.gradient_solver(mechanism)``, whose discrete derivatives match converged
            finite differences. At any settings but ``gradient_solver``'s the Jacobian comes from
            the sensitivities.
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
    config = default_fit_solver(mechanism) if solver is None else solver_config(solver, mechanism)
    if settings.horizons is None:
        horizons, window_note = _automatic_windows(mechanism, data, specs, config, t0, t_end)
    else:
        horizons, window_note = settings.horizons, ""
    windows = _Windows.of(mechanism, data, specs, config, t0, t_end, horizons)
    probed = settings.horizons is None and bool(contact_joints(mechanism))
    windows = dataclasses.replace(windows, probed=probed)

    history: list[dict[str, Any]] = []

    def record(entry):
        history.append(entry)
        if callback is not None:
            callback(entry)

    p = len(specs)
    refill = settings.scan_engine == "refill"
    chunk = chunk_rows(EnsembleSettings(chunk_size=SCAN_REFILL_CHUNK if refill else SCAN_CHUNK))
    scan_steps = (
        math.ceil(settings.scan_count(p) / chunk) * len(windows.ends)
        + math.ceil(settings.scan_budget(p) / chunk)
        if settings.scan_count(p) > 1
        else 0
    )
    lm_steps = (len(windows.ends) + settings.starts - 1) * (settings.max_iterations + 1)
    with progress_bar(progress, scan_steps + lm_steps, "fit") as bar:
        scan = _global_scan(windows, specs, settings, bar, record)
        if scan.separated:
            fit = _refine_windows(windows, specs, scan.starts, scan.first, settings, bar, record)
        else:
            last = len(windows.ends) - 1
            fit = _Refinement(scan.u, last, [], 0, False, "not refined: the scanned points tie")
        _advance(bar, bar.total - bar.count)  # what the scan's refinement and the windows left

    estimates, covariance, loss, scale, note = _estimates(windows, specs, fit)
    loss_whole_record, fitted = _whole_record(windows, data, fit.u)
    fitted_span = windows.ends[fit.used] - windows.t0
    success, reason = _verdict(
        estimates, loss, windows.counts[fit.used], scan.separated, fitted_span
    )
    status = fit.status + note + scan.note + (f"; {window_note}" if window_note else "")
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


def _levenberg_marquardt(evaluate, u, count, max_iterations, tolerance, report, hopeless=None):
    """Minimise Σr² over u with damped Gauss–Newton steps (Marquardt's diagonal scaling).

    ``hopeless(iteration, loss, previous loss)``: stop early when it returns True (a window that
    will be dropped).

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
        previous = loss
        u, r, jac, loss = u_new, r_new, jac_new, loss_new
        damping = max(damping / 3.0, 1e-9)
        report(it, loss, u)
        if hopeless is not None and hopeless(it, loss, previous):
            return u, it, False, f"stopped after {it} iterations at loss {loss:.4g}", loss
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
