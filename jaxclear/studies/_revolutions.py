"""Revolution by revolution: per-revolution statistics, a steady-state verdict from the Poincaré
returns, and a horizon that ends when the response has settled (docs/outputs.md, "What to quote").

A clearance joint's impact sequence forks under rounding-level changes, so a single peak of one
run is not a property of the design; the median over the revolutions of the settled response is.
``simulate_revolutions`` integrates one crank revolution per solve, each started from the last
one's final state (the solver's own state at the revolution's end, not an interpolated one): the
revolution ends are the stroboscopic Poincaré returns, each revolution's statistics come from its
own solve's steps, and one compiled program serves every revolution, so a longer horizon (or
``"auto"``) compiles nothing new and a revolution once solved is never solved again.

The verdict: the returns x_0, x_1, … (x_k at the start of revolution k) are compared k
revolutions apart. The response has settled into a period-k orbit at return n when both
d(x_n, x_{n−k}) and d(x_{n−1}, x_{n−1−k}) are at most ``tolerance``, for the smallest such
k ≤ ``max_period``; d is the largest component of the difference in the scaled coordinates of
``return_coordinates``. Otherwise, up to the cap, the response is irregular (chaotic, quasi-
periodic or still in its transient), and the verdict gives the smallest distance found.
"""

import dataclasses
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..analysis._modes import contact_events, contact_joints, crank_period, shares_of_contacts
from ..analysis._statistics import statistics
from ..model import Mechanism
from ..solve._extremes import combine_extremes
from ..solve._simulate import assemble, simulate
from ..solve._solver import solver_config
from ..solve._trajectory import Trajectory, join_trajectories

MAX_REVOLUTIONS = 12
"""Cap of ``revolutions="auto"``: a response not settled by then is reported as irregular over the
revolutions after the start-up one (the benchmark three-joint run stays irregular; the one-joint
runs of docs/outputs.md settle within 3–6 revolutions)."""

MAX_PERIOD = 8
"""Largest period (in revolutions) the verdict looks for."""

SETTLED_TOLERANCE = 1e-2
"""Returns k revolutions apart closer than this (largest scaled component, see
``return_coordinates``) count as the same point of a period-k orbit. Chosen from the distances
measured in docs/outputs.md: a settled one-joint run returns within 1e-6–1e-5 (the solver's
tolerance), an irregular run's closest returns stay above 1e-2."""

COMPANION_PERTURBATION = 1e-12
"""Relative size of the companions' initial-state perturbation (``companions``): each state
component is multiplied by 1 + 1e-12·ξ, ξ standard normal. Rounding level: a Runge–Kutta step
changes the state by a relative 1e-16 of rounding per operation and a revolution takes thousands
of steps, so two runs of one design that differ only in their compiled program (output grid,
tolerance, XLA flags) already differ by this much after the first steps; a statistic that moves
under it is not a property of the design. (A tolerance perturbation would need another compiled
program per companion: the solver settings are static.)"""

SENSITIVE_SPREAD = 0.02
"""A statistic whose median over the kept revolutions spreads over more than 2 % of the
nominal's across the companions is marked sensitive (the issue's bar for a figure to quote)."""

START_UP_REVOLUTIONS = 1
"""Revolutions left out of an irregular response's statistics: a centred journal's start-up impact
is over within the first revolution on the benchmark (``jaxclear run --skip-revolutions``)."""


