"""What ``jaxclear montecarlo`` and ``jaxclear sweep`` share: options, devices, the run, the outputs.

Both commands take the mechanism, operating point, horizon and solver from the same config file and
options as ``jaxclear run`` and hand the members to the ensemble engine
(``jaxclear.run_ensemble``): vectorised chunks, split over the local devices, finished members
written after every chunk, resumed when the same command runs again.
"""

import argparse
import csv
import dataclasses
import json
import math
import os
import time
import warnings
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import jaxclear

from ..analysis import DEFAULT_CONTINUOUS_FRACTION
from ..internal import (
    DEFAULT_LANES,
    ENGINES,
    MANIFEST,
    ResumeWarning,
    read_table,
)
from ..io import package_versions, write_json
from ..studies import DEFAULT_CHUNKS, EnsembleError, EnsembleSettings
from ._common import (
    NOT_APPLIED,
    PROG,
    RunError,
    UsageError,
    apply_compilation_cache,
    apply_fast_compile,
    backend_started,
    one_line,
)
from ._config import Settings, resolve_settings
from ._folders import ENSEMBLE_TABLES, claim_output
from ._mechanism_config import build_mechanism
from ._prepare import grid, kept_start, prepare_output, solver_for

DEVICE_COUNT_FLAG = "--xla_force_host_platform_device_count"
"""XLA flag that exposes the CPU as this many JAX devices, each running its own share of a chunk."""

ENSEMBLE_FLAGS = (
    "--chunk-size",
    "--devices",
    "--engine",
    "--lanes",
    "--member",
    "--no-progress",
    "--quiet",
)
"""Options every ensemble command adds (for 'did you mean' hints)."""


