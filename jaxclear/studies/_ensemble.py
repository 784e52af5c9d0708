"""The ensemble engine: many members of one mechanism topology, solved in vectorised chunks.

Monte Carlo over tolerances (``montecarlo``), parameter sweeps (``sweep``) and the commands built on
them run through ``run_ensemble``. A member is the mechanism with some named parameters
(``jaxclear.parameter_names``) replaced; its result is the ``statistics`` of ``jaxclear run``
(same names, from the solver's steps), the RMS deviation of chosen signals from the ideal
mechanism, per-joint contact-mode shares and counts and the shares of the 3ⁿ combinations (from
contacts located from the solver's steps), the solver's step count and its share of the chunk's
wall time.

How it runs:
- members are solved ``chunk_size`` at a time by one compiled, vmapped solve (one compilation per
  chunk size, topology and settings); memory grows with the chunk;
- with several local devices (``jax.local_devices()``: GPUs, or CPU cores exposed by
  ``XLA_FLAGS=--xla_force_host_platform_device_count=N``) each chunk is split over the devices:
  every device solves its own share as its own computation, launched from its own thread;
- a vmapped solve steps all its members until the slowest finishes (lockstep), so members are
  ordered by expected cost before they are chunked (``order="cost"``: the step counts of the
  members solved so far, regressed on the drawn values; see ``_cost_order``);
- with ``out`` given, finished members are written after every chunk (atomic replace of the CSV
  and of a JSON manifest); called again with the same arguments it resumes, solving only the
  members not yet on disk, and refuses a changed configuration;
- a member whose solve fails, or whose drawn values are not admissible, is recorded with its
  message, its statistics are NaN, and the others go on.
"""

import collections
import concurrent.futures
import csv
import dataclasses
import hashlib
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import diffrax
import equinox as eqx
import jax
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
from ..io import atomic_write, write_json
from ..model import Mechanism, parameter_info, parameter_names, with_parameters
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, solver_config
from ..solve._startup import ideal_mechanism

DEFAULT_CHUNK = 64
"""Members per vectorised solve: measured by benchmarks/bench_ensemble.py (see docs/ensembles.md)."""
MANIFEST = "ensemble.json"
OK, FAILED = "ok", "failed"
NON_NEGATIVE = frozenset({"friction_coefficient", "viscous_friction", "damping", "free_length"})
"""Fields whose admissible range includes its lower bound 0 (``ParameterInfo.domain`` is open)."""
FORMAT = 2  # 2: contact modes from located events, counts and combination shares
EVENTS_PER_REVOLUTION = 128
"""Default room for contacts per clearance joint and crank revolution (at least 256 in all), here
and in ``jaxclear run``: the default run has 3–7 contacts per joint and revolution; where the
buffer overflows, the modes come from the saved grid (``grid_contacts``)."""


@dataclasses.dataclass
class EnsembleResult:
    """Per-member results of ``run_ensemble``, in member order.

    Attributes:
        names: the drawn parameters' names (``B.clearance``, ``rod_mass``, ...).
        values: (N, len(names)) drawn values, SI units.
        statistics: {name: (N,) values}, NaN where the member failed. Names: those of
            ``jaxclear.analysis.statistics`` (``B_peak_normal_force``, ``crank_torque_rms``, ...),
            ``<signal>_deviation`` (RMS deviation from the ideal mechanism over the statistics
            window), ``torque_fluctuation`` (RMS of the input torque about its mean), and the
            contact modes over the statistics window from the contacts located from the solver's
            steps (``mode_statistic_names``: per joint ``<J>_free_share``, ``<J>_impact_share``,
            ``<J>_continuous_share``, ``<J>_impacts``, ``<J>_continuous_contacts``; per
            combination ``combination_C-I-F_share`` and so on).
        status: (N,) ``"ok"`` or ``"failed"``.
        messages: (N,) why a member failed (``""`` if it did not).
        num_steps: (N,) solver steps (0 for members not solved).
        wall_time_s: (N,) the wall time of the member's chunk divided by its members.
    """

    names: tuple[str, ...]
    values: np.ndarray
    statistics: dict[str, np.ndarray]
    status: np.ndarray
    messages: list[str]
    num_steps: np.ndarray
    wall_time_s: np.ndarray

    @property
    def succeeded(self) -> np.ndarray:
        return self.status == OK

    def __len__(self) -> int:
        return len(self.status)

    def rows(self) -> list[dict[str, Any]]:
        """One dict per member: ``index``, drawn values, statistics, steps, time, status, message."""
        rows = []
        for i in range(len(self)):
            row: dict[str, Any] = {"index": i}
            row.update({n: float(self.values[i, k]) for k, n in enumerate(self.names)})
            row.update({k: float(v[i]) for k, v in self.statistics.items()})
            row.update(
                num_steps=int(self.num_steps[i]),
                wall_time_s=float(self.wall_time_s[i]),
                status=str(self.status[i]),
                message=self.messages[i],
            )
            rows.append(row)
        return rows

    def summary(self) -> dict[str, Any]:
        """Over the members that succeeded: percentiles 5/50/95, mean and its standard error, min,
        max of each statistic; counts and the failures' messages."""
        ok = self.succeeded
        out: dict[str, Any] = {
            "members": len(self),
            "succeeded": int(ok.sum()),
            "failed": int((~ok).sum()),
            "failures": [
                {"index": int(i), "message": self.messages[i]} for i in np.flatnonzero(~ok)
            ],
            "statistics": {},
        }
        for name, v in self.statistics.items():
            x = v[ok]
            x = x[np.isfinite(x)]
            if x.size == 0:
                continue
            p5, p50, p95 = np.percentile(x, [5, 50, 95])
            out["statistics"][name] = {
                "mean": float(x.mean()),
                "standard_error": float(x.std(ddof=1) / math.sqrt(x.size)) if x.size > 1 else None,
                "p5": float(p5),
                "p50": float(p50),
                "p95": float(p95),
                "min": float(x.min()),
                "max": float(x.max()),
                "count": int(x.size),
            }
        return out


