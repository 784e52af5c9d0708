"""The file-backed ensemble run: many members of one mechanism topology, each solved and summed up.

Monte Carlo over tolerances (``montecarlo``), parameter sweeps (``sweep``) and the commands built on
them run through ``run_ensemble``. A member is the mechanism with some named parameters
(``jaxclear.parameter_names``) replaced; its result is the ``statistics`` of ``jaxclear run``
(same names, from the solver's steps), the RMS deviation of chosen signals from the ideal
mechanism, per-joint contact-mode shares and counts and the shares of the 3ⁿ combinations (from
contacts located from the solver's steps), the solver's step count and its share of the chunk's
wall time.

How it runs (``EnsembleSettings``):
- members are solved in vectorised chunks, split over the local devices, by the engine
  (``map_members``, ``jaxclear.studies._engine``): in lockstep (``engine="lockstep"``, a vmapped
  ``simulate`` per chunk) or on refilled lanes (``engine="refill"``, ``solve_members`` with the
  output grid, then the same statistics code, ``_summary``);
- members are ordered by expected cost before they are chunked (``order="cost"``: the step counts
  of the members solved so far, regressed on the drawn values; see ``cost_order``);
- with ``out`` given, finished members are written after every chunk (atomic replace of the CSV
  and of a JSON manifest, ``jaxclear.studies._ensemble_result``); called again with the same
  arguments it resumes, solving only the members not yet on disk, and refuses a changed
  configuration;
- a member whose solve fails, or whose drawn values are not admissible, is recorded with its
  message, its statistics are NaN, and the others go on.
"""

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from .._core._errors import EnsembleError, InputCheck
from .._core._executable_cache import stored_jit
from .._core._progress import progress_bar
from ..analysis._modes import (
    CONTINUOUS,
    DEFAULT_CONTINUOUS_FRACTION,
    FREE,
    IMPACT,
    MODE_NAMES,
    all_combinations,
    contact_joints,
    grid_contacts,
    located_contacts,
    shares_of_contacts,
)
from ..analysis._signals import signal_names, signals
from ..analysis._statistics import statistic_names, statistics
from ..model import Mechanism, get_parameter, parameter_info, with_parameters
from ..solve._lanes import _Program, batched_trajectories, members_solution
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, solver_config
from ..solve._startup import ideal_mechanism
from ._engine import (
    EnsembleSettings,
    chunk_rows,
    chunk_size_of,
    concurrent_refill,
    cost_order,
    map_members,
)
from ._ensemble_result import FAILED, OK, EnsembleResult, mechanism_values, resume, save

NON_NEGATIVE = frozenset({"friction_coefficient", "viscous_friction", "damping", "free_length"})
"""Fields whose admissible range includes its lower bound 0 (``ParameterInfo.domain`` is open)."""
FORMAT = 2  # 2: contact modes from located events, counts and combination shares
EVENTS_PER_REVOLUTION = 128
"""Default room for contacts per clearance joint and crank revolution (at least 256 in all), here
and in ``jaxclear run``: the default run has 3–7 contacts per joint and revolution; where the
buffer overflows, the modes come from the saved grid (``grid_contacts``)."""


# --- one member ------------------------------------------------------------------------------------


def _window_rms(t, x, start):
    """RMS of x(t) over t ≥ start (trapezoidal rule on the output grid)."""
    w = jnp.where(t >= start, 1.0, 0.0)
    seg = 0.5 * (w[1:] + w[:-1]) * jnp.diff(t)
    return jnp.sqrt(jnp.sum(seg * 0.5 * (x[1:] ** 2 + x[:-1] ** 2)) / jnp.sum(seg))


def _window_mean(t, x, start):
    w = jnp.where(t >= start, 1.0, 0.0)
    seg = 0.5 * (w[1:] + w[:-1]) * jnp.diff(t)
    return jnp.sum(seg * 0.5 * (x[1:] + x[:-1])) / jnp.sum(seg)


def _member_of_row(v, mechanism, names, config, ideal_config, deviation, events, ts, t0, t1, start):
    return _member(mechanism, names, config, ideal_config, deviation, events, v, ts, t0, t1, start)


def _member_replay_of_row(
    v, mechanism, names, config, ideal_config, deviation, events, ts, t0, t1, start
):
    """``_member_of_row`` with the member's trajectory as well (``replay_member``)."""
    return _member(
        mechanism, names, config, ideal_config, deviation, events, v, ts, t0, t1, start, True
    )