def _chunk_size(requested: "int | None", members: int, devices: int, engine: str) -> int:
    """Members per chunk: at most ``requested`` (default: the engine's, ``DEFAULT_CHUNKS``) and
    the members there are, a multiple of the number of devices (each takes an equal share)."""
    requested = DEFAULT_CHUNKS[engine] if requested is None else requested
    return -(-min(requested, members) // devices) * devices


def _engine_options(prepared) -> dict:
    """What an ensemble and the replay of one of its members share besides the members: the time
    window, output grid, solver and contact-mode threshold (the same compiled program)."""
    return dict(
        t0=0.0,
        statistics_start=prepared.statistics_start,
        num_points=prepared.num_points,
        solver=prepared.solver,
        continuous_fraction=prepared.continuous_fraction,
    )


def add_ensemble_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--chunk-size``, ``--devices``, ``--engine``, ``--lanes``, ``--member``,
    ``--no-progress`` and ``--quiet``."""
    parser.add_argument(
        "--chunk-size",
        type=int,
        default=None,
        metavar="K",
        help=f"members per vectorised solve (default {DEFAULT_CHUNKS['refill']} with the refill "
        f"engine, {DEFAULT_CHUNKS['lockstep']} with lockstep, or the number of members if "
        "smaller), rounded up to a multiple of the devices; memory grows with it",
    )
    parser.add_argument(
        "--devices",
        type=int,
        default=None,
        metavar="N",
        help="devices to spread each chunk over (default: every core this process may use, "
        f"exposed to JAX by XLA_FLAGS={DEVICE_COUNT_FLAG}=N on a CPU; every GPU on a GPU host)",
    )
    parser.add_argument(
        "--engine",
        choices=ENGINES,
        default=None,
        help=f"how a chunk is solved (default {EnsembleSettings().engine}; with --member, the "
        "ensemble's own as its JSON summary records it): 'refill', on --lanes lanes where a lane "
        "whose member is done takes the next one at once; 'lockstep', one vectorised solve of "
        "the chunk's members, each waiting for the slowest (see docs/ensembles.md, 'Which "
        "engine is faster')",
    )
    parser.add_argument(
        "--lanes",
        type=int,
        default=None,
        metavar="L",
        help=f"members integrated at once per device by the refill engine (default "
        f"{DEFAULT_LANES}, or with --member the ensemble's own; a GPU wants far more)",
    )
    parser.add_argument(
        "--member",
        type=int,
        default=None,
        metavar="K",
        help="replay member K alone (its index in the table), by the ensemble's own batched "
        "program: write what 'jaxclear run' writes (results.csv, plots, modes.csv, run.json) into "
        "--out DIR/member-K, with statistics bitwise equal to its row; the same command and "
        "options as the ensemble (see docs/ensembles.md, 'Replaying a member')",
    )
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress (a bar on a terminal, a line every 5 s in a log file or pipe)",
    )
    parser.add_argument(
        "--quiet", "-q", action="store_true", help="print nothing but errors (no progress bar)"
    )


def usable_cores() -> int:
    """Cores this process may run on (``os.sched_getaffinity``; ``os.cpu_count`` where absent)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def accelerator_plugins() -> list[str]:
    """Installed JAX plugins for GPUs or TPUs (``jax-cuda12-plugin``, ``jax-rocm...``, ``libtpu``),
    read from the installed distributions without starting JAX's backend."""
    from importlib import metadata

    prefixes = ("jax-cuda", "jax_cuda", "jax-rocm", "jax_rocm", "libtpu")
    names = {(d.metadata["Name"] or "").lower() for d in metadata.distributions()}
    return sorted(n for n in names if n.startswith(prefixes))


def apply_device_count(devices: int | None) -> str:
    """Expose the CPU as several JAX devices: add ``DEVICE_COUNT_FLAG`` to ``XLA_FLAGS``.

    Like ``apply_fast_compile``, this must run before JAX's backend starts (the process's first
    array); called later (``jaxclear.cli.main([...])`` from a process that already computed with
    JAX) it leaves the variable alone (``NOT_APPLIED``), and the devices that exist are used.

    Args:
        devices: the number wanted (``--devices``), or ``None`` for every usable core.

    Returns:
        For the JSON summary: the flag as set, or ``"set by XLA_FLAGS"`` when the user's own
        ``XLA_FLAGS`` already sets it (then it wins), or ``NOT_APPLIED``.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if DEVICE_COUNT_FLAG.lstrip("-") in flags:
        return "set by XLA_FLAGS"
    if backend_started():
        return NOT_APPLIED
    flag = f"{DEVICE_COUNT_FLAG}={devices or usable_cores()}"
    os.environ["XLA_FLAGS"] = f"{flags} {flag}".strip()
    return flag


@dataclasses.dataclass
class Prepared:
    """An ensemble command's checked inputs, before the output folder is made.

    Attributes:
        settings: the resolved settings (as ``jaxclear run``).
        mechanism: the nominal mechanism, assembled.
        t1: end time, s. num_points: output points over [0, t1].
        statistics_start: start of the kept window (after ``skip_revolutions``), s.
        solver: the ``SolverConfig``.
        continuous_fraction: the contact-mode rule: ``[clearance] continuous_fraction`` where
            the config or an option sets it, else the engine's ``DEFAULT_CONTINUOUS_FRACTION``
            (2 % of a crank period; ``jaxclear run``'s default is 5 %).
        fast_compile, device_flag: what was done to ``XLA_FLAGS``.
        compilation_cache: the persistent compilation cache's folder, or ``"off"``.
    """

    settings: Settings
    mechanism: Any
    t1: float
    num_points: int
    statistics_start: float
    solver: Any
    continuous_fraction: float
    fast_compile: str
    device_flag: str
    compilation_cache: str = "off"


def prepare(args: argparse.Namespace, command: str) -> Prepared:
    """Settings, XLA flags, mechanism, horizon and solver of an ensemble command, checked.

    Raises:
        UsageError: bad settings, options or mechanism (exit 2); nothing is written yet.
    """
    settings = resolve_settings(args)
    config = settings.config
    solver_for(settings)  # reject a bad solver name before any work
    if args.chunk_size is not None and args.chunk_size < 1:
        raise UsageError(f"--chunk-size {args.chunk_size}: give 1 or more members per chunk")
    if args.lanes is not None and args.lanes < 1:
        raise UsageError(f"--lanes {args.lanes}: give 1 or more lanes (members at once)")
    if args.devices is not None and args.devices < 1:
        raise UsageError(f"--devices {args.devices}: give 1 or more")
    if args.devices is not None and not accelerator_plugins() and args.devices > usable_cores():
        cores = usable_cores()
        raise UsageError(
            f"--devices {args.devices} is more than the {cores} CPU core{'s' if cores > 1 else ''} "
            f"this process may use (no GPU plugin of JAX is installed); give at most {cores}: "
            "more devices than cores only pads each chunk and runs slower"
        )
    fast_compile = apply_fast_compile(config["solver"]["fast_compile"])  # before JAX starts
    compilation_cache = apply_compilation_cache(config["solver"]["compilation_cache"])
    device_flag = apply_device_count(args.devices)
    mechanism = build_mechanism(settings)
    if config["simulation"]["start"] == "wall" and mechanism.clearance_joints:
        raise UsageError(
            f"{settings.source('simulation', 'start')}: 'wall' is not supported by {command}: the "
            "wall start puts each journal on the wall of the nominal clearance, so members with "
            "another clearance would start off their walls; use --start centred (members start "
            "centred)"
        )
    try:
        jaxclear.assemble(mechanism)
    except jaxclear.AssemblyError as e:
        raise UsageError(f"the mechanism cannot be assembled: {one_line(e)}") from None
    except jaxclear.ModelError as e:
        raise UsageError(f"invalid mechanism: {one_line(e)}") from None
    t1, num_points = grid(settings)
    given = settings.source("clearance", "continuous_fraction") != "default"
    fraction = config["clearance"]["continuous_fraction"] if given else DEFAULT_CONTINUOUS_FRACTION
    return Prepared(
        settings=settings,
        mechanism=mechanism,
        t1=t1,
        num_points=num_points,
        statistics_start=kept_start(settings),
        solver=solver_for(settings, mechanism),
        continuous_fraction=float(fraction),
        fast_compile=fast_compile,
        compilation_cache=compilation_cache,
        device_flag=device_flag,
    )


def local_devices(requested: int | None) -> list:
    """The devices to use: the first ``requested`` local devices (all by default)."""
    import jax

    devices = list(jax.local_devices())
    return devices[:requested] if requested is not None else devices


@dataclasses.dataclass
class Outcome:
    """What one ensemble command did.

    Attributes:
        result: the ``EnsembleResult``.
        out_dir: the output folder.
        settings: the engine's settings as run: ``chunk_size`` (members per vectorised solve, a
            multiple of the devices), ``devices`` (the devices the chunks were spread over),
            ``out``, ``table_name``, ``progress``.
        already_finished: members found finished in ``out_dir`` (resumed), 0 for a fresh run.
        run_now: the other members, handed to the solver by this call (or recorded as failed
            without a solve when their drawn values are inadmissible).
        wall_time_s: wall time of the engine call (compilation included).
    """

    result: Any
    out_dir: Path
    settings: EnsembleSettings
    already_finished: int
    run_now: int
    wall_time_s: float


def _previous(out_dir: Path, table_name: str) -> int:
    """Members a resumed run finds finished in the output folder (0 without a manifest): the
    table's rows, less a torn last row (which the engine drops and solves again)."""
    if not (out_dir / MANIFEST).exists():
        return 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResumeWarning)  # the engine says it
        try:
            return len(read_table(out_dir / table_name, ()))
        except (OSError, UnicodeDecodeError, csv.Error):
            return 0


