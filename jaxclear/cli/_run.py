"""``jaxclear run [CONFIG.toml]``: simulate one mechanism and write results and plots."""

import argparse
import dataclasses
import math
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import jax
import numpy as np

import jaxclear

from .._core._progress import progress_bar
from ..analysis import contact_joints
from ..contact import CONTACT_LAWS
from ..friction import FRICTION_LAWS
from ..internal import EVENTS_PER_REVOLUTION
from ..io import (
    RUN_FORMAT,
    RUN_JSON_NAME,
    clearance_joint_names,
    mode_shares,
    package_versions,
    run_statistics,
    write_json,
    write_modes_csv,
    write_results,
    write_revolutions_csv,
)
from ..mechanisms import is_slider_crank
from ..solve import finite_rows, ideal_mechanism, wall_start, window
from ..studies import compile_revolutions, simulate_revolutions
from ..studies._revolutions import (
    COMPANION_PERTURBATION,
    MAX_REVOLUTIONS,
    SENSITIVE_SPREAD,
    segment_points,
)
from ._common import (
    PROG,
    RunError,
    UsageError,
    apply_compilation_cache,
    apply_fast_compile,
    one_line,
)
from ._config import Settings, resolve_settings
from ._folders import StagedOutput, claim_output
from ._mechanism_config import build_mechanism
from ._prepare import grid, kept_start, solver_for
from ._settings import (
    AUTO,
    add_setting_arguments,
    config_reference,
)

MODES_CSV = "modes.csv"
REVOLUTIONS_CSV = "revolutions.csv"

MAX_SPREAD = 64
"""Most ``--spread`` companions. They are one vectorised batch stepped together, so a revolution
costs about K + 1 solves and K times the memory of the nominal's results; the spread's min/max
over tens of companions already shows whether a figure forks (docs/outputs.md)."""
WARMUP_FRACTION = 1e-3
"""The warm-up (compile) call integrates this fraction of the horizon; see ``timed_revolutions``."""

DESCRIPTION = """\
Simulate a planar mechanism with revolute clearance joints and write results.csv, results.npz,
run.json and PNG plots into --out DIR. The mechanism is the benchmark slider-crank (default), the
four-bar (--mechanism four_bar), or any mechanism described in CONFIG.toml (bodies, points, joints,
driver, springs, loads; see docs/cli.md).

Defaults: slider-crank at 5000 rpm with clearance joints O, A, B (c = 0.5 mm, hybrid contact law,
LuGre friction), revolutions auto (one solve per revolution until the response settles into a
period-k orbit, at most 12; '--revolutions 2' for a fixed horizon), 360 points per revolution, no
gravity, solver 'auto' (imex with LuGre friction, else fast; measured fastest here).
'--clearance-joints none' gives ideal joints.

Start-up: by default journals start centred (--start centred) and the revolutions before the
response settles are left out of the plots and statistics (with a fixed horizon: the first
revolution, --skip-revolutions 1). Why: a centred journal flies free across
the clearance and hits the wall with a start-up impact about ten times larger than anything in the
running motion; that transient would set the y-ranges of every plot and the peaks of the
statistics. '--start wall' puts each journal on its wall along the ideal joint's reaction instead,
with no hysteresis damping until it first leaves the wall (impact-velocity memory 1000 m/s; about
40 % fewer solver steps than the default run; see docs/cli.md, "Start-up", and docs/model.md
§5c). '--skip-revolutions 0' keeps every revolution."""