@dataclasses.dataclass(frozen=True)
class SteadyState:
    """The verdict on a run's Poincaré returns.

    Attributes:
        settled: whether the response settled into a period-k orbit.
        period: k (revolutions per repetition) if settled, else ``None``.
        distance: the distance that decided it: the larger of the two return distances that
            matched (settled), else the smallest distance of any return to the one k revolutions
            earlier over the last revolutions (irregular).
        settled_from: first revolution of the settled orbit (0-based), else ``None``.
        tolerance: the tolerance the distances were compared with.
        revolutions: returns examined (the revolutions solved).
    """

    settled: bool
    period: int | None
    distance: float
    settled_from: int | None
    tolerance: float
    revolutions: int

    @property
    def decided(self) -> bool:
        """Whether there were enough returns to look for a period: settling needs two matches, so
        at least 3 revolutions."""
        return self.settled or self.revolutions >= 3

    @property
    def label(self) -> str:
        """``"period-k"``, ``"irregular"`` or ``"undecided"`` (fewer than 3 revolutions)."""
        if self.settled:
            return f"period-{self.period}"
        return "irregular" if self.decided else "undecided"

    def describe(self) -> str:
        """One line for people: what was decided and on what distance."""
        if not self.decided:
            return (
                f"steady state undecided: {self.revolutions} revolution(s) are too few "
                "(3 or more compare returns; e.g. --revolutions 8)"
            )
        if self.settled:
            return (
                f"settled, period-{self.period} from revolution {self.settled_from} "
                f"(returns {self.period} revolution(s) apart within {self.distance:.2g} <= {self.tolerance:g})"
            )
        return (
            f"irregular over {self.revolutions} revolutions (closest return {self.distance:.2g} > "
            f"{self.tolerance:g} for every period up to {MAX_PERIOD})"
        )

    def as_dict(self) -> dict:
        return {
            "verdict": self.label,
            "settled": self.settled,
            "period": self.period,
            "distance": self.distance,
            "settled_from_revolution": self.settled_from,
            "tolerance": self.tolerance,
            "revolutions": self.revolutions,
        }


def _state_columns(traj: Trajectory) -> list[np.ndarray]:
    """The state at the saved instants in groups compared alike: positions, each body's angle as
    (cos, sin) (a crank's angle grows by 2π per revolution), velocities, internal states."""
    q = np.asarray(traj.q)
    angles = q[:, 2::3]
    return [
        np.delete(q, np.s_[2::3], axis=-1),
        np.concatenate([np.cos(angles), np.sin(angles)], axis=-1),
        np.asarray(traj.qd),
        np.asarray(traj.internal_state),
    ]


STATE_SCALE_FLOOR = 1e-3
"""A state component that hardly moves (a slider's y, a constant LuGre state) is scaled by at
least this fraction of its group's largest range, so that round-off in it does not count as a
distance."""


def return_coordinates(mechanism: Mechanism, parts: list[Trajectory]) -> np.ndarray:
    """The Poincaré returns of consecutive revolutions ``parts`` in the verdict's scaled
    coordinates: at the first saved instant of each and the last of the last.

    Each revolute clearance joint's eccentricity over its clearance, e/c, and its penetration rate
    and slip velocity over c·ω (ω the crank speed): the clearance motion in units of the
    clearance; then the state (``_state_columns``), each component over its range over all the
    revolutions, floored at ``STATE_SCALE_FLOOR`` of its group's largest range.

    Returns:
        (len(parts) + 1, features).
    """
    period = crank_period(mechanism)
    omega = 2 * np.pi / period if period else 1.0
    pick = [(p, 0) for p in parts] + [(parts[-1], -1)]
    columns = []
    for joint in mechanism.clearance_joints:
        geometry = getattr(joint, "geometry", None)
        first = parts[0].clearance.get(joint.name)
        if geometry is None or first is None or "ecc_x" not in first:
            continue
        c = float(geometry.clearance)
        for name, scale in (
            ("ecc_x", c),
            ("ecc_y", c),
            ("penetration_rate", c * omega),
            ("slip_velocity", c * omega),
        ):
            columns.append(
                np.array([float(np.asarray(p.clearance[joint.name][name])[i]) for p, i in pick])
                / scale
            )
    groups = [_state_columns(p) for p in parts]
    for g in range(len(groups[0])):
        values = [parts_group[g] for parts_group in groups]
        if values[0].shape[-1] == 0:
            continue
        spread = np.max([v.max(0) for v in values], 0) - np.min([v.min(0) for v in values], 0)
        scale = np.maximum(spread, STATE_SCALE_FLOOR * spread.max())
        scale = np.where(scale > 0, scale, 1.0)
        rows = np.stack([values[k][0] for k in range(len(parts))] + [values[-1][-1]])
        columns.extend((rows / scale).T)
    return np.stack(columns, axis=-1)


