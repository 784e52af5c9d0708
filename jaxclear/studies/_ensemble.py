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
  (``map_members``, ``jaxclear.studies._engine``);
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
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core._errors import EnsembleError, InputCheck
from .._core._progress import progress_bar
from ..analysis._modes import (
    CONTINUOUS,
    DEFAULT_CONTINUOUS_FRACTION,
    FREE,
    IMPACT,
    MODE_NAMES,
    all_combinations,
    grid_contacts,
    located_contacts,
    shares_of_contacts,
)
from ..analysis._signals import signal_names, signals
from ..analysis._statistics import statistics
from ..model import Mechanism, get_parameter, parameter_info, with_parameters
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, solver_config
from ..solve._startup import ideal_mechanism
from ._engine import EnsembleSettings, chunk_rows, cost_order, map_members
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


def _member(mechanism, names, config, ideal_config, deviation, events, v, ts, t0, t1, start):
    """One member: its statistics, its contacts (located events, and penetrations on the grid in
    case the event buffer overflows), outcome."""
    m = with_parameters(mechanism, {n: v[k] for k, n in enumerate(names)})
    traj = simulate(
        m,
        t1,
        t0=t0,
        ts=ts,
        solver=config,
        statistics_start=start,
        throw=False,
        contact_events=events if mechanism.clearance_joints else 0,
    )
    stats = dict(statistics(traj))
    if mechanism.driver is not None:
        tau = traj.input_torque
        stats["torque_fluctuation"] = _window_rms(ts, tau - _window_mean(ts, tau, start), start)
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
        mine, theirs = signals(traj, deviation), signals(ideal, deviation)
        for name in deviation:
            stats[f"{name}_deviation"] = _window_rms(ts, mine[name] - theirs[name], start)
    contacts = {"penetration": {j: traj.clearance[j]["penetration"] for j in traj.clearance}}
    if mechanism.clearance_joints:
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
    return stats, contacts, outcome


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
    names, vals = _check_values(mechanism, values)
    n = len(vals)
    if not (0.0 < continuous_fraction < 1.0):
        raise EnsembleError(f"continuous_fraction must lie in (0, 1), got {continuous_fraction}.")
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
    if contact_events is None:
        revolutions = (t1 - t0) / period if period else 1.0
        contact_events = max(256, math.ceil(EVENTS_PER_REVOLUTION * revolutions))
    if int(contact_events) != contact_events or contact_events < 1:
        raise EnsembleError(
            f"contact_events must be a positive integer (room for contacts per joint), got "
            f"{contact_events!r}."
        )
    contact_events = int(contact_events)

    # statistic names, from an abstract evaluation of one member
    shape_stats, _, _ = eqx.filter_eval_shape(
        _member,
        mechanism,
        names,
        config,
        solver_config("fast"),
        deviation,
        contact_events,
        jnp.asarray(vals[0]),
        jnp.asarray(ts),
        jnp.asarray(t0),
        jnp.asarray(t1),
        jnp.asarray(start),
    )
    joints = [j.name for j in mechanism.clearance_joints]
    stat_names = list(shape_stats) + mode_statistic_names(joints)
    result = EnsembleResult(
        names=names,
        values=vals,
        statistics={k: np.full(n, np.nan) for k in stat_names},
        status=np.full(n, FAILED, dtype=object),
        messages=[""] * n,
        num_steps=np.zeros(n, dtype=np.int64),
        wall_time_s=np.zeros(n),
    )
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
    base = np.asarray([float(np.asarray(get_parameter(mechanism, nm))) for nm in names])

    ideal_config = solver_config("fast")
    todo = np.flatnonzero(~finished)
    if 0 < len(todo) < settings.chunk_size:
        # never pad a chunk beyond the members left (a small run, or a resumed one)
        settings = dataclasses.replace(settings, chunk_size=len(todo))
    chunk = chunk_rows(settings)
    bar = progress_bar(settings.progress, n, "members")
    bar.update(int(finished.sum()))
    try:
        while len(todo):
            if settings.order == "cost":
                todo = cost_order(vals, todo, np.flatnonzero(finished), result.num_steps)
            members, todo = todo[:chunk], todo[chunk:]
            batch = np.repeat(base[None, :], chunk, axis=0)
            batch[: len(members)] = vals[members]
            started = time.perf_counter()
            stats, pen, outcome = map_members(
                _member_of_row,
                (
                    mechanism,
                    names,
                    config,
                    ideal_config,
                    deviation,
                    contact_events,
                    jnp.asarray(ts),
                    jnp.asarray(t0, dtype=float),
                    jnp.asarray(t1, dtype=float),
                    jnp.asarray(start, dtype=float),
                ),
                batch,
                settings=settings,
            )
            wall = (time.perf_counter() - started) / len(members)
            for row, i in enumerate(members):
                _record(result, i, row, stats, pen, outcome, ts, start, period, continuous_fraction)
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