EPILOG = f"""\
config file (TOML; every key optional; command-line options override it):
{config_reference()}

  per-joint clearance tables [clearance.<joint>] take the keys marked 'also per joint' plus
  journal_body and lubrication (a hydrodynamic film: lubrication = {{ viscosity = 0.4,
  length = 0.01, theory = "short" }}; docs/cli.md), and override the shared [clearance] values
  for that joint. A custom mechanism is
  described by [ground.points], [bodies.<name>], [joints.<name>], [driver], [springs.<name>] and
  [loads.<name>] tables: see docs/cli.md and examples/custom_mechanism.toml.

example config:
  [mechanism]
  rpm = 3000
  gravity = true
  [clearance]
  joints = "A,B"
  contact = "lankarani-nikravesh"
  friction = "modified-coulomb"
  [clearance.B]
  clearance = 2e-4
  journal_body = "rod"
  [simulation]
  revolutions = 4

outputs in --out DIR: results.csv and results.npz (every saved instant; columns follow the
mechanism: see docs/cli.md), run.json (configuration, versions, solver statistics, timings,
statistics over the kept revolutions, contact-mode shares) and PNG plots of the kept revolutions.

exit codes: 0 success, 1 simulation failed, 2 bad input.
"""


def add_parser(subparsers, parser_class) -> argparse.ArgumentParser:
    """Register the ``run`` subcommand."""
    run = subparsers.add_parser(
        "run",
        allow_abbrev=False,
        help="simulate a mechanism (slider-crank, four-bar or one from a config file) and write results and plots",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="TOML config file (keys below)"
    )
    add_setting_arguments(run, "run")
    run.add_argument(
        "--spread",
        type=int,
        default=0,
        metavar="K",
        help="also solve K companions, started from the initial state perturbed at the rounding "
        "level (1e-12 relative), in one vectorised batch; run.json's spread says how far each "
        "figure's median over the kept revolutions moves, and marks the ones that move more than "
        f"2 %% as sensitive (default 0: none; at most {MAX_SPREAD}; docs/outputs.md)",
    )
    run.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (it is shown only on a terminal anyway)",
    )
    run.add_argument(
        "--quiet",
        "-q",
        action="store_true",
        help="print nothing but errors (implies --no-progress)",
    )
    return run


# --- pieces -----------------------------------------------------------------------------------------


def _block(traj):
    jax.block_until_ready(traj.t)
    return traj


def event_capacity() -> int:
    """Contact events recorded per revolution and clearance joint (``run_revolutions``'s
    ``contact_events``: each revolution is a solve with a buffer of its own). It had been sized
    for the whole horizon, in every revolution: memory grew with the square of the horizon."""
    return max(256, EVENTS_PER_REVOLUTION)


def timed_revolutions(
    mechanism,
    settings: Settings,
    solver,
    progress: bool,
    contact_events: int = 0,
    companions: int = 0,
):
    """Simulate revolution by revolution (``jaxclear.studies.simulate_revolutions``), timing
    compilation and the run separately.

    A warm-up over ``WARMUP_FRACTION`` of a revolution (``studies.compile_revolutions``), with a
    revolution's number of output points and the same solver settings, triggers the compilations
    of the nominal solve and of the companions' batch (start and end times are traced values, so
    every revolution reuses the compiled code); its wall time is ``compile_time_s``. The revolutions are then timed together as ``run_time_s`` (a fractional
    last revolution compiles a second program, inside that time).
    """
    simulation = settings.config["simulation"]
    per_revolution = int(simulation["points_per_revolution"])
    revolutions = simulation["revolutions"]
    span = 1.0 if revolutions == AUTO else min(float(revolutions), 1.0)
    start = time.perf_counter()
    _block(
        jaxclear.simulate(
            mechanism,
            60.0 / settings.config["mechanism"]["rpm"] * WARMUP_FRACTION,
            num_points=segment_points(span, per_revolution),
            solver=solver,
            throw=False,
            contact_events=contact_events,
        )
    )
    if companions:  # their vectorised batch too, so that 'run' times the run alone
        compile_revolutions(
            mechanism,
            span=span,
            points_per_revolution=per_revolution,
            solver=solver,
            contact_events=contact_events,
            companions=companions,
            fraction=WARMUP_FRACTION,
        )
    compile_time = time.perf_counter() - start
    start = time.perf_counter()
    total = MAX_REVOLUTIONS if revolutions == AUTO else math.ceil(revolutions)
    with progress_bar(progress, total, "revolutions") as bar:
        result = simulate_revolutions(
            mechanism,
            revolutions,
            points_per_revolution=per_revolution,
            # revolutions auto: the start-up left out follows the verdict unless it was given
            skip=(
                AUTO
                if simulation["revolutions"] == AUTO
                and settings.source("simulation", "skip_revolutions") == "default"
                else simulation["skip_revolutions"]
            ),
            solver=solver,
            contact_events=contact_events,
            on_revolution=lambda k, traj: bar.update(1),
            companions=companions,
        )
    return result, compile_time, time.perf_counter() - start