def run_engine(
    prepared: Prepared,
    args: argparse.Namespace,
    call: Callable[..., Any],
    members: int,
    table_name: str,
    say: Callable[..., None],
) -> Outcome:
    """Make the output folder and run ``call(**engine options)`` (``montecarlo`` or ``sweep``),
    ``settings=`` an ``EnsembleSettings`` among them.

    The chunk is ``--chunk-size``, or ``members`` when there are fewer (the engine pads a chunk
    with nominal members), rounded up to a multiple of the devices.

    Raises:
        UsageError: the folder holds another configuration (the engine's message), or cannot be
            written.
    """
    settings = prepared.settings
    claim_output(settings, ENSEMBLE_TABLES[table_name], say)  # may --out take these results?
    out_dir = prepare_output(settings)  # all input checked: make the folder, prove it writable
    devices = local_devices(args.devices)
    per = len(devices)
    chunk = _chunk_size(args.chunk_size, members, per, args.engine or EnsembleSettings().engine)
    previous = _previous(out_dir, table_name)
    if args.devices is not None and per < args.devices:
        say(
            f"note: {per} device{'s' if per > 1 else ''} available, not {args.devices} (JAX had "
            f"started before {DEVICE_COUNT_FLAG} was set, or XLA_FLAGS sets fewer)"
        )
    quiet = args.quiet
    progress = not (quiet or args.no_progress)  # a bar on a terminal, timed lines in a log
    engine = EnsembleSettings(
        chunk_size=chunk,
        devices=devices,
        out=out_dir,
        table_name=table_name,
        progress=progress,
        engine=args.engine or EnsembleSettings().engine,
        lanes=args.lanes or DEFAULT_LANES,
    )
    say(
        f"{len(devices)} {devices[0].platform.upper()} device{'s' if per > 1 else ''}, "
        f"chunks of {chunk} members; compiling (one-off) and solving ...",
        flush=True,
    )
    started = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ResumeWarning)
            result = call(**_engine_options(prepared), settings=engine)
        for w in caught:  # what resuming set right is said; other warnings go on as they came
            if issubclass(w.category, ResumeWarning):
                say(f"note: {w.message}")
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    except EnsembleError as e:
        raise UsageError(one_line(e)) from None
    except jaxclear.ModelError as e:
        raise UsageError(one_line(e)) from None
    except OSError as e:
        raise RunError(
            f"cannot write results to {str(out_dir)!r}: {e.strerror or e}; choose another --out "
            "folder"
        ) from None
    wall = time.perf_counter() - started
    return Outcome(
        result=result,
        out_dir=out_dir,
        settings=engine,
        already_finished=previous,
        run_now=len(result) - previous,
        wall_time_s=wall,
    )