def steady_state(
    returns: np.ndarray, tolerance: float = SETTLED_TOLERANCE, max_period: int = MAX_PERIOD
) -> SteadyState:
    """The verdict on Poincaré returns x_0 … x_R (rows of ``returns``, x_k at the start of
    revolution k, in the scaled coordinates of ``return_coordinates``); see the module docstring.

    The first settled return is searched from the start, so the verdict names the earliest
    revolution from which the orbit repeats.
    """
    x = np.asarray(returns, dtype=float)
    count = x.shape[0] - 1  # revolutions
    distance = lambda a, b: float(np.max(np.abs(x[a] - x[b]))) if x.shape[1] else 0.0  # noqa: E731
    for n in range(2, count + 1):
        for k in range(1, min(max_period, n - 1) + 1):
            d = max(distance(n, n - k), distance(n - 1, n - 1 - k))
            if d <= tolerance:
                return SteadyState(True, k, d, n - 1 - k, tolerance, count)
    closest = [
        distance(n, n - k)
        for n in range(max(1, count - max_period), count + 1)
        for k in range(1, min(max_period, n) + 1)
    ]
    return SteadyState(False, None, min(closest) if closest else math.inf, None, tolerance, count)


@dataclasses.dataclass(frozen=True)
class RevolutionRun:
    """A run solved revolution by revolution (``simulate_revolutions``).

    Attributes:
        trajectory: all revolutions as one ``Trajectory`` (saved instants of every revolution);
            its ``extremes`` cover the kept revolutions (``kept``), its contact events all of them.
        revolutions: each revolution's own ``Trajectory`` (its extremes over that revolution).
        returns: (R + 1, features) Poincaré returns in the verdict's scaled coordinates.
        verdict: the ``SteadyState``.
        kept: indices of the revolutions the summary covers: the settled orbit's, or those after
            the start-up (``skip``).
        period: crank period, s.
        statistics_start: start of the kept window, s.
        companion_revolutions: with ``companions=K``, each revolution's batched ``Trajectory``
            of the K companions (``spread``), else ``None``.
    """

    trajectory: Trajectory
    revolutions: list[Trajectory]
    returns: np.ndarray
    verdict: SteadyState
    kept: tuple[int, ...]
    period: float
    statistics_start: float
    companion_revolutions: "list[Trajectory] | None" = None

    def spread(self, threshold: float = SENSITIVE_SPREAD) -> dict[str, dict]:
        """Each statistic's median over the kept revolutions for the nominal run and for each
        companion (``simulate_revolutions(companions=K)``): ``{name: {"nominal", "min", "max",
        "relative_spread", "sensitive", "companions"}}``, the spread being (max − min)/|nominal|
        over the nominal and the companions that succeeded. Empty without companions."""
        if not self.companion_revolutions:
            return {}
        kept = list(self.kept)
        nominal = self.summary()
        per_revolution = [
            {k: np.asarray(v, dtype=float) for k, v in statistics(traj).items()}
            for traj in self.companion_revolutions
        ]  # each {name: (K,)} for one revolution
        ok = np.all(np.stack([np.asarray(t.succeeded) for t in self.companion_revolutions]), axis=0)
        out = {}
        for name, values in nominal.items():
            table = np.stack([r[name] for r in per_revolution])[kept]  # (kept, K)
            medians = np.median(table[:, ok], axis=0) if ok.any() else np.zeros(0)
            everything = np.append(medians, values["median"])
            scale = abs(values["median"]) or 1.0
            relative = float((everything.max() - everything.min()) / scale)
            out[name] = {
                "nominal": values["median"],
                "min": float(everything.min()),
                "max": float(everything.max()),
                "relative_spread": relative,
                "sensitive": bool(relative > threshold),
                "companions": medians.tolist(),
            }
        return out

    def revolution_statistics(self) -> dict[str, np.ndarray]:
        """Each revolution's named statistics (``jaxclear.analysis.statistics``): {name: (R,)};
        values of a revolution wholly before the kept window are NaN."""
        rows = []
        for traj in self.revolutions:
            x = traj.extremes
            empty = x is None or float(x.duration) <= 0
            stats = {} if x is None else statistics(traj)
            rows.append({k: (np.nan if empty else float(v)) for k, v in stats.items()})
        names = list(rows[0]) if rows else []
        return {k: np.array([r.get(k, np.nan) for r in rows]) for k in names}

    def summary(self) -> dict[str, dict[str, float]]:
        """Median, min and max over the kept revolutions of each named statistic."""
        table = self.revolution_statistics()
        kept = list(self.kept)
        out = {}
        for name, values in table.items():
            if name in ("statistics_start", "statistics_duration"):
                continue
            v = values[kept]
            v = v[np.isfinite(v)]
            if v.size:
                out[name] = {
                    "median": float(np.median(v)),
                    "min": float(v.min()),
                    "max": float(v.max()),
                }
        return out

    def table(self, continuous_fraction: float | None = None) -> list[dict]:
        """One row per revolution (revolutions.csv, run.json's ``revolutions``): ``revolution``,
        ``start_s``, ``end_s``, ``kept`` (1 if the summary covers it), its named statistics and,
        with ``continuous_fraction`` and recorded contact events, each clearance joint's
        ``{J}_impact_share``, ``{J}_continuous_share``, ``{J}_impacts`` and
        ``{J}_continuous_contacts``."""
        stats = self.revolution_statistics()
        shares = None
        if continuous_fraction is not None:
            try:
                shares = self.mode_shares(continuous_fraction)
            except ValueError:  # no recorded events, or a buffer overflowed
                shares = None
        rows = []
        for k, traj in enumerate(self.revolutions):
            row = {
                "revolution": k,
                "start_s": float(traj.t[0]),
                "end_s": float(traj.t_final),
                "kept": int(k in self.kept),
            }
            row.update({name: float(v[k]) for name, v in stats.items()})
            if shares is not None:
                for joint, share in shares[k]["joints"].items():
                    row[f"{joint}_impact_share"] = share["impact"]
                    row[f"{joint}_continuous_share"] = share["continuous"]
                    row[f"{joint}_impacts"] = share["impacts"]
                    row[f"{joint}_continuous_contacts"] = share["continuous_contacts"]
            rows.append(row)
        return rows

    def mode_shares(self, continuous_fraction: float) -> list[dict]:
        """Each revolution's contact-mode time shares (``shares_of_contacts``), from the contact
        events of the whole run (a contact across a revolution's end keeps its full duration for
        its mode). Needs ``contact_events`` > 0."""
        events = contact_events(
            self.trajectory,
            continuous_fraction=continuous_fraction,
            reference_period=self.period,
            start=float(self.trajectory.t[0]),
        )
        order = [j for j in contact_joints(self.trajectory.mechanism) if j in events]
        out = []
        for traj in self.revolutions:
            a, b = float(traj.t[0]), float(traj.t_final)
            clipped = {}
            for j, e in events.items():
                inside = (e["end"] > a) & (e["onset"] < b)
                clipped[j] = {
                    key: (np.clip(v[inside], a, b) if key in ("onset", "end") else v[inside])
                    for key, v in e.items()
                }
            out.append(shares_of_contacts(clipped, order, a, b))
        return out