def _joints_text(settings: Settings, names: list[str], sliders=()) -> str:
    """The header's joints: the revolute clearance joints ``names`` (shared values) and the
    translational clearance joints ``sliders`` (their own values, docs/model.md §2c)."""
    if not names and not sliders:
        return "ideal joints"
    parts = []
    if names:
        c = settings.config["clearance"]
        per_joint = [j for j in names if j in settings.joint_tables]
        extra = f", per-joint settings at {','.join(per_joint)}" if per_joint else ""
        parts.append(
            f"clearance joints {','.join(names)} (c = {c['clearance'] * 1e3:g} mm, {c['contact']} contact, "
            f"{'no' if c['friction'] == 'none' else c['friction']} friction{extra})"
        )
    for j in sliders:
        law, friction = (
            next((k for k, v in laws.items() if type(x) is v), type(x).__name__)
            for laws, x in ((CONTACT_LAWS, j.contact_law), (FRICTION_LAWS, j.friction_law))
        )
        parts.append(
            f"translational clearance joint {j.name} (c = {float(j.clearance) * 1e3:g} mm, "
            f"slider {2e3 * float(j.half_length):g} x {2e3 * float(j.half_height):g} mm, {law} corner "
            f"contact K = {float(j.contact_law.stiffness):g}, "
            f"{'no' if friction == 'none' else friction} friction)"
        )
    return ", ".join(parts)


def _summary_line(run) -> str:
    """The printed line that leads: the verdict and the median (min .. max) over the kept
    revolutions of the headline figures; the single largest values follow on their own line."""
    summary, kept = run.summary(), run.kept
    parts = []
    mechanism = run.trajectory.mechanism
    names = []
    if is_slider_crank(mechanism):
        names.append(("peak_slider_acceleration", "peak |slider acceleration|", "m/s^2"))
    if mechanism.driver is not None:
        body = mechanism.driver.body
        names += [(f"{body}_torque_rms", f"{body} torque rms", "N m")]
    names += [
        (f"{j.name}_peak_normal_force", f"{j.name} peak normal force", "N")
        for j in (*mechanism.clearance_joints, *mechanism.translational_clearance_joints)
    ]
    for key, label, unit in names:
        if key in summary:
            v = summary[key]
            parts.append(f"{label} {v['median']:.4g} {unit} ({v['min']:.4g} .. {v['max']:.4g})")
    head = f"revolutions {kept[0]}-{kept[-1]} ({len(kept)}): {run.verdict.describe()}"
    return f"{head}\nmedian (min .. max) per revolution: " + "; ".join(parts)


def _spread_line(run, companions: int) -> str:
    """Which headline figures move under a rounding-level perturbation (``--spread``)."""
    spread = run.spread()
    moved = [f"{k} {v['relative_spread']:.0%}" for k, v in spread.items() if v["sensitive"]]
    steady = [k for k, v in spread.items() if not v["sensitive"]]
    head = f"spread over {companions} companions (rounding-level start): "
    if not moved:
        return head + f"no median moves more than {SENSITIVE_SPREAD:.0%}"
    return (
        head
        + f"sensitive (median moves > {SENSITIVE_SPREAD:.0%}): "
        + ", ".join(moved)
        + f"; steady: {', '.join(steady) or 'none'}"
    )