def base_info(prepared: Prepared, outcome: Outcome, argv: list[str], fmt: int) -> dict[str, Any]:
    """The JSON summary's common part: command, configuration (as run.json), devices, timing."""
    import jax

    settings = prepared.settings
    solver = prepared.solver
    devices = outcome.settings.devices
    assert devices is not None  # run_engine names them
    return {
        "format": fmt,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": [PROG, *argv],
        "config_file": str(Path(settings.config_file).resolve()) if settings.config_file else None,
        "config": settings.config,
        "clearance_per_joint": settings.joint_tables,
        "description": settings.description,
        "sources": {f"{sec}.{key}": src for (sec, key), src in settings.sources.items()},
        "mechanism": settings.mechanism,
        "clearance_joints": [j.name for j in prepared.mechanism.clearance_joints],
        "t_end_s": prepared.t1,
        "num_points": prepared.num_points,
        "kept_window_s": [prepared.statistics_start, prepared.t1],
        "solver": {f.name: getattr(solver, f.name) for f in dataclasses.fields(solver)},
        "continuous_fraction": prepared.continuous_fraction,
        "devices": len(devices),
        "device_kind": devices[0].device_kind,
        "jax_backend": jax.default_backend(),
        "device_flag": prepared.device_flag,
        "fast_compile": prepared.fast_compile,
        "compilation_cache": prepared.compilation_cache,
        "chunk_size": outcome.settings.chunk_size,
        "engine": outcome.settings.engine,
        "lanes": outcome.settings.lanes,
        "already_finished": outcome.already_finished,
        "run_now": outcome.run_now,
        "wall_time_s": outcome.wall_time_s,
        "timing": (
            "wall_time_s: wall time of this call's ensemble solve, compilation included "
            "(members resumed from disk are not solved again); per-member times are in the table"
        ),
    }


def finish(
    outcome: Outcome,
    info: dict[str, Any],
    json_name: str,
    table_name: str,
    kind: str,
    plots: bool,
    say: Callable[..., None],
) -> int:
    """Write the JSON summary and the plots, print the result; 0, or ``RunError`` if all failed."""
    result = outcome.result
    out_dir = outcome.out_dir
    summary = result.summary()
    files = [table_name, json_name]
    ok = summary["succeeded"] > 0
    try:
        if plots and ok:
            from ..plot import save_ensemble_plots

            files += [p.name for p in save_ensemble_plots(result, out_dir, kind=kind)]
        info.update(summary)
        info["files"] = files
        info["versions"] = package_versions()
        write_json(out_dir / json_name, info)
    except OSError as e:
        raise RunError(
            f"cannot write results to {str(out_dir)!r}: {e.strerror or e}; choose another --out "
            "folder"
        ) from None
    if outcome.already_finished:
        say(
            f"resumed from {out_dir}/: {outcome.already_finished} of {len(result)} members were "
            f"already finished, {outcome.run_now} left to solve"
        )
    say(
        f"{summary['succeeded']} of {summary['members']} members succeeded, "
        f"{summary['failed']} failed{f' (see {json_name})' if summary['failed'] else ''}; "
        f"{outcome.wall_time_s:.2f} s{' (compilation included)' if outcome.run_now else ''}"
    )
    for line in summary_lines(result, summary, kind):
        say(line)
    say(f"wrote {', '.join(files)} to {out_dir}/")
    if not ok:
        first = summary["failures"][0]["message"] if summary["failures"] else ""
        raise RunError(
            f"all {summary['members']} members failed (member 0: {first}); see "
            f"{out_dir / json_name}"
        )
    return 0


