"""The vectorised engine: one function of a member's row, evaluated for many rows in chunks.

``map_members`` runs ``fn(v, *args)`` for every row ``v`` of a table of members. The file-backed
ensemble run (``run_ensemble``), bifurcation diagrams (``bifurcation_points``), Lyapunov sweeps
(``lyapunov_sweep``) and identification's global scan all solve their members through it. How
it runs is set by one ``EnsembleSettings``:

- members are solved ``chunk_size`` at a time by one compiled, vmapped call (one compilation per
  chunk size, function and static arguments); a last, partial chunk is padded by repeating its
  last row (on several devices: split evenly, each share padded), so that every chunk has one
  shape; memory grows with the chunk;
- with several local devices (``jax.local_devices()``: GPUs, or CPU cores exposed by
  ``XLA_FLAGS=--xla_force_host_platform_device_count=N``) each chunk is split over the devices:
  every device solves its own share as its own computation, launched from its own thread;
- a vmapped adaptive solve steps all its members until the slowest finishes (lockstep), so a run
  that learns its members' costs as it goes may order the rest by expected cost before it cuts
  the next chunk (``cost_order``, ``EnsembleSettings.order``);
- ``run_ensemble`` may instead solve each chunk on refilled lanes (``EnsembleSettings.engine =
  "refill"``: ``jaxclear.solve.solve_members``, where a lane whose member is done takes the next
  one of the chunk at once), and so does identification's global scan (``FitSettings.scan_engine``);
  ``map_members(..., batched=True)`` then hands each chunk (or each device's share of it) to a
  function of all its rows.

Nothing here reads or writes files.
"""

import collections
import os
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core._errors import EnsembleError
from ..dynamics._equations import UNROLLED_SOLVE_MAX
from ..model import Mechanism, parameter_names
from ..solve._lanes import DEFAULT_LANES
from ..solve._solver import IMPLICIT, SolverConfig
from ..solve._startup import ideal_mechanism

DEFAULT_CHUNK = 64
"""Members per vectorised solve of the ``"lockstep"`` engine (and of ``map_members``' other
users): measured by benchmarks/bench_ensemble.py (see docs/ensembles.md)."""
DEFAULT_CHUNKS = {"lockstep": DEFAULT_CHUNK, "refill": 256}
"""Members per chunk by engine, where ``EnsembleSettings.chunk_size`` is not given. Refilled lanes
idle only at a chunk's end, so larger chunks waste less. A 1000-member case-a Monte Carlo on two
CPU devices (``JAX_COMPILATION_CACHE_DIR=DIR EQX_ON_ERROR=nan python benchmarks/bench_ensemble.py
--case a --devices 2 --montecarlo 1000 --mc-chunk K``, run twice, 2026-11-28): chunks of 64,
44.4 s with empty caches and 32.4 s with the programs loaded from the store; chunks of 256, 42.0
and 29.7 s. Lockstep chunks wait on their slowest member, and 64 was its best size."""
ORDERS = ("cost", "index")
"""Member orders of ``EnsembleSettings.order``."""
ENGINES = ("lockstep", "refill")
"""How ``run_ensemble`` solves a chunk (``EnsembleSettings.engine``): ``"lockstep"``, one vmapped
``simulate`` over the chunk's members (each waits for the slowest); ``"refill"``, the chunk's
members on ``EnsembleSettings.lanes`` lanes refilled as members finish
(``jaxclear.solve.solve_members``)."""


def _device_tuple(devices: Any) -> tuple | None:
    """``devices`` as a tuple (``None`` stays ``None``: all local devices)."""
    if devices is None:
        return None
    try:
        return tuple(devices)
    except TypeError:
        raise EnsembleError(
            f"devices must be a sequence of JAX devices (e.g. jax.local_devices()[:2]), or None "
            f"for all local devices; got {devices!r}."
        ) from None


def _is_whole(size: Any) -> bool:
    return (
        isinstance(size, int | float | np.integer | np.floating)
        and not isinstance(size, bool | np.bool_)
        and bool(np.isfinite(size))
        and bool(int(size) == size)
    )


def _whole(size: Any) -> Any:
    """A whole number (``4``, ``4.0``, ``np.int64(4)``) as an ``int``; anything else unchanged, for
    ``__check_init__`` to refuse."""
    return int(size) if _is_whole(size) else size


def _flag(on: Any) -> bool:
    """A NumPy bool as a Python ``bool``; anything else unchanged, for ``__check_init__``."""
    return bool(on) if isinstance(on, np.bool_) else on


def _folder(out: Any) -> Path | None:
    """``out`` as a ``Path`` (``None`` stays ``None``: nothing is written)."""
    if out is None:
        return None
    if not isinstance(out, str | os.PathLike):
        raise EnsembleError(
            f"out must be a folder (a str or a pathlib.Path), or None to keep nothing on disk; "
            f"got {out!r}."
        )
    return Path(out)