def _figures(traj, statistics: dict) -> str:
    """The run's headline figures over the kept window, from the solver's steps (``statistics``)."""
    parts = []
    if is_slider_crank(traj.mechanism):
        parts.append(
            f"peak |slider acceleration| {statistics['peak_slider_acceleration']:.6g} m/s^2"
        )
    driver = traj.mechanism.driver
    if driver is not None:
        low, high, rms = (statistics[f"{driver.body}_torque_{k}"] for k in ("min", "max", "rms"))
        parts.append(f"{driver.body} torque {low:.6g} .. {high:.6g} N m (rms {rms:.6g})")
    sliders = [j.name for j in traj.mechanism.translational_clearance_joints]  # largest corner
    for name in clearance_joint_names(traj) + sliders:
        parts.append(
            f"{name} peak normal force {statistics[f'{name}_peak_normal_force']:.6g} N, "
            f"peak penetration {statistics[f'{name}_peak_penetration'] * 1e6:.4g} um"
        )
    parts.append(f"max constraint violation {statistics['max_constraint_violation']:.3g} m")
    return "; ".join(parts)


# --- the command ------------------------------------------------------------------------------------


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """Run ``jaxclear run``; returns 0, raises ``UsageError`` (exit 2) or ``RunError`` (exit 1).

    The results are written into a staging folder beside ``--out`` and moved into place when
    complete (``_folders.StagedOutput``); a command that stops early leaves ``--out`` as it was.
    """
    staged: list[StagedOutput] = []
    try:
        return _run(args, argv, staged)
    finally:
        for s in staged:
            s.discard()  # nothing left after publish; a run that stopped early leaves no trace