def _member(
    mechanism, names, config, ideal_config, deviation, events, v, ts, t0, t1, start, keep=False
):
    """One member: its statistics, its contacts (located events, and penetrations on the grid in
    case the event buffer overflows), outcome; with ``keep``, its trajectory as well."""
    m = with_parameters(mechanism, {n: v[k] for k, n in enumerate(names)})
    traj = simulate(
        m,
        t1,
        t0=t0,
        ts=ts,
        solver=config,
        statistics_start=start,
        throw=False,
        contact_events=_events(mechanism, events),
    )
    ideal = None
    if deviation:
        ideal = simulate(
            ideal_mechanism(m),
            t1,
            t0=t0,
            ts=ts,
            solver=ideal_config,
            extremes=False,
            throw=False,
        )
    return _summary(mechanism, deviation, traj, ideal, ts, start, keep)


def _events(mechanism, events):
    """Room for contact events per joint: ``events`` where the mechanism has contact joints."""
    return events if contact_joints(mechanism) else 0


def _summary(mechanism, deviation, traj, ideal, ts, start, keep=False):
    """A member's statistics, contacts and outcome from its trajectory ``traj`` on ``ts`` (and
    its ideal mechanism's, ``ideal``, for the ``deviation`` signals), whichever engine solved
    it (``_member``: lockstep; ``_refilled_chunk``: refilled lanes)."""
    m = traj.mechanism
    stats = dict(statistics(traj))
    if mechanism.driver is not None:
        tau = traj.input_torque
        stats["torque_fluctuation"] = _window_rms(ts, tau - _window_mean(ts, tau, start), start)
    if deviation:
        mine, theirs = signals(traj, deviation), signals(ideal, deviation)
        for name in deviation:
            stats[f"{name}_deviation"] = _window_rms(ts, mine[name] - theirs[name], start)
    # in the order of the modes' combinations (contact_joints)
    joints = contact_joints(mechanism)
    contacts = {"penetration": {j: traj.clearance[j]["penetration"] for j in joints}}
    if joints:
        x = traj.extremes
        assert x is not None  # simulate's default extremes=True
        contacts.update(events=x.events, count=x.event_count, ongoing=x.contact_onset)
    outcome = {
        "num_steps": traj.num_steps,
        "succeeded": traj.succeeded,
        "result": traj.result._value,  # pyright: ignore[reportAttributeAccessIssue]
        "input_error": traj.input_error,
        "t_final": traj.t_final,
    }
    speed = None if m.driver is None else m.driver.constant_speed
    if speed is not None:  # the member's own crank period sets its impact/continuous threshold
        outcome["speed"] = jnp.asarray(speed, dtype=float)
    if keep:
        return stats, contacts, outcome, traj
    return stats, contacts, outcome


# --- a chunk on refilled lanes ----------------------------------------------------------------------


@stored_jit
def _refill_solve(values, count, arguments, ends, starts, lanes, ideal=False):
    """The first ``count`` rows of ``values`` solved on ``lanes`` refilled lanes as ``_member``
    solves one (``solve_members`` with the output grid ``ts``), or with ``ideal`` their ideal
    mechanisms as ``_member`` solves them for the deviations: a ``MemberSolutions``.
    ``arguments``: ``_member``'s after its row (``_Plan.arguments``); ``ends``, ``starts``: (N,)
    each member's t1 and statistics start, s."""
    mechanism, names, config, ideal_config, deviation, events, ts, t0, t1, start = arguments
    program = _Program(
        mechanism=mechanism,
        names=names,
        config=ideal_config if ideal else config,
        track=not ideal,
        max_events=0 if ideal else _events(mechanism, events),
        ideal=ideal,
    )
    return members_solution(program, values, t0, ends, starts, None, lanes, ts, count)


@stored_jit
def _refill_summaries(members, ideal, mechanism, deviation, ts, start):
    """``_summary`` of every member of ``_refill_solve``'s solutions (vmapped)."""
    trajectories = batched_trajectories(members)
    ideals = None if ideal is None else batched_trajectories(ideal)
    return jax.vmap(lambda tr, idl: _summary(mechanism, deviation, tr, idl, ts, start))(
        trajectories, ideals
    )