class EnsembleSettings(eqx.Module):
    """How an ensemble's members are run and where its results go (all static).

    None of these is part of the configuration a resumed run must match: a run resumed from
    ``out`` may use other values. ``map_members`` and the
    sweeps built on it (``bifurcation_points``, ``lyapunov_sweep``) use ``chunk_size`` and
    ``devices``; ``run_ensemble`` (and ``montecarlo``, ``sweep``) uses them all.

    Attributes:
        chunk_size: members per vectorised solve (one compilation per chunk size), rounded up to
            a multiple of the devices; memory grows with it. ``None`` (default): the engine's
            (``DEFAULT_CHUNKS``: 256 refilled, 64 lockstep; ``chunk_size_of``). ``run_ensemble``
            pads a last, partial chunk; ``bifurcation_points`` and ``lyapunov_sweep`` lower it
            to their number of values.
        devices: the devices to split each chunk over (a sequence of JAX devices, e.g.
            ``jax.local_devices()[:2]``); ``None``: all local devices.
        order: ``"cost"`` (members of similar expected cost in one chunk, see ``cost_order``)
            or ``"index"`` (member order).
        out: folder to keep the results in (``run_ensemble``: the member table and the manifest
            ``ensemble.json``, replaced after every chunk; a later call with the same arguments
            resumes from them); ``None`` keeps nothing on disk.
        table_name: file name of the member table in ``out``.
        progress: show a progress bar over members.
        engine: how ``run_ensemble`` (``montecarlo``, ``sweep``) and ``bifurcation_points``
            solve a chunk (``ENGINES``):
            ``"refill"`` (default), ``jaxclear.solve.solve_members`` on ``lanes`` lanes, where
            a lane whose member has finished takes the next one of the chunk at once;
            ``"lockstep"``, one vmapped ``simulate`` of its members, which steps them all until
            the slowest one ends (the same per-member results to rounding: docs/ensembles.md,
            "The engine"). Refilling was the faster on one and two CPU devices, cases a and c
            (docs/ensembles.md, "Which engine is faster"). ``map_members``' other users
            (``lyapunov_sweep``, identification's scan) always run lockstep.
        lanes: members integrated at once by the ``"refill"`` engine (default
            ``jaxclear.solve._lanes.DEFAULT_LANES``, the faster of 8 and 32 on one CPU core,
            benchmarks/lane_refill.py); ignored by ``"lockstep"``.

    Raises:
        EnsembleError: a field out of its range, naming the field and what is allowed.
    """

    chunk_size: int | None = eqx.field(static=True, default=None, converter=_whole)
    devices: tuple | None = eqx.field(static=True, default=None, converter=_device_tuple)
    order: str = eqx.field(static=True, default="cost")
    out: Path | None = eqx.field(static=True, default=None, converter=_folder)
    table_name: str = eqx.field(static=True, default="members.csv")
    progress: bool = eqx.field(static=True, default=True, converter=_flag)
    engine: str = eqx.field(static=True, default="refill")
    lanes: int = eqx.field(static=True, default=DEFAULT_LANES, converter=_whole)

    def __check_init__(self):
        size = self.chunk_size
        if size is not None and (not isinstance(size, int) or isinstance(size, bool) or size < 1):
            raise EnsembleError(
                f"chunk_size must be a positive integer (members per vectorised solve), or None "
                f"for the engine's default; got {size!r}."
            )
        if self.devices is not None:
            if not self.devices:
                raise EnsembleError(
                    "devices is empty: give at least one device, or None for all local devices."
                )
            for d in self.devices:
                if not isinstance(d, jax.Device):
                    raise EnsembleError(
                        f"devices must hold JAX devices (e.g. jax.local_devices()[:2]), got {d!r}."
                    )
        if self.order not in ORDERS:
            raise EnsembleError(f"order must be 'cost' or 'index', got {self.order!r}.")
        name = self.table_name
        if not isinstance(name, str) or not name or Path(name).name != name:
            raise EnsembleError(
                f"table_name must be a file name without a folder (the table is written into "
                f"out), e.g. 'members.csv'; got {name!r}."
            )
        if not isinstance(self.progress, bool):
            raise EnsembleError(f"progress must be True or False, got {self.progress!r}.")
        if not isinstance(self.engine, str) or self.engine not in ENGINES:
            raise EnsembleError(
                f"engine must be 'lockstep' or 'refill' (how run_ensemble solves a chunk), got "
                f"{self.engine!r}."
            )
        lanes = self.lanes
        if not isinstance(lanes, int) or isinstance(lanes, bool) or lanes < 1:
            raise EnsembleError(
                f"lanes must be a positive integer (members integrated at once by the 'refill' "
                f"engine), got {lanes!r}."
            )