def _run(args: argparse.Namespace, argv: list[str], staged: list[StagedOutput]) -> int:
    settings = resolve_settings(args)
    config = settings.config
    solver_for(settings)  # reject a bad solver name before any work
    if not 0 <= args.spread <= MAX_SPREAD:
        raise UsageError(
            f"--spread {args.spread}: give 0 (no companions) to {MAX_SPREAD} (the companions are "
            "one vectorised batch stepped together: its time and memory grow with their number)"
        )
    fast_compile = apply_fast_compile(
        config["solver"]["fast_compile"]
    )  # before JAX's backend starts
    compilation_cache = apply_compilation_cache(config["solver"]["compilation_cache"])
    mechanism = build_mechanism(settings)
    ideal = ideal_mechanism(mechanism)  # clearance joints made ideal: the plots' reference
    names = [j.name for j in mechanism.clearance_joints]
    start = config["simulation"]["start"]
    quiet = args.quiet
    progress = not (quiet or args.no_progress) and sys.stderr.isatty()
    say = (lambda *a, **k: None) if quiet else print
    auto = config["simulation"]["revolutions"] == AUTO
    t1, num_points = grid(settings, MAX_REVOLUTIONS if auto else None)  # auto: at most
    try:
        jaxclear.assemble(ideal)  # a mechanism that cannot assemble is bad input: exit 2
        out_dir = claim_output(settings, "run", say)  # all input checked: may it take our results?
        staged.append(StagedOutput(out_dir, settings.source("output", "directory")))
        if names and start == "wall":
            mechanism = wall_start(
                mechanism, num_points=num_points
            )  # shares the reference run's compilation
        jaxclear.assemble(mechanism)
    except jaxclear.AssemblyError as e:
        raise UsageError(f"the mechanism cannot be assembled: {one_line(e)}") from None
    except jaxclear.ModelError as e:
        raise UsageError(f"invalid mechanism: {one_line(e)}") from None
    except jaxclear.SimulationError as e:  # the short ideal solve of the wall start
        raise RunError(f"wall start: {one_line(e)} Or start centred (--start centred).") from None
    solver = solver_for(settings, mechanism)
    t_keep = kept_start(settings)

    rpm, revs = config["mechanism"]["rpm"], config["simulation"]["revolutions"]
    skip = config["simulation"]["skip_revolutions"]
    say(
        f"jaxclear {jaxclear.__version__}: {settings.mechanism}, "
        f"{_joints_text(settings, names, mechanism.translational_clearance_joints)}, {rpm:g} rpm, "
        + (
            f"revolutions auto (until settled, at most {MAX_REVOLUTIONS}; "
            if auto
            else f"{revs:g} rev ({t1:.6g} s, {num_points} points; "
        )
        + (
            "plots and statistics from the settled revolutions), "
            if auto and settings.source("simulation", "skip_revolutions") == "default"
            else f"plots and statistics from revolution {skip:g}), "
        )
        + f"{start} start, solver {config['solver']['method']} ({solver.method}, rtol {solver.rtol:g}, atol {solver.atol:g})"
    )
    say("compiling (one-off) and simulating ...", flush=True)
    try:
        revolution_run, compile_time, run_time = timed_revolutions(
            mechanism,
            settings,
            solver,
            progress,
            event_capacity() if contact_joints(mechanism) else 0,
            companions=args.spread,
        )
        traj = revolution_run.trajectory
        if auto and bool(traj.succeeded):  # the horizon the run took
            t1, num_points = float(traj.t_final), int(np.asarray(traj.t).size)
        t_keep = revolution_run.statistics_start  # the verdict's, with revolutions auto
    except jaxclear.AssemblyError as e:
        raise UsageError(f"the mechanism cannot be assembled: {one_line(e)}") from None
    except jaxclear.ModelError as e:
        raise UsageError(f"invalid mechanism: {one_line(e)}") from None
    except jaxclear.SimulationError as e:
        raise RunError(one_line(e)) from None

    info = run_info(
        settings, argv, mechanism, solver, traj, t1, num_points, t_keep,
        compile_time=compile_time, run_time=run_time, fast_compile=fast_compile,
        compilation_cache=compilation_cache,
    )  # fmt: skip
    fraction = config["clearance"]["continuous_fraction"]
    if not bool(traj.succeeded):
        return _failed(traj, solver, info, staged[0], fraction, say)

    kept = window(traj, t_keep)
    statistics = run_statistics(traj)
    rows = revolution_run.table(fraction if contact_joints(mechanism) else None)
    info.update(
        steady_state=revolution_run.verdict.as_dict(),
        summary=revolution_run.summary(),
        revolutions=rows,
    )
    if args.spread:
        info["spread"] = {
            "companions": args.spread,
            "perturbation": f"initial state x (1 + {COMPANION_PERTURBATION:g} xi), xi standard normal",
            "threshold": SENSITIVE_SPREAD,
            "statistics": revolution_run.spread(),
        }
    try:
        paths, files = write_run_outputs(
            traj, staged[0], info, statistics, ideal, t1, num_points, t_keep, fraction,
            plots=config["output"]["plots"], period=60.0 / rpm, say=say, revolution_rows=rows,
        )  # fmt: skip
    except OSError as e:
        raise RunError(
            f"cannot write results to {str(out_dir)!r}: {e.strerror or e}; choose another --out folder"
        ) from None

    stats = traj.stats()
    say(
        f"compile {compile_time:.2f} s, run {run_time:.3f} s, {stats['num_steps']} steps ({stats['num_rejected_steps']} rejected)"
    )
    say(_summary_line(revolution_run))
    if args.spread:
        say(_spread_line(revolution_run, args.spread))
    say(
        f"largest over the kept revolutions (from revolution {revolution_run.kept[0]}): "
        f"{_figures(kept, statistics)}"
    )
    say(f"wrote {', '.join(sorted([p.name for p in paths.values()] + files))} to {out_dir}/")
    return 0