def _refilled_chunk(values, count, arguments, lanes, keep=False):
    """A chunk's members on refilled lanes (``map_members(..., batched=True)``): their
    statistics, contacts and outcomes as ``_member`` gives them; with ``keep``, their batched
    ``Trajectory`` as well (built by its own program from the same solutions, so the statistics
    come from the very program of the run)."""
    mechanism, deviation, ts, t0, t1, start = (arguments[i] for i in (0, 4, 6, 7, 8, 9))
    # per-member end and start times made here, not broadcast inside the program: with t1
    # broadcast inside it, XLA's algebraic simplifier logged that it was stuck in a loop
    # (clearance-joint slider–crank; compilation 22 s against 19 s)
    n = values.shape[0]
    ends, starts = (np.full(n, float(x)) for x in (t1, start))
    members = _refill_solve(values, count, arguments, ends, starts, lanes)
    ideal = None
    if deviation:
        starts = np.full(n, float(t0))
        ideal = _refill_solve(values, count, arguments, ends, starts, lanes, True)
    out = _refill_summaries(members, ideal, mechanism, deviation, ts, start)
    if keep:
        return (*out, members.trajectories())
    return out


# --- the run --------------------------------------------------------------------------------------


def _check_values(
    mechanism: Mechanism, values: Mapping[str, Any]
) -> tuple[tuple[str, ...], np.ndarray]:
    if not values:
        raise EnsembleError("values is empty: give at least one parameter, {name: (N,) values}.")
    names = tuple(values)
    for n in names:
        parameter_info(mechanism, n)  # ModelError naming the closest valid name
    arrays = [np.atleast_1d(np.asarray(values[n], dtype=float)) for n in names]
    sizes = {a.shape for a in arrays}
    if len(sizes) != 1 or len(arrays[0].shape) != 1:
        raise EnsembleError(
            "values must all be 1-D arrays of one length (one value per member); got shapes "
            + ", ".join(f"{n} {a.shape}" for n, a in zip(names, arrays))
            + "."
        )
    return names, np.stack(arrays, axis=1)


def inadmissible_values(mechanism: Mechanism, names, values: np.ndarray) -> list[str]:
    """Per member (row of ``values``, one column per name), why its values cannot be simulated
    ("" if they can): a value outside its parameter's admissible range (``parameter_info``)."""
    out = [""] * len(values)
    for k, n in enumerate(names):
        low, high = parameter_info(mechanism, n).domain
        x = values[:, k]
        field = n.rsplit(".", 1)[-1]
        closed = low == 0.0 and field in NON_NEGATIVE
        below = (x < low) if closed else (x <= low)
        for i in np.flatnonzero(~np.isfinite(x) | below | (x >= high)):
            if not out[i]:
                left = "[" if closed else "("
                out[i] = (
                    f"{n} = {float(x[i])!r} is outside its admissible range {left}{low:g}, {high:g})"
                )
    return out


def _result_message(code: int, t_final: float) -> str:
    try:
        text = diffrax.RESULTS[code]  # pyright: ignore[reportIndexIssue]
    except Exception:  # message lookup is best effort; the code is what matters
        text = f"solver result code {code}"
    return f"solve failed at t = {t_final:.6g} s: {text}".replace("\n", " ")