def _split_devices(devices: Sequence[Any] | None) -> list | None:
    """The devices a chunk is split over: ``devices`` (default all local devices), or ``None``
    when there is only one (no split)."""
    if devices is None:
        devices = jax.local_devices()
    devices = list(devices)
    return devices if len(devices) > 1 else None


def chunk_size_of(settings: EnsembleSettings, engine: str | None = None) -> int:
    """``settings.chunk_size``, or where it is ``None`` the default of ``engine`` (default
    ``settings.engine``; ``DEFAULT_CHUNKS``)."""
    if settings.chunk_size is not None:
        return settings.chunk_size
    return DEFAULT_CHUNKS[engine or settings.engine]


def chunk_size_for(chunk_size: int, devices) -> int:
    """``chunk_size`` rounded up to a multiple of the number of devices."""
    per = len(devices) if devices else 1
    return -(-int(chunk_size) // per) * per


def chunk_rows(settings: EnsembleSettings) -> int:
    """Rows per vectorised call under ``settings``: its ``chunk_size`` rounded up to a multiple of
    the devices it splits a chunk over."""
    return chunk_size_for(chunk_size_of(settings), _split_devices(settings.devices))


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


def concurrent_refill(mechanism: Mechanism, config: SolverConfig, ideal: bool = True) -> bool:
    """Whether the refilled programs of ``mechanism`` solved with ``config`` (and, with
    ``ideal``, of its ideal mechanism: ``run_ensemble``'s deviations) may run at once on several
    devices: their step loops call no LAPACK routine. Each device's share then runs from its
    own thread; otherwise the shares run one after another (``map_members(..., concurrent=)``).

    Two refilled programs of case a run at once on two CPU devices deadlocked, both in LAPACK's
    batched Cholesky (``lapack_dpotrf_ffi``) of the ideal mechanism's 9-row constraint solve,
    each waiting on the shared thread pool (a Monte Carlo of 256 members stopped at 0 % CPU
    until killed, after 300 s and after 90 s; 20.2 s without that call). A loop is free of LAPACK when every constraint solve
    is unrolled (at most ``UNROLLED_SOLVE_MAX`` rows) and the method needs no Newton linear
    solve (the implicit Kvaerno methods factor a Jacobian; the IMEX ones solve their stiff
    part in closed form). The initial assembly's batched LU runs once, before the loop; it has
    not hung (1000 members of case a and of case c, 256 of case a).
    """
    rows = mechanism.num_constraints
    if ideal:
        rows = max(rows, ideal_mechanism(mechanism).num_constraints)
    return rows <= UNROLLED_SOLVE_MAX and config.method not in IMPLICIT


@eqx.filter_jit
def _vmap_chunk(fn, args, values):
    """``fn(v, *args)`` for every row ``v`` of ``values``, vmapped."""
    return jax.vmap(lambda v: fn(v, *args))(values)


def map_members(
    fn: Callable[..., Any],
    args: tuple,
    values,
    *,
    settings: EnsembleSettings = EnsembleSettings(),
    on_chunk: Callable[[int, int], Any] | None = None,
    batched: bool = False,
    concurrent: bool = False,
):
    """Evaluate ``fn(v, *args)`` for every row ``v`` of ``values`` in vectorised chunks.

    The engine's core, shared by ``run_ensemble``, the sweeps and identification's global scan:
    chunks of ``chunk_size_of(settings)`` rows, each one vmapped and split over the devices. A
    last, partial chunk is padded by repeating its last row (on several devices: its rows split
    evenly, each device's share padded so), so that every chunk has one shape and one
    compilation.

    Args:
        fn: a module-level function ``fn(v, *args)`` of one member's row ``v`` (a JAX function:
            it is traced once per chunk shape).
        args: the other arguments (pytrees; arrays are traced, the rest static).
        values: (N, p) rows.
        settings: ``chunk_size`` (rows per vectorised call, rounded up to a multiple of the
            devices) and ``devices`` (to split each chunk over); its other fields are not used
            here.
        on_chunk: ``on_chunk(start, stop)`` after rows ``start:stop`` are done.
        batched: ``fn`` takes a whole chunk (or a device's share of it) instead of one row:
            ``fn(rows, count, *args)`` with ``rows`` (C, p) and ``count`` (a traced int32
            scalar) the number of rows that are members (the rest pad the last chunk, and
            ``fn`` need not solve them); it returns outputs with a leading axis of C. For a
            function that vectorises itself (``run_ensemble``'s refilled chunks).
        concurrent: with ``batched``, the devices' shares run at once (each from its own
            thread, as unbatched shares always do); otherwise one after another. Only for a
            ``fn`` whose loops call no LAPACK routine: two refilled programs with a batched
            LAPACK Cholesky in their step loops, running at once on two CPU devices, deadlocked
            (see ``concurrent_refill``).

    Returns:
        ``fn``'s outputs as NumPy arrays with a leading axis of N.
    """
    values = np.asarray(values, dtype=float)
    devs = _split_devices(settings.devices)
    chunk = chunk_size_for(chunk_size_of(settings, "refill" if batched else "lockstep"), devs)
    per = chunk // len(devs) if devs else chunk
    if batched and not concurrent and devs is not None and len(devs) > 1:
        warnings.warn(
            f"the refilled shares of each chunk run one after another on the {len(devs)} "
            "devices, not at once: this mechanism's step loop would call LAPACK (a constraint "
            "solve of more than UNROLLED_SOLVE_MAX rows, or an implicit Kvaerno method), and "
            "such programs deadlocked when run at once; engine='lockstep' (--engine lockstep) "
            "uses all devices at once",
            stacklevel=3,
        )
    outputs = []
    pending = collections.deque()

    def collect():
        start, counts, parts = pending.popleft()
        got = [jax.device_get(p) for p in parts]
        got = [
            jax.tree_util.tree_map(lambda x, c=c: np.asarray(x)[:c], g) for g, c in zip(got, counts)
        ]
        outputs.append(jax.tree_util.tree_map(lambda *xs: np.concatenate(xs), *got))
        if on_chunk is not None:
            on_chunk(start, start + sum(counts))

    def padded(rows, size):  # rows filled up to size by repeating the last one
        return np.concatenate([rows, np.repeat(rows[-1:], size - len(rows), axis=0)])

    for start in range(0, len(values), chunk):
        part = values[start : start + chunk]
        if devs is None:
            counts = [len(part)]
            if batched:
                count = jnp.asarray(len(part), dtype=jnp.int32)
                parts = [fn(jnp.asarray(padded(part, chunk)), count, *args)]
            else:
                parts = [_vmap_chunk(fn, args, jnp.asarray(padded(part, chunk)))]
        else:
            # each device solves its own share as an independent computation, launched from its
            # own thread (JAX releases the GIL while XLA runs): the devices run at once. (A
            # shard_map over the devices hung for good in some configurations: 12 members
            # drawing rod_mass with the ideal-joint deviation on two CPU devices.) A partial
            # chunk's members are split evenly (232 members on two devices: 116 each, not 128
            # and 104), each share padded to its shape: a device with fewer members would wait.
            counts = [
                len(part) // len(devs) + (k < len(part) % len(devs)) for k in range(len(devs))
            ]
            edges = np.concatenate([[0], np.cumsum(counts)])
            shares = [
                padded(part[edges[k] : edges[k + 1]] if counts[k] else part[-1:], per)
                for k in range(len(devs))
            ]

            def run(k, shares=shares, counts=counts):
                rows = jax.device_put(shares[k], devs[k])
                if batched:
                    count = jnp.asarray(counts[k], dtype=jnp.int32)
                    out = fn(rows, jax.device_put(count, devs[k]), *args)
                else:
                    out = _vmap_chunk(fn, args, rows)
                return jax.block_until_ready(out)

            if batched and not concurrent:
                # one share after another: two refilled programs with LAPACK's batched Cholesky
                # in their step loops, run at once on two CPU devices, deadlocked (both in
                # lapack_dpotrf_ffi, each waiting on the shared thread pool; a Monte Carlo of
                # 1000 case-a members hung with 0 % CPU)
                parts = [run(k) for k in range(len(devs))]
            else:
                with ThreadPoolExecutor(len(devs)) as pool:
                    parts = list(pool.map(run, range(len(devs))))
        pending.append((start, counts, parts))
        if len(pending) > 1:
            collect()
    while pending:
        collect()
    return jax.tree_util.tree_map(lambda *xs: np.concatenate(xs), *outputs)


def cost_order(values: np.ndarray, todo: np.ndarray, done: np.ndarray, steps: np.ndarray):
    """Members of ``todo`` sorted by predicted step count (cheapest first).

    The prediction is a least-squares fit of log(steps) on the drawn values (standardised, with
    squares) over the members solved so far (``done``); until there are more solved members than
    coefficients, ``todo`` keeps its order. Members with similar expected cost then share a chunk,
    which shortens the lockstep wait for the slowest.

    Args:
        values: (N, p) every member's drawn values.
        todo: indices of the members still to solve.
        done: indices of the members finished so far.
        steps: (N,) solver steps per member (0 where not solved).

    Returns:
        ``todo``, reordered.
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