def run_info(
    settings: Settings,
    argv: list[str],
    mechanism,
    solver,
    traj,
    t1: float,
    num_points: int,
    t_keep: float,
    *,
    compile_time: float,
    run_time: float,
    fast_compile: str,
    compilation_cache: str,
) -> dict[str, Any]:
    """run.json's configuration, solver and timing entries (the statistics come later)."""
    config = settings.config
    names = [j.name for j in mechanism.clearance_joints]
    return dict(
        format=RUN_FORMAT,
        status="complete",
        error=None,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        command=[PROG, *argv],
        config_file=str(Path(settings.config_file).resolve()) if settings.config_file else None,
        config=config,
        clearance_per_joint=settings.joint_tables,
        description=settings.description,
        sources={f"{sec}.{key}": src for (sec, key), src in settings.sources.items()},
        mechanism=settings.mechanism,
        clearance_joints=names,
        initial_eccentricity={
            j.name: np.asarray(j.initial_eccentricity).tolist() for j in mechanism.clearance_joints
        },
        t_end_s=t1,
        num_points=num_points,
        kept_window_s=[t_keep, t1],
        solver={f.name: getattr(solver, f.name) for f in dataclasses.fields(solver)},
        stats=traj.stats(),
        compile_time_s=compile_time,
        run_time_s=run_time,
        fast_compile=fast_compile,
        compilation_cache=compilation_cache,
        compiled_programs=jaxclear.compilation_cache_statistics(),
        timing=(
            "compile_time_s: wall time of a warm-up simulate call over "
            f"{WARMUP_FRACTION:g} of the horizon with identical shapes and settings (tracing, XLA "
            "compilation, assembly and a negligible solve; with the compilation cache warm, "
            "loading the stored program instead); run_time_s: wall time of the full "
            "simulate call afterwards, which reuses the compiled code. compiled_programs: "
            "programs loaded from the compilation cache, compiled (and stored) in this run."
        ),
        versions=package_versions(),
        jax_backend=jax.default_backend(),
    )


def write_run_outputs(
    traj,
    staged: StagedOutput,
    info: dict,
    statistics: dict,
    ideal,
    t1: float,
    num_points: int,
    t_keep: float,
    fraction: float,
    *,
    plots: bool,
    period: float,
    say,
    revolution_rows: list[dict] | None = None,
) -> tuple[dict, list[str]]:
    """Write a successful run's outputs (what ``jaxclear run`` writes) and publish them.

    Plots of the kept revolutions against an ideal-joint reference run, modes.csv and the mode
    timeline from the contacts located in ``traj``, results.csv, results.npz and run.json (``info``
    with ``statistics`` and the contact modes), staged in ``staged`` and moved into place.

    Args:
        traj: a successful single ``Trajectory``.
        staged: the staging folder (``StagedOutput``), published at the end.
        info: run.json's entries (``run_info``).
        statistics: run.json's ``statistics``.
        ideal: the ideal-joint mechanism of the plots' reference run.
        t1, num_points: the horizon and its output points (for the reference run).
        t_keep: start of the kept window, s. fraction: continuous-contact threshold, fraction of
            ``period`` (the crank period, s).
        plots: write the PNG plots.

    Returns:
        ``(paths, files)``: ``write_results``'s paths and the other files written.

    Raises:
        OSError: a file cannot be written.
    """
    names = clearance_joint_names(traj)
    kept = window(traj, t_keep)
    reference = None
    if names and plots:
        say("ideal-joint reference run for the plots ...", flush=True)
        reference = _block(jaxclear.simulate(ideal, t1, num_points=num_points, solver="fast"))
        reference = window(reference, t_keep)
    stage = staged.stage
    files = []
    if plots:
        from ..plot import save_standard_plots, save_translational_plots

        files = [p.name for p in save_standard_plots(kept, stage, reference=reference)]
        files += [p.name for p in save_translational_plots(kept, stage)]  # slider tilt, corners
    modes = (
        _contact_modes(traj, kept, fraction, period, t_keep)
        if names or traj.mechanism.translational_clearance_joints
        else {"contact_mode_shares": {}, "contact_modes": {}}
    )
    if modes.get("events") is not None:
        events = modes.pop("events")
        files.append(write_modes_csv(stage / MODES_CSV, events).name)
        if plots:
            from ..plot import save_mode_timeline

            files.append(save_mode_timeline(traj, stage, events=events, start=t_keep).name)
    modes.pop("events", None)
    if revolution_rows:
        files.append(write_revolutions_csv(stage / REVOLUTIONS_CSV, revolution_rows).name)
    info.update(statistics=statistics, **modes, files=files)
    paths = write_results(stage, traj, info, fraction)
    staged.publish()
    return paths, files