@dataclasses.dataclass
class _Plan:
    """An ensemble's checked inputs, shared by ``run_ensemble`` and ``replay_member``: one plan
    gives both the same compiled program and the same chunks."""

    mechanism: Mechanism
    names: tuple[str, ...]
    values: np.ndarray
    config: SolverConfig
    deviation: tuple[str, ...]
    events: int
    ts: np.ndarray
    t0: float
    t1: float
    start: float
    period: float | None
    fraction: float
    statistic_names: list[str]
    summary_names: tuple[str, ...]  # those of _summary (the rest are the contact modes')

    def arguments(self, mechanism: Mechanism) -> tuple:
        """The member function's arguments after its row (``_member_of_row``)."""
        return (
            mechanism,
            self.names,
            self.config,
            solver_config("fast"),
            self.deviation,
            self.events,
            jnp.asarray(self.ts),
            jnp.asarray(self.t0, dtype=float),
            jnp.asarray(self.t1, dtype=float),
            jnp.asarray(self.start, dtype=float),
        )

    def solve(
        self, members: np.ndarray, chunk: int, settings: EnsembleSettings, keep: bool = False
    ):
        """One chunk's outputs, one row per member of ``members`` (then padding rows):
        (statistics, contacts, outcome), and with ``keep`` the batched ``Trajectory``; solved
        by ``settings.engine``. Lockstep: ``_member`` vmapped over the chunk, filled up with
        nominal rows (``batch``). Refill: ``_refilled_chunk`` on ``settings.lanes`` lanes; the
        engine pads the chunk to its shape, and the padding rows are not solved."""
        args = self.arguments(self.mechanism)
        if settings.engine == "refill":
            args = (args, settings.lanes, keep)
            rows = self.values[members]
            concurrent = concurrent_refill(self.mechanism, self.config, bool(self.deviation))
            return map_members(
                _refilled_chunk, args, rows, settings=settings, batched=True, concurrent=concurrent
            )
        fn = _member_replay_of_row if keep else _member_of_row
        return map_members(fn, args, self.batch(members, chunk), settings=settings)

    def batch(self, members: np.ndarray, chunk: int) -> np.ndarray:
        """The rows of one chunk: these members' values, then nominal rows up to ``chunk``."""
        mechanism = self.mechanism
        base = np.asarray([float(np.asarray(get_parameter(mechanism, n))) for n in self.names])
        batch = np.repeat(base[None, :], chunk, axis=0)
        batch[: len(members)] = self.values[members]
        return batch

    def empty_result(self) -> EnsembleResult:
        n = len(self.values)
        return EnsembleResult(
            names=self.names,
            values=self.values,
            statistics={k: np.full(n, np.nan) for k in self.statistic_names},
            status=np.full(n, FAILED, dtype=object),
            messages=[""] * n,
            num_steps=np.zeros(n, dtype=np.int64),
            wall_time_s=np.zeros(n),
        )

    def record(self, result, i, row, stats, contacts, outcome) -> None:
        """Member ``i``'s results from row ``row`` of its chunk's outputs, into ``result``."""
        _record(
            result, i, row, stats, contacts, outcome, self.ts, self.start, self.period,
            self.fraction,
        )  # fmt: skip


def _plan(
    mechanism, values, t1, t0, statistics_start, num_points, solver, deviation, fraction, events
) -> _Plan:
    """Check ``run_ensemble``'s arguments and derive what its chunks need."""
    names, vals = _check_values(mechanism, values)
    if not (0.0 < fraction < 1.0):
        raise EnsembleError(f"continuous_fraction must lie in (0, 1), got {fraction}.")
    start = t0 if statistics_start is None else float(statistics_start)
    if not (t0 <= start < t1):
        raise EnsembleError(f"statistics_start must lie in [t0, t1) = [{t0}, {t1}), got {start}.")
    config = solver_config(solver, mechanism)
    available = signal_names(mechanism)
    if deviation is None:
        deviation = tuple(
            s
            for s in ("slider_a", f"{mechanism.driver.body}_torque" if mechanism.driver else "")
            if s in available
        )
    deviation = tuple(deviation)
    if not mechanism.clearance_joints:
        deviation = ()
    for s in deviation:
        if s not in available:
            raise EnsembleError(
                f"deviation signal {s!r} is unknown; use some of {', '.join(available)}."
            )
    ts = np.linspace(t0, t1, num_points)
    period = None
    if mechanism.driver is not None:
        speed = float(np.asarray(mechanism.driver.constant_speed))
        period = 2.0 * math.pi / abs(speed) if speed else None
    if events is None:
        revolutions = (t1 - t0) / period if period else 1.0
        events = max(256, math.ceil(EVENTS_PER_REVOLUTION * revolutions))
    if int(events) != events or events < 1:
        raise EnsembleError(
            f"contact_events must be a positive integer (room for contacts per joint), got "
            f"{events!r}."
        )
    events = int(events)

    # the statistic names _summary gives (sorted, as a dict out of a jit comes back), without
    # tracing a member's solve and its ideal mechanism's (seconds before every run)
    shape_stats = sorted(
        statistic_names(mechanism)
        + (["torque_fluctuation"] if mechanism.driver is not None else [])
        + [f"{name}_deviation" for name in deviation]
    )
    joints = contact_joints(mechanism)
    return _Plan(
        mechanism=mechanism,
        names=names,
        values=vals,
        config=config,
        deviation=deviation,
        events=events,
        ts=ts,
        t0=float(t0),
        t1=float(t1),
        start=start,
        period=period,
        fraction=float(fraction),
        statistic_names=shape_stats + mode_statistic_names(joints),
        summary_names=tuple(shape_stats),
    )