# --- the compiled chunk ---------------------------------------------------------------------------


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


@eqx.filter_jit
def _vmap_chunk(fn, args, values):
    """``fn(v, *args)`` for every row ``v`` of ``values``, vmapped."""
    return jax.vmap(lambda v: fn(v, *args))(values)


def chunk_size_for(chunk_size: int, devices) -> int:
    """``chunk_size`` rounded up to a multiple of the number of devices."""
    per = len(devices) if devices else 1
    return -(-int(chunk_size) // per) * per


def swept_values(mechanism: Mechanism, name: str, values) -> np.ndarray:
    """Check a one-parameter sweep's arguments (``bifurcation_points``, ``lyapunov_sweep``): a
    known parameter name and a non-empty 1-D array of finite values, returned as floats.

    Raises:
        ValueError: naming the parameter and what is allowed.
    """
    known = parameter_names(mechanism)
    if name not in known:
        raise ValueError(
            f"name {name!r} is not a parameter of this mechanism; choose among {known}."
        )
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size == 0 or not np.all(np.isfinite(values)):
        raise ValueError(f"values must be a non-empty 1-D array of finite numbers, got {values!r}.")
    return values


def map_members(
    fn: Callable[..., Any],
    args: tuple,
    values,
    *,
    chunk_size: int = DEFAULT_CHUNK,
    devices: Sequence[Any] | None = None,
    on_chunk: Callable[[int, int], Any] | None = None,
):
    """Evaluate ``fn(v, *args)`` for every row ``v`` of ``values`` in vectorised chunks.

    The engine's core, shared by ``run_ensemble`` and identification's global scan: chunks of
    ``chunk_size`` rows (the last one padded by repeating its last row, so that every chunk has
    one shape and one compilation), each one vmapped and split over the local devices.

    Args:
        fn: a module-level function ``fn(v, *args)`` of one member's row ``v`` (a JAX function:
            it is traced once per chunk shape).
        args: the other arguments (pytrees; arrays are traced, the rest static).
        values: (N, p) rows.
        chunk_size: rows per vectorised call (rounded up to a multiple of the devices).
        devices: devices to split each chunk over (default all local devices).
        on_chunk: ``on_chunk(start, stop)`` after rows ``start:stop`` are done.

    Returns:
        ``fn``'s outputs as NumPy arrays with a leading axis of N.
    """
    values = np.asarray(values, dtype=float)
    devs = _devices(devices)
    chunk = chunk_size_for(chunk_size, devs)
    per = chunk // len(devs) if devs else chunk
    outputs = []
    pending = collections.deque()

    def collect():
        start, count, parts = pending.popleft()
        got = [jax.device_get(p) for p in parts]
        out = jax.tree_util.tree_map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *got)
        outputs.append(jax.tree_util.tree_map(lambda x: x[:count], out))
        if on_chunk is not None:
            on_chunk(start, start + count)

    for start in range(0, len(values), chunk):
        part = values[start : start + chunk]
        padded = np.concatenate([part, np.repeat(part[-1:], chunk - len(part), axis=0)])
        if devs is None:
            parts = [_vmap_chunk(fn, args, jnp.asarray(padded))]
        else:
            # each device solves its own share as an independent computation, launched from its
            # own thread (JAX releases the GIL while XLA runs): the devices run at once. (A
            # shard_map over the devices hung for good in some configurations: 12 members
            # drawing rod_mass with the ideal-joint deviation on two CPU devices.)
            shares = [padded[k * per : (k + 1) * per] for k in range(len(devs))]

            def run(k, shares=shares):
                out = _vmap_chunk(fn, args, jax.device_put(shares[k], devs[k]))
                return jax.block_until_ready(out)

            with concurrent.futures.ThreadPoolExecutor(len(devs)) as pool:
                parts = list(pool.map(run, range(len(devs))))
        pending.append((start, len(part), parts))
        if len(pending) > 1:
            collect()
    while pending:
        collect()
    return jax.tree_util.tree_map(lambda *xs: np.concatenate(xs), *outputs)