def _contact_modes(traj, kept, fraction: float, period: float, t_keep: float) -> dict:
    """run.json's contact-mode entries over the kept window: from the located contact events
    (``analysis.event_mode_shares``; also returned under ``events`` for modes.csv), or from the
    saved instants where the event buffer overflowed."""
    from ..analysis import contact_events, event_mode_shares

    rule = {"continuous_fraction": fraction, "reference_period_s": period}
    guides = bool(traj.mechanism.translational_clearance_joints)
    try:
        events = contact_events(traj, continuous_fraction=fraction, start=t_keep)
        shares = event_mode_shares(traj, continuous_fraction=fraction, start=t_keep)
    except ValueError as e:  # the buffer overflowed: shares from the saved instants instead
        out = {
            "contact_mode_shares": mode_shares(kept, fraction, reference_period=period),
            "contact_modes": {},
            "contact_mode_source": f"saved instants ({one_line(e)})",
            "contact_mode_rule": rule,
            "events": None,
        }
        if guides:
            out["corner_pair_mode_shares"] = _corner_pair_shares(kept, fraction, period)
        return out
    out = {
        "contact_mode_shares": shares["combinations"],
        "contact_modes": shares["joints"],
        "contact_mode_source": "contact onsets and ends located from the solver's steps",
        "contact_mode_rule": rule,
        "events": events,
    }
    if guides:
        out["corner_pair_mode_shares"] = shares["corner_pairs"]["combinations"]
        out["corner_pair_modes"] = shares["corner_pairs"]["joints"]
    return out


def _corner_pair_shares(kept, fraction: float, period: float) -> dict:
    """run.json's ``corner_pair_mode_shares`` where the contact events overflowed their buffer:
    time share of each combination of the corner pairs' contact modes of the translational
    clearance joints (``<J>.upper``: the upper front and rear corners against the upper guide
    face, ``<J>.lower`` likewise; a pair is in contact when one of its corners is), over the kept
    saved instants, as the columns ``<J>_mode_upper`` and ``<J>_mode_lower`` label them
    (docs/model.md §2c)."""
    from ..analysis import combination_shares, contact_modes
    from ..model import CORNER_PAIRS

    modes = {}
    for joint in kept.mechanism.translational_clearance_joints:
        depth = np.asarray(kept.clearance[joint.name]["corner_penetration"], dtype=float)
        for pair, corners in CORNER_PAIRS.items():
            modes[f"{joint.name}.{pair}"] = contact_modes(
                kept.t, depth[:, corners].max(axis=1), fraction * period
            )
    return combination_shares(modes)


def _failed(traj, solver, info: dict, staged: StagedOutput, fraction: float, say) -> int:
    """A failed solve: the finite instants reached are written, no plots, run.json says why; exit 1."""
    # the message simulate(throw=True) would raise, for a trajectory that is kept
    from ..solve import failure_error

    failure = failure_error(traj, solver)
    reached = finite_rows(traj.truncated())
    info.update(
        status="failed", error=one_line(failure), statistics={}, contact_mode_shares={}, files=[]
    )
    out_dir = staged.out
    try:
        if reached.t.shape[0] >= 1:
            write_results(staged.stage, reached, info, fraction)
            where = (
                f"Partial results up to t = {float(reached.t[-1]):.6g} s (no plots) are in {out_dir}/ "
                "(run.json status 'failed')."
            )
        else:
            write_json(staged.stage / RUN_JSON_NAME, {**info, "files": [RUN_JSON_NAME]})
            where = f"No instant was reached; {out_dir}/run.json has status 'failed'."
        staged.publish()
    except OSError as e:
        raise RunError(
            f"{one_line(failure)} Also cannot write to {str(out_dir)!r}: {e.strerror or e}."
        ) from None
    say(f"simulation failed after {int(traj.num_steps)} steps")
    raise RunError(f"{one_line(failure)} {where}")