def _number(value: float) -> str:
    """4 significant digits, without an exponent up to 1e7 (as the plots' legends)."""
    return f"{value:.0f}" if 1e4 <= abs(value) < 1e7 else f"{value:.4g}"


ASCII = str.maketrans({"µ": "u", "²": "^2", "·": " ", "−": "-"})
"""Printed lines stay ASCII (as ``jaxclear run``'s): any terminal encoding can show them."""


def summary_lines(result, summary: dict[str, Any], kind: str = "montecarlo") -> list[str]:
    """One line per main statistic, in the plots' units: for a Monte Carlo the median and the
    5-95 % range; for a sweep the range over the values and where its ends lie."""
    import numpy as np

    from ..plot import main_ensemble_statistics, statistic_axis

    lines = []
    for name in main_ensemble_statistics(result):
        s = summary["statistics"].get(name)
        if s is None:
            continue
        title, unit, scale = statistic_axis(name)
        unit = f" {unit}" if unit else ""
        if kind == "sweep":
            y = np.where(result.succeeded, result.statistics[name], np.nan)
            at = [result.values[int(np.nanargmin(y)), 0], result.values[int(np.nanargmax(y)), 0]]
            line = (
                f"  {title}: {_number(s['min'] * scale)} .. {_number(s['max'] * scale)}{unit} (min at "
                f"{result.names[0]} = {at[0]:.6g}, max at {at[1]:.6g})"
            )
        else:
            line = (
                f"  {title}: median {_number(s['p50'] * scale)}{unit}, 5-95 % "
                f"{_number(s['p5'] * scale)} .. {_number(s['p95'] * scale)}{unit}"
            )
        lines.append(line.translate(ASCII))
    return lines


SUMMARIES = {"montecarlo": "summary.json", "sweep": "sweep.json"}
"""The JSON summary each ensemble command writes when it finishes (it records the engine)."""


def _recorded_engine(args: argparse.Namespace, out_dir: Path, kind: str) -> dict[str, Any]:
    """``engine`` and ``lanes`` for a replay: the options when given, else what the ensemble's
    JSON summary in ``out_dir`` records (summaries written before the option existed, or no
    summary: the defaults)."""
    recorded = {}
    path = out_dir / SUMMARIES[kind]
    if path.is_file():
        try:
            recorded = json.loads(path.read_text())
        except (OSError, ValueError):
            recorded = {}
    engine = args.engine or recorded.get("engine") or EnsembleSettings().engine
    lanes = args.lanes or recorded.get("lanes") or DEFAULT_LANES
    return {"engine": engine, "lanes": int(lanes)}


def member_folder(out_dir: Path, member: int) -> Path:
    """Where ``--member K`` writes its run: ``DIR/member-K`` inside the ensemble's folder."""
    return out_dir / f"member-{member}"