# --- ordering by expected cost --------------------------------------------------------------------


def _cost_order(values: np.ndarray, todo: np.ndarray, done: np.ndarray, steps: np.ndarray):
    """Members of ``todo`` sorted by predicted step count (cheapest first).

    The prediction is a least-squares fit of log(steps) on the drawn values (standardised, with
    squares) over the members solved so far (``done``); until there are more solved members than
    coefficients, ``todo`` keeps its order. Members with similar expected cost then share a chunk,
    which shortens the lockstep wait for the slowest.
    """

    def features(x):
        z = (x - mean) / scale
        return np.concatenate([np.ones((len(x), 1)), z, z**2], axis=1)

    mean = values.mean(axis=0)
    scale = values.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    usable = done[steps[done] > 0]
    if len(todo) == 0 or len(usable) <= 1 + 2 * values.shape[1]:
        return todo
    coef, *_ = np.linalg.lstsq(features(values[usable]), np.log(steps[usable]), rcond=None)
    predicted = features(values[todo]) @ coef
    return todo[np.argsort(predicted, kind="stable")]


# --- storage ---------------------------------------------------------------------------------------


def fingerprint(description: Mapping[str, Any]) -> str:
    """A short hash of a JSON-able description of an ensemble (its configuration)."""
    text = json.dumps(description, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _differences(old: Mapping, new: Mapping, prefix="") -> list[str]:
    keys = sorted(set(old) | set(new))
    out = []
    for k in keys:
        a, b = old.get(k), new.get(k)
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            out += _differences(a, b, f"{prefix}{k}.")
        elif json.dumps(a, default=str) != json.dumps(b, default=str):
            out.append(f"{prefix}{k}")
    return out


def _write_table(path: Path, result: EnsembleResult, finished: np.ndarray) -> None:
    rows = [r for r, f in zip(result.rows(), finished) if f]
    fields = list(result.rows()[0]) if len(result) else ["index"]

    def write(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            for r in rows:
                w.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})

    atomic_write(path, write)


def _read_table(path: Path, names: Sequence[str]) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if rows and not set(names) <= set(rows[0]):
        return []
    return rows


# --- the engine ------------------------------------------------------------------------------------


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


def _inadmissible(mechanism: Mechanism, names, values: np.ndarray) -> list[str]:
    """Per member, why its drawn values cannot be simulated ("" if they can)."""
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