def _chunk_settings(settings: EnsembleSettings, solvable: int) -> EnsembleSettings:
    """``settings`` for a run of ``solvable`` members (those with admissible values): never pad a
    chunk beyond them (a small run). A resumed run passes the whole run's count, not the members
    left, so that it keeps the run's chunk shape and reuses its compiled program (from the
    compilation store in a new process) instead of compiling one for the members left
    (tests/test_cli_ensemble.py's resume of the last of 4 members took 23.7 s with a chunk of its
    own, 2.0 s with the run's)."""
    if 0 < solvable < chunk_size_of(settings):
        return dataclasses.replace(settings, chunk_size=solvable)
    return settings


def _next_chunk(settings, values, todo, finished, steps, chunk):
    """The members of the next chunk and those left after it (``settings.order``: by expected
    cost from the ``steps`` of the ``finished`` members, or by index)."""
    if settings.order == "cost":
        todo = cost_order(values, todo, np.flatnonzero(finished), steps)
    return todo[:chunk], todo[chunk:]


def run_ensemble(
    mechanism: Mechanism,
    values: Mapping[str, Any],
    t1: float,
    *,
    t0: float = 0.0,
    statistics_start: float | None = None,
    num_points: int = 721,
    solver: "str | SolverConfig" = "auto",
    deviation: Sequence[str] | None = None,
    continuous_fraction: float = DEFAULT_CONTINUOUS_FRACTION,
    contact_events: int | None = None,
    settings: EnsembleSettings = EnsembleSettings(),
    description: Mapping[str, Any] | None = None,
    callback: Callable[[EnsembleResult, np.ndarray], None] | None = None,
) -> EnsembleResult:
    """Solve every member of an ensemble and return its statistics.

    Args:
        mechanism: the base mechanism (concrete values): each member replaces the named
            parameters.
        values: ``{name: (N,) values}``: member i takes ``values[name][i]`` for every name
            (``jaxclear.parameter_names``).
        t1: end time, s. t0: start time, s.
        statistics_start: start of the statistics window, s (default ``t0``): leave out start-up
            revolutions here, as ``jaxclear run --skip-revolutions`` does.
        num_points: output points over [t0, t1] on which deviations, torque fluctuation and
            contact modes are taken (``jaxclear run``'s grid: 360 per revolution + 1); the peak
            statistics come from the solver's steps and do not depend on it.
        solver: as in ``simulate``; ``"auto"`` picks ``recommended_solver(mechanism)``.
        deviation: signals (``jaxclear.signal_names``) whose RMS deviation from the ideal
            mechanism (clearance joints made ideal, same member values) is reported as
            ``<signal>_deviation``; default ``slider_a`` and the input torque where present,
            ``()`` for none (one ideal solve per member less).
        continuous_fraction: contact lasting at least this fraction of the member's crank period
            counts as continuous contact, shorter as an impact (the contact-mode statistics).
        contact_events: room for this many contacts per clearance joint and member (default
            ``EVENTS_PER_REVOLUTION`` per crank revolution of the horizon, at least 256). The
            contacts are located from the solver's steps (``jaxclear.analysis.contact_events``);
            a member with more contacts takes its modes from the output grid instead
            (``contact_modes_located`` 0).
        settings: how the members run and where the results go (``EnsembleSettings``: chunk size,
            devices, member order, output folder ``out`` and its table's name, progress bar);
            none of it is part of the configuration a resumed run must match. With ``out``
            given, the table (one row per finished member) and ``ensemble.json`` are replaced
            atomically after every chunk; a later call with the same arguments resumes from them.
        description: JSON-able description of how the values were made (distributions, seed,
            command): part of the configuration that a resumed run must match.
        callback: ``callback(result_so_far, finished_mask)`` after every chunk.

    Returns:
        An ``EnsembleResult``.

    Raises:
        EnsembleError: bad arguments, or ``out`` holds a run with another configuration.
        ModelError: an unknown parameter name.
    """
    plan = _plan(
        mechanism, values, t1, t0, statistics_start, num_points, solver, deviation,
        continuous_fraction, contact_events,
    )  # fmt: skip
    names, vals, n = plan.names, plan.values, len(plan.values)
    config, deviation, contact_events = plan.config, plan.deviation, plan.events
    start = plan.start
    result = plan.empty_result()
    finished = np.zeros(n, dtype=bool)

    configuration = {
        "format": FORMAT,
        "names": list(names),
        "members": n,
        "t0": t0,
        "t1": t1,
        "statistics_start": start,
        "num_points": num_points,
        "solver": dataclasses.asdict(config),
        "deviation": list(deviation),
        "continuous_fraction": continuous_fraction,
        "contact_events": contact_events,
        "mechanism": mechanism_values(mechanism),
        "description": dict(description or {}),
    }
    out_dir, table_name = settings.out, settings.table_name
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        resume(out_dir, table_name, configuration, result, finished)

    bad = inadmissible_values(mechanism, names, vals)
    for i, why in enumerate(bad):
        if why and not finished[i]:
            result.messages[i] = why
            finished[i] = True

    todo = np.flatnonzero(~finished)
    settings = _chunk_settings(settings, sum(not why for why in bad))
    chunk = chunk_rows(settings)
    bar = progress_bar(settings.progress, n, "members")
    bar.update(int(finished.sum()))
    try:
        while len(todo):
            members, todo = _next_chunk(settings, vals, todo, finished, result.num_steps, chunk)
            started = time.perf_counter()
            stats, pen, outcome = plan.solve(members, chunk, settings)
            missing = set(stats).symmetric_difference(plan.summary_names)
            if missing:  # statistic_names and _summary disagree: a bug, never a user's error
                raise AssertionError(f"statistic names out of step with the summary: {missing}")
            wall = (time.perf_counter() - started) / len(members)
            for row, i in enumerate(members):
                plan.record(result, i, row, stats, pen, outcome)
                result.wall_time_s[i] = wall
            finished[members] = True
            if out_dir is not None:
                save(out_dir, table_name, configuration, result, finished)
            if callback is not None:
                callback(result, finished.copy())
            bar.update(len(members))
    finally:
        bar.close()
    if out_dir is not None:
        save(out_dir, table_name, configuration, result, finished)
    return result