def segment_points(span: float, points_per_revolution: int) -> int:
    """Saved instants of a solve over ``span`` revolutions (1, or a fractional last one)."""
    if span == 1.0:
        return int(points_per_revolution) + 1
    return max(2, round(span * points_per_revolution) + 1)


def simulate_revolutions(
    mechanism: Mechanism,
    revolutions: "int | float | str" = "auto",
    *,
    points_per_revolution: int = 360,
    skip: "int | float | str" = "auto",
    max_revolutions: int = MAX_REVOLUTIONS,
    tolerance: float = SETTLED_TOLERANCE,
    max_period: int = MAX_PERIOD,
    solver="auto",
    t0: float = 0.0,
    y0=None,
    contact_events: int = 0,
    on_revolution: Callable[[int, Trajectory], None] | None = None,
    companions: int = 0,
    seed: int = 0,
) -> RevolutionRun:
    """Simulate a crank-driven mechanism one revolution per solve, with per-revolution statistics
    and a steady-state verdict (see the module docstring).

    Args:
        mechanism: a ``Mechanism`` with a constant-speed driver.
        revolutions: how many revolutions (a fractional last one is solved by a second compiled
            program), or ``"auto"``: until the response has settled into a period-k orbit
            (k ≤ ``max_period``), at most ``max_revolutions``.
        points_per_revolution: saved instants per revolution (the statistics come from the
            solver's steps and do not depend on it).
        skip: revolutions left out of the summary and of ``trajectory.extremes``: ``"auto"``
            keeps the settled orbit's revolutions, or those after ``START_UP_REVOLUTIONS`` if the
            response is irregular; a number (may be fractional) leaves out that many.
        tolerance, max_period: the verdict's (``steady_state``).
        solver: as ``simulate``'s.
        t0: start time, s. y0: initial state (default: assembled at t0).
        contact_events: events recorded per revolution and clearance joint (``simulate``).
        on_revolution: called after each revolution with its index and ``Trajectory`` (e.g. to
            write finished work or show progress).
        companions: K > 0 also solves K companions in one vectorised batch per revolution, each
            started from the initial state perturbed at the rounding level
            (``COMPANION_PERTURBATION``, random signs from ``seed``) and run for the nominal run's
            revolutions: ``RevolutionRun.spread`` then says which statistics move under it.

    Returns:
        A ``RevolutionRun``. A failed revolution ends the run: ``trajectory`` then ends with it
        (``trajectory.succeeded`` is False) and the verdict covers the revolutions before it.

    Raises:
        ValueError: no constant-speed driver, or a bad ``revolutions``/``skip``/
            ``points_per_revolution``.
    """
    period = crank_period(mechanism)
    if period is None:
        raise ValueError(
            "simulate_revolutions needs a constant-speed driver (a crank period); use simulate for "
            "other mechanisms."
        )
    auto = revolutions == "auto"
    if not auto:
        if isinstance(revolutions, str) or not (float(revolutions) > 0):
            raise ValueError(f'revolutions must be positive or "auto", got {revolutions!r}.')
        total = float(revolutions)
    else:
        total = float(max_revolutions)
    if int(points_per_revolution) < 2:
        raise ValueError(f"points_per_revolution must be at least 2, got {points_per_revolution}.")
    if int(companions) < 0:
        raise ValueError(f"companions must be 0 or more, got {companions}.")
    if skip != "auto" and (isinstance(skip, str) or not (0 <= float(skip) < total)):
        raise ValueError(f'skip must be "auto" or in [0, revolutions), got {skip!r}.')
    config = solver_config(solver, mechanism)
    t_keep = None if skip == "auto" else t0 + float(skip) * period
    state = assemble(mechanism, t0) if y0 is None else jnp.asarray(y0, dtype=float)
    others = None
    if companions:
        xi = np.random.default_rng(seed).standard_normal((int(companions), state.shape[0]))
        others = jnp.asarray(np.asarray(state) * (1.0 + COMPANION_PERTURBATION * xi))
    companion_parts: list[Trajectory] = []
    parts: list[Trajectory] = []
    returns = []
    verdict = None
    whole, fraction = int(math.floor(total + 1e-9)), total - math.floor(total + 1e-9)
    spans = [1.0] * whole + ([fraction] if fraction > 1e-9 else [])
    start = t0
    for k, span in enumerate(spans):
        end = start + span * period
        points = segment_points(span, points_per_revolution)
        traj = _revolution(state, mechanism, start, end, points, config, contact_events, t_keep)
        parts.append(traj)
        if others is not None:
            batch = _companion_revolution(
                mechanism, others, start, end, points, config, contact_events, t_keep
            )
            companion_parts.append(batch)
            others = batch.y_final
        if on_revolution is not None:
            on_revolution(k, traj)
        if not bool(traj.succeeded):
            break
        state, start = traj.y_final, end
        if auto and span == 1.0:
            verdict = steady_state(return_coordinates(mechanism, parts), tolerance, max_period)
            if verdict.settled:
                break
    joined = join_trajectories(parts)
    whole_parts = [p for p in parts if bool(p.succeeded) and _is_whole(p, period)]
    returns = return_coordinates(mechanism, whole_parts) if whole_parts else np.zeros((1, 0))
    verdict = steady_state(returns, tolerance, max_period)
    if skip == "auto":
        first = (
            verdict.settled_from if verdict.settled else min(START_UP_REVOLUTIONS, len(parts) - 1)
        )
        kept = tuple(range(first, len(parts)))
    else:
        kept = tuple(i for i, p in enumerate(parts) if float(p.t_final) > t_keep)  # type: ignore[operator]
    kept = kept or (len(parts) - 1,)
    used = [parts[i] for i in kept]
    window = (
        combine_extremes([p.extremes for p in used], [float(p.t[0]) for p in used])
        if all(p.extremes is not None for p in parts)
        else None
    )
    if window is not None and joined.extremes is not None:
        all_events = joined.extremes
        window = dataclasses.replace(
            window,
            events=all_events.events,
            event_count=all_events.event_count,
            contact_onset=all_events.contact_onset,
        )
    trajectory = dataclasses.replace(joined, extremes=window)
    return RevolutionRun(
        trajectory=trajectory,
        revolutions=parts,
        returns=returns,
        verdict=verdict,
        kept=kept,
        period=period,
        statistics_start=float(parts[kept[0]].t[0]) if t_keep is None else float(t_keep),
        companion_revolutions=companion_parts[: len(parts)] or None,
    )