def _devices(devices) -> list | None:
    if devices is None:
        devices = jax.local_devices()
    devices = list(devices)
    return devices if len(devices) > 1 else None


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
    chunk_size: int = DEFAULT_CHUNK,
    order: str = "cost",
    devices: Sequence[Any] | None = None,
    out: "str | Path | None" = None,
    table_name: str = "members.csv",
    description: Mapping[str, Any] | None = None,
    progress: bool = True,
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
        chunk_size: members per vectorised solve (rounded up to a multiple of the devices).
        order: ``"cost"`` (similar expected cost in one chunk, see the module docstring) or
            ``"index"`` (member order).
        devices: the devices to spread each chunk over (default all local devices).
        out: folder to keep results in: ``table_name`` (one row per finished member) and
            ``ensemble.json`` are replaced atomically after every chunk; a later call with the
            same arguments resumes from them.
        table_name: file name of the table in ``out``.
        description: JSON-able description of how the values were made (distributions, seed,
            command): part of the configuration that a resumed run must match.
        progress: show a progress bar over members.
        callback: ``callback(result_so_far, finished_mask)`` after every chunk.

    Returns:
        An ``EnsembleResult``.

    Raises:
        EnsembleError: bad arguments, or ``out`` holds a run with another configuration.
        ModelError: an unknown parameter name.
    """
    names, vals = _check_values(mechanism, values)
    n = len(vals)
    if chunk_size < 1:
        raise EnsembleError(f"chunk_size must be a positive integer, got {chunk_size}.")
    if order not in ("cost", "index"):
        raise EnsembleError(f"order must be 'cost' or 'index', got {order!r}.")
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
    devs = _devices(devices)
    chunk = chunk_size_for(chunk_size, devs)
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

    settings = {
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
        "mechanism": _mechanism_values(mechanism),
        "description": dict(description or {}),
    }
    out_dir = Path(out) if out is not None else None
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        _resume(out_dir, table_name, settings, result, finished)

    bad = _inadmissible(mechanism, names, vals)
    for i, why in enumerate(bad):
        if why and not finished[i]:
            result.messages[i] = why
            finished[i] = True
    base = np.asarray([float(np.asarray(_get(mechanism, nm))) for nm in names])

    ideal_config = solver_config("fast")
    todo = np.flatnonzero(~finished)
    bar = progress_bar(progress, n, "members")
    bar.update(int(finished.sum()))
    try:
        while len(todo):
            if order == "cost":
                todo = _cost_order(vals, todo, np.flatnonzero(finished), result.num_steps)
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
                chunk_size=chunk,
                devices=devices,
            )
            wall = (time.perf_counter() - started) / len(members)
            for row, i in enumerate(members):
                _record(result, i, row, stats, pen, outcome, ts, start, period, continuous_fraction)
                result.wall_time_s[i] = wall
            finished[members] = True
            if out_dir is not None:
                _save(out_dir, table_name, settings, result, finished)
            if callback is not None:
                callback(result, finished.copy())
            bar.update(len(members))
    finally:
        bar.close()
    if out_dir is not None:
        _save(out_dir, table_name, settings, result, finished)
    return result


def _get(mechanism, name):
    from ..model import get_parameter

    return get_parameter(mechanism, name)


def _mechanism_values(mechanism: Mechanism) -> dict[str, Any]:
    """The base mechanism as JSON-able values: its parameters by name and its structure."""
    from ..model import parameter_names

    out: dict[str, Any] = {}
    for name in parameter_names(mechanism):
        try:
            out[name] = float(np.asarray(_get(mechanism, name)))
        except (TypeError, ValueError):  # a non-scalar parameter: its repr decides
            out[name] = repr(np.asarray(_get(mechanism, name)).tolist())
    out["laws"] = {
        j.name: [type(j.contact_law).__name__, type(j.friction_law).__name__]
        for j in mechanism.clearance_joints
    }
    out["bodies"] = list(mechanism.body_names)
    return out


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


def _save(out_dir: Path, table_name: str, settings, result: EnsembleResult, finished) -> None:
    _write_table(out_dir / table_name, result, finished)
    write_json(
        out_dir / MANIFEST,
        {
            "settings": settings,
            "fingerprint": fingerprint(settings),
            "finished": int(finished.sum()),
            "failed": int((finished & (result.status != OK)).sum()),
            "table": table_name,
        },
    )


def _resume(out_dir: Path, table_name: str, settings, result: EnsembleResult, finished) -> None:
    manifest = out_dir / MANIFEST
    if not manifest.exists():
        return
    try:
        old = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        raise EnsembleError(
            f"{manifest} cannot be read ({e}); remove it or choose another output folder."
        ) from None
    if old.get("fingerprint") != fingerprint(settings):
        changed = _differences(
            old.get("settings", {}), json.loads(json.dumps(settings, default=str))
        )
        raise EnsembleError(
            f"{out_dir} holds an ensemble with another configuration (changed: "
            f"{', '.join(changed[:6]) or 'format'}); resume with the same settings, or choose "
            "another output folder."
        )
    for row in _read_table(out_dir / table_name, result.names):
        i = int(row["index"])
        if not (0 <= i < len(result)):
            continue
        drawn = np.asarray([float(row[nm]) for nm in result.names])
        if not np.array_equal(drawn, result.values[i]):
            raise EnsembleError(
                f"{out_dir / table_name}: member {i} has other drawn values than this run "
                "would draw; resume with the same settings and seed, or choose another folder."
            )
        for k in result.statistics:
            if k in row and row[k] != "":
                result.statistics[k][i] = float(row[k])
        result.status[i] = row.get("status", FAILED)
        result.messages[i] = row.get("message", "")
        result.num_steps[i] = int(row.get("num_steps", 0) or 0)
        result.wall_time_s[i] = float(row.get("wall_time_s", 0.0) or 0.0)
        finished[i] = True