@dataclasses.dataclass
class MemberReplay:
    """One ensemble member solved again by ``replay_member``, with its trajectory.

    Attributes:
        index: the member's index in the ensemble.
        row: its row as in the ensemble's table (``EnsembleResult.rows``: ``index``, drawn values,
            statistics, ``num_steps``, ``status``, ``message``; ``wall_time_s`` is the replayed
            chunk's wall time per member).
        trajectory: its ``Trajectory`` (single, unbatched), from the same compiled batched solve
            as its row. The row's statistics were computed inside that program;
            ``trajectory_statistics`` recomputes them outside it, which may differ in the last
            digits (measured: 1 ulp-level differences in some RMS values).
        chunk: the members solved together with it, in lane order (the chunk is filled up to
            ``chunk_size`` with nominal rows).
        lane: its row within the chunk.
        chunk_size: rows per vectorised solve (the compiled program's batch, before the split
            over devices).
        names: the drawn parameters' names.
        exact_chunk: whether ``chunk`` is the ensemble's own chunk (rebuilt from the member order
            and step counts), or the member alone with nominal rows (``order="cost"`` without
            ``num_steps``; a member's result does not depend on its chunk mates: see
            docs/ensembles.md, "Replaying a member").
        engine: how the chunk was solved again: the ensemble's ``EnsembleSettings.engine``.
            ``"lockstep"``: the vmapped ``simulate`` of the chunk; ``"refill"``: the same
            refill program as the run (``solve_members`` on ``settings.lanes`` lanes, the
            chunk's members in the same order, then the same statistics program), with the
            trajectory built from those solutions by a program of its own.
    """

    index: int
    row: dict[str, Any]
    trajectory: Any
    chunk: list[int]
    lane: int
    chunk_size: int
    names: tuple[str, ...]
    exact_chunk: bool
    engine: str = "lockstep"

    @property
    def statistics(self) -> dict[str, float]:
        """The member's statistics: the row without its index, drawn values and bookkeeping."""
        skip = {"index", "num_steps", "wall_time_s", "status", "message", *self.names}
        return {k: v for k, v in self.row.items() if k not in skip}

    @property
    def trajectory_statistics(self) -> dict[str, float]:
        """``jaxclear.analysis.statistics`` of the trajectory, as floats."""
        return {k: float(v) for k, v in statistics(self.trajectory).items()}