def replay(
    prepared: Prepared,
    args: argparse.Namespace,
    argv: list[str],
    values: dict,
    table_name: str,
    kind: str,
    say: Callable[..., None],
) -> int:
    """``--member K``: solve member K again by the ensemble's batched program and write what
    ``jaxclear run`` writes into ``--out DIR/member-K``.

    The chunk size and devices are those the ensemble command would use (``--chunk-size``,
    ``--devices``); with the ensemble's table in ``--out DIR`` its step counts rebuild the
    member's chunk and its row is compared with the replay's statistics.

    Raises:
        UsageError: K outside the ensemble or never solved (exit 2).
        RunError: the replayed solve failed, or a file cannot be written (exit 1).
    """
    from ..studies import replay_member
    from ._folders import StagedOutput
    from ._run import run_info, write_run_outputs

    member = args.member
    settings = prepared.settings
    n = len(next(iter(values.values())))
    if not 0 <= member < n:
        raise UsageError(f"--member {member}: the ensemble has members 0 to {n - 1}")
    out_dir = Path(settings.config["output"]["directory"])
    table = out_dir / table_name
    rows = []
    if (out_dir / MANIFEST).is_file():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ResumeWarning)
            rows = read_table(table, tuple(values))
    by_index = {int(r["index"]): r for r in rows if r.get("index", "").isdigit()}
    steps = None
    if len(by_index) == n:
        steps = [int(by_index[i].get("num_steps") or 0) for i in range(n)]
    devices = local_devices(args.devices)
    per = len(devices)
    recorded = _recorded_engine(args, out_dir, kind)
    chunk = _chunk_size(args.chunk_size, n, per, recorded.get("engine", EnsembleSettings().engine))
    engine = EnsembleSettings(chunk_size=chunk, devices=devices, progress=False, **recorded)
    target = member_folder(out_dir, member)
    staged = StagedOutput(target, f"--out {str(out_dir)!r}: member folder")
    try:
        say(
            f"replaying member {member} of {n} ({engine.engine} engine, chunks of {chunk} on {per} "
            f"{devices[0].platform.upper()} device{'s' if per > 1 else ''}"
            f"{', chunk rebuilt from ' + str(table) if steps is not None else ''}) ...",
            flush=True,
        )
        started = time.perf_counter()
        try:
            replayed = replay_member(
                prepared.mechanism,
                values,
                prepared.t1,
                member,
                num_steps=steps,
                **_engine_options(prepared),
                settings=engine,
            )
        except EnsembleError as e:
            raise UsageError(f"--member {member}: {one_line(e)}") from None
        wall = time.perf_counter() - started
        row = replayed.row
        if row["status"] != "ok":
            raise RunError(f"member {member} failed again, as in the ensemble: {row['message']}")
        traj = replayed.trajectory
        from ..analysis import statistics as trajectory_statistics

        statistics = {k: float(row[k]) for k in trajectory_statistics(traj)}
        info = run_info(
            settings,
            argv,
            prepared.mechanism,
            prepared.solver,
            traj,
            prepared.t1,
            prepared.num_points,
            prepared.statistics_start,
            compile_time=float("nan"),
            run_time=wall,
            fast_compile=prepared.fast_compile,
            compilation_cache=prepared.compilation_cache,
        )
        info["timing"] = (
            "run_time_s: wall time of the replayed chunk's batched solve, compilation included; "
            "compile_time_s is not measured apart (NaN)"
        )
        info["member"] = {
            "kind": kind,
            "index": member,
            "values": {name: float(row[name]) for name in replayed.names},
            "ensemble_statistics": replayed.statistics,
            "num_steps": int(row["num_steps"]),
            "chunk": replayed.chunk,
            "lane": replayed.lane,
            "chunk_size": replayed.chunk_size,
            "engine": engine.engine,
            "lanes": engine.lanes,
            "devices": per,
            "exact_chunk": replayed.exact_chunk,
            "note": (
                "solved by the ensemble's batched program (same chunk size and devices), so the "
                "statistics equal the member's row bitwise; run.json's statistics are the row's"
            ),
        }
        from ..solve import ideal_mechanism

        ideal = ideal_mechanism(
            jaxclear.with_parameters(prepared.mechanism, info["member"]["values"])
        )
        speed = abs(float(traj.mechanism.driver.constant_speed)) if traj.mechanism.driver else 0.0
        period = 2.0 * math.pi / speed if speed else prepared.t1
        try:
            paths, files = write_run_outputs(
                traj,
                staged,
                info,
                statistics,
                ideal,
                prepared.t1,
                prepared.num_points,
                prepared.statistics_start,
                prepared.continuous_fraction,
                plots=settings.config["output"]["plots"],
                period=period,
                say=say,
            )
        except OSError as e:
            raise RunError(
                f"cannot write results to {str(target)!r}: {e.strerror or e}; choose another --out "
                "folder"
            ) from None
    finally:
        staged.discard()
    say(f"member {member}: {int(row['num_steps'])} steps, {wall:.2f} s (compilation included)")
    if member in by_index:
        old = by_index[member]
        differ = [k for k, v in replayed.statistics.items() if k in old and repr(v) != old[k]]
        if differ:
            say(
                f"note: {len(differ)} statistics differ from row {member} of {table} "
                f"({', '.join(differ[:4])}): the ensemble ran with other settings (chunk size, "
                "devices, engine, solver, ...) than this command"
            )
        else:
            say(f"statistics bitwise equal to row {member} of {table}")
    say(f"wrote {', '.join(sorted([p.name for p in paths.values()] + files))} to {target}/")
    return 0