def compile_revolutions(
    mechanism: Mechanism,
    *,
    span: float = 1.0,
    points_per_revolution: int = 360,
    solver="auto",
    t0: float = 0.0,
    contact_events: int = 0,
    companions: int = 0,
    fraction: float = 1e-3,
) -> None:
    """Compile what ``simulate_revolutions`` runs per revolution of ``span`` revolutions (1: a
    whole one; less: a run shorter than a revolution), for the nominal run and for ``companions``
    companions in their vectorised batch, by solving ``fraction`` of a revolution with the same
    output shapes and settings (start and end times are traced values, so the revolutions reuse
    the programs). Lets a caller time compilation apart from the run (``jaxclear run``'s
    ``compile`` and ``run``)."""
    period = crank_period(mechanism)
    if period is None:
        raise ValueError("compile_revolutions needs a constant-speed driver (a crank period).")
    config = solver_config(solver, mechanism)
    state = assemble(mechanism, t0)
    points = segment_points(span, points_per_revolution)
    end = t0 + fraction * period
    args = (mechanism, t0, end, points, config, contact_events, None)
    jax.block_until_ready(_revolution(state, *args).y_final)
    if companions:
        states = jnp.broadcast_to(state, (int(companions), state.shape[0]))
        jax.block_until_ready(_companion_revolution(args[0], states, *args[1:]).y_final)


def _revolution(y0, mechanism, start, end, points, config, contact_events, t_keep) -> Trajectory:
    """One revolution (or the last part of one) from state ``y0``: a ``simulate`` over
    [start, end] whose statistics start at ``t_keep`` if later."""
    return simulate(
        mechanism,
        end,
        t0=start,
        num_points=points,
        solver=config,
        y0=y0,
        statistics_start=start if t_keep is None else max(start, t_keep),
        contact_events=contact_events,
        throw=False,
    )


def _companion_revolution(mechanism, states, start, end, points, config, contact_events, t_keep):
    """One revolution of the companions: ``_revolution`` vmapped over their initial states."""
    return eqx.filter_vmap(
        lambda y: _revolution(y, mechanism, start, end, points, config, contact_events, t_keep)
    )(states)


def _is_whole(traj: Trajectory, period: float) -> bool:
    return abs(float(traj.t_final) - float(traj.t[0]) - period) <= 1e-9 * period