def replay_member(
    mechanism: Mechanism,
    values: Mapping[str, Any],
    t1: float,
    member: int,
    *,
    num_steps: Sequence[int] | np.ndarray | None = None,
    t0: float = 0.0,
    statistics_start: float | None = None,
    num_points: int = 721,
    solver: "str | SolverConfig" = "auto",
    deviation: Sequence[str] | None = None,
    continuous_fraction: float = DEFAULT_CONTINUOUS_FRACTION,
    contact_events: int | None = None,
    settings: EnsembleSettings = EnsembleSettings(),
) -> MemberReplay:
    """Solve one member of an ensemble again, as ``run_ensemble`` solved it, with its trajectory.

    The way to look at an outlier: the member's row says *that* it stands out, its trajectory
    (plots, contacts, ``jaxclear.io.write_results``) shows *why*. A member solved alone by
    ``simulate`` is another compiled program: its rounding differs, and a clearance joint's
    impact sequence amplifies rounding, so its peaks may differ from the row by a factor of 2.
    Here the member is solved by the ensemble's own batched program: the chunk that held it is
    rebuilt (the same ``chunk_size``, devices and member order; with ``order="cost"`` the order
    follows the ensemble's step counts, ``num_steps``) and solved again, and the member's row of
    that chunk is taken. Its statistics equal the ensemble's row bitwise.

    Args:
        mechanism, values, t1: as given to ``run_ensemble`` (``montecarlo``: ``values =
            draw(distributions, samples, seed)``; ``sweep``: ``{name: values}``).
        member: the member's index (its ``index`` in the table).
        num_steps: the ensemble's solver steps per member (``EnsembleResult.num_steps``, the
            table's ``num_steps``). With ``settings.order == "cost"`` they decide the chunks;
            without them the member is solved with nominal rows as chunk mates (the same
            program; its result does not depend on its mates, measured: docs/ensembles.md).
        t0, statistics_start, num_points, solver, deviation, continuous_fraction,
        contact_events: as given to ``run_ensemble``; they must be the same.
        settings: as given to ``run_ensemble`` (``chunk_size``, ``devices``, ``order``,
            ``engine``, ``lanes``; ``out`` and ``progress`` are not used): the chunk size, the
            devices, the engine and its lanes decide the compiled program. A member of a
            ``"refill"`` run is replayed by the refill program with the run's lanes.

    Returns:
        A ``MemberReplay``: the row, the trajectory, the chunk.

    Raises:
        EnsembleError: bad arguments, a member outside the ensemble, or one whose drawn values
            are not admissible (it was never solved).
    """
    plan = _plan(
        mechanism, values, t1, t0, statistics_start, num_points, solver, deviation,
        continuous_fraction, contact_events,
    )  # fmt: skip
    n = len(plan.values)
    if isinstance(member, bool) or not isinstance(member, int | np.integer):
        raise EnsembleError(f"member must be an integer index, got {member!r}.")
    member = int(member)
    if not 0 <= member < n:
        raise EnsembleError(f"member {member} is outside the ensemble: give 0 to {n - 1}.")
    bad = inadmissible_values(mechanism, plan.names, plan.values)
    if bad[member]:
        raise EnsembleError(
            f"member {member} was never solved: {bad[member]}; there is nothing to replay."
        )
    steps = np.zeros(n, dtype=np.int64)
    if num_steps is not None:
        steps = np.asarray(num_steps)
        if steps.shape != (n,):
            raise EnsembleError(
                f"num_steps must hold one step count per member ({n}), got shape {steps.shape}."
            )
        steps = steps.astype(np.int64)
    finished = np.asarray([bool(why) for why in bad])
    todo = np.flatnonzero(~finished)
    settings = _chunk_settings(settings, len(todo))
    chunk = chunk_rows(settings)
    exact = settings.order == "index" or num_steps is not None
    if exact:  # the run's schedule, from its step counts: no solve needed
        while True:
            members, todo = _next_chunk(settings, plan.values, todo, finished, steps, chunk)
            if member in members:
                break
            finished[members] = True
    else:
        members = np.asarray([member])
    lane = int(np.flatnonzero(members == member)[0])
    started = time.perf_counter()
    stats, contacts, outcome, trajectories = plan.solve(members, chunk, settings, keep=True)
    result = plan.empty_result()
    plan.record(result, member, lane, stats, contacts, outcome)
    result.wall_time_s[member] = (time.perf_counter() - started) / len(members)
    return MemberReplay(
        index=member,
        row=result.rows()[member],
        trajectory=jax.tree_util.tree_map(jnp.asarray, trajectories.member(lane)),
        chunk=[int(i) for i in members],
        lane=lane,
        chunk_size=chunk,
        names=plan.names,
        exact_chunk=exact,
        engine=settings.engine,
    )


def mode_statistic_names(joints: Sequence[str]) -> list[str]:
    """Contact-mode statistics of an ensemble member with these clearance joints: per joint
    ``<J>_free_share``, ``<J>_impact_share``, ``<J>_continuous_share`` (time shares over the
    statistics window), ``<J>_impacts``, ``<J>_continuous_contacts`` (counts); per combination of
    all joints' modes ``combination_<label>_share`` (3ⁿ labels such as ``C-I-F``, joints in the
    mechanism's order, ``analysis.combination_label``); ``contact_modes_located`` (1 when the modes
    come from the located contacts, 0 from the output grid after an event-buffer overflow)."""
    if not joints:
        return []
    names = [f"{j}_{MODE_NAMES[m]}_share" for j in joints for m in (FREE, IMPACT, CONTINUOUS)]
    names += [f"{j}_{count}" for j in joints for count in ("impacts", "continuous_contacts")]
    names += [f"combination_{label}_share" for label in all_combinations(len(joints))]
    return names + ["contact_modes_located"]


def _record(result, i, row, stats, contacts, outcome, ts, start, period, fraction):
    code = int(outcome["input_error"][row])
    res = int(outcome["result"][row])
    result.num_steps[i] = int(outcome["num_steps"][row])
    if code:
        result.messages[i] = InputCheck(code).message
        return
    if not bool(outcome["succeeded"][row]):
        result.messages[i] = _result_message(res, float(outcome["t_final"][row]))
        return
    for k, v in stats.items():
        result.statistics[k][i] = float(v[row])
    joints = list(contacts["penetration"])
    if joints:
        if "speed" in outcome and float(outcome["speed"][row]) != 0.0:
            period = 2.0 * math.pi / abs(float(outcome["speed"][row]))  # e.g. rpm swept
        modes = _member_modes(
            contacts, row, joints, ts, start, float(outcome["t_final"][row]), period, fraction
        )
        for k, v in modes.items():
            result.statistics[k][i] = v
    result.status[i] = OK
    result.messages[i] = ""


def _member_modes(contacts, row, joints, ts, start, t_end, period, fraction) -> dict[str, float]:
    """One member's ``mode_statistic_names`` from its located contacts (or, after an overflow of
    the event buffer, from the output grid)."""
    span = period if period is not None else float(ts[-1] - ts[0])
    threshold = fraction * span
    counts = {j: int(contacts["count"][j][row]) for j in joints}
    located = all(counts[j] <= contacts["events"][j].shape[-2] for j in joints)
    if located:
        events = {
            j: located_contacts(
                contacts["events"][j][row],
                counts[j],
                contacts["ongoing"][j][row],
                start,
                t_end,
                threshold,
            )
            for j in joints
        }
    else:  # contacts from the saved grid: runs of positive penetration
        keep = ts >= start
        events = {
            j: grid_contacts(ts[keep], np.asarray(contacts["penetration"][j][row])[keep], threshold)
            for j in joints
        }
    shares = shares_of_contacts(events, joints, start, t_end)
    out: dict[str, float] = {}
    for j in joints:
        share = shares["joints"][j]
        for m in (FREE, IMPACT, CONTINUOUS):
            out[f"{j}_{MODE_NAMES[m]}_share"] = share[MODE_NAMES[m]]
        out[f"{j}_impacts"] = float(share["impacts"])
        out[f"{j}_continuous_contacts"] = float(share["continuous_contacts"])
    for label in all_combinations(len(joints)):
        out[f"combination_{label}_share"] = shares["labels"].get(label, 0.0)
    out["contact_modes_located"] = float(located)
    return out
