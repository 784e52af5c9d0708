"""``jaxclear fit DATA.csv [CONFIG.toml]``: identify mechanism parameters from a measured response."""

import argparse
import csv
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import jax
import numpy as np

import jaxclear

from ..internal import NOISE_LEVEL_LOSS, check_identification
from ..io import CSV_FORMAT, atomic_write, package_versions, write_json
from ..studies import FitSettings, identify
from ._common import (
    EXIT_NOT_FITTED,
    PROG,
    RunError,
    UsageError,
    apply_compilation_cache,
    apply_fast_compile,
    one_line,
)
from ._config import resolve_settings
from ._folders import StagedOutput, claim_output
from ._mechanism_config import build_mechanism
from ._prepare import grid, solver_for
from ._settings import add_setting_arguments, config_reference

DESCRIPTION = f"""\
Fit parameters of a mechanism (clearances, restitution, friction, stiffness, masses, ...) to a
measured response in DATA.csv by gradient-based weighted least squares, and write fit.json,
fit.csv, fit.png and loss.png into --out DIR.

DATA.csv: a column t (s, strictly increasing, from the start of the motion) and one or more of the
columns 'jaxclear run' writes for the mechanism (slider_x, slider_v, slider_a, crank_torque, a
clearance joint's B_ecc_x, ...), SI units. The mechanism and its operating point (speed, gravity,
per-joint clearance tables, journal_body, start) come from the same config file and options as
'jaxclear run'; the simulation starts at t = 0 from that start state and must cover the data
(--revolutions).

Each signal is weighted by its noise level: estimated from the data (third differences, robust to
impacts) or given with --noise. The fit starts on the shortest window that carries the
parameters (up to the first contacts of a first simulation, and of the data), scans the bounds
there (vectorised solves) with a design refined until its spacing resolves the width of the loss's
basins that it measures, runs Levenberg-Marquardt from the best few scanned points, and continues
from the best over windows twice as long each, with forward-mode derivatives through the solve. It
stops extending the window where the model no longer follows the data (a chaotic impact sequence):
fit.json says up to which time the data were fitted. Uncertainties are one
standard deviation (1 sigma): Gauss-Newton (scaled by the reduced chi-square when above 1) plus the
estimate's drift between the last two windows.

A fit is a success only when every estimate and standard deviation is finite, a window of the
record told the scanned points apart, and the loss reaches the noise level (1 = noise level; at
most {NOISE_LEVEL_LOSS:g} for the usual hundreds of residuals). Otherwise the command still writes
its files, fit.json says "success": false and why ("reason"), and it prints the reason and exits
with code 3."""

EPILOG = f"""\
parameters (--fit): comma-separated NAME[=INITIAL[:LOWER:UPPER]]; NAME as in
jaxclear.parameter_names(mechanism): B.clearance, B.restitution, B.friction_coefficient,
B.young_modulus, rod_mass, slider_mass, rpm, ... Without INITIAL the config's value is the start;
without bounds a positive parameter is searched in [INITIAL/4, 4*INITIAL].

example (5000 rpm, clearance joint B with the pin on the rod, gravity on):
  jaxclear fit measured.csv --clearance-joints B --contact lankarani-nikravesh \\
      --friction modified-coulomb --friction-coefficient 0.01 --gravity --rpm 5000 \\
      --fit B.clearance=5e-4:1e-4:8e-4 --out fit-B

outputs in --out DIR: fit.json (success and reason; parameters with value, std (1 sigma),
initial, lower, upper, unit; noise levels; loss history; iterations; time; convergence status),
fit.csv (t and, per signal, <name>_measured, <name>_fitted, <name>_residual), fit.png (measured
and fitted signals, estimates +- 1 sigma), loss.png (loss per iteration).

exit codes: 0 success, 1 a solve failed or the results could not be written, 2 bad input (bad
data, unknown parameter or column, ...), 3 not a fit: the loss did not reach the noise level, an
estimate has no finite standard deviation, or no window told the scanned points apart (files
written, fit.json says "success": false and the reason, the printed estimates are marked
unreliable).

config file (TOML; every key optional; command-line options override it):
{config_reference()}
"""

FIT_JSON = "fit.json"
FIT_CSV = "fit.csv"
FIT_FORMAT = 1
DEFAULTS = FitSettings()


def add_parser(subparsers, parser_class) -> argparse.ArgumentParser:
    """Register the ``fit`` subcommand."""
    fit = subparsers.add_parser(
        "fit",
        allow_abbrev=False,
        help="fit clearances, contact and friction parameters to a measured response",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    fit.add_argument("data", metavar="DATA.csv", help="measured signals (columns t, ...)")
    fit.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="TOML config file (as for 'run')"
    )
    fit.add_argument(
        "--fit",
        dest="fit_parameters",
        action="append",
        required=True,
        metavar="NAMES",
        help="parameters to fit: NAME[=INITIAL[:LOWER:UPPER]], comma-separated (repeatable)",
    )
    fit.add_argument(
        "--noise",
        action="append",
        default=[],
        metavar="NAME=SIGMA",
        help="noise standard deviation of a column in its units (repeatable; default: estimated)",
    )
    fit.add_argument(
        "--columns",
        default=None,
        metavar="NAMES",
        help="comma-separated data columns to fit (default: every column but t)",
    )
    fit.add_argument(
        "--scan-points",
        type=int,
        default=None,
        metavar="N",
        help="points of the global scan's first design (default 16 per parameter; 0: start from "
        "INITIAL)",
    )
    fit.add_argument(
        "--max-scan-points",
        type=int,
        default=None,
        metavar="N",
        help="most points the scan refines its design to, following the basin width it measures "
        f"(default {DEFAULTS.scan_budget(1)}; the first design's size: no refinement)",
    )
    fit.add_argument(
        "--starts",
        type=int,
        default=DEFAULTS.starts,
        metavar="N",
        help="Levenberg-Marquardt runs on the first window, from the best scanned points of "
        f"distinct basins (default {DEFAULTS.starts})",
    )
    fit.add_argument(
        "--max-iterations",
        type=int,
        default=DEFAULTS.max_iterations,
        metavar="N",
        help=f"Levenberg-Marquardt iterations per window (default {DEFAULTS.max_iterations})",
    )
    fit.add_argument(
        "--horizons",
        default=None,
        metavar="F,...",
        help="growing windows as fractions of the record, ending with 1 (default: the first up "
        "to the first contacts, then twice as long each)",
    )
    add_setting_arguments(fit, "fit")
    fit.add_argument("--no-progress", action="store_true", help="no progress bar")
    fit.add_argument("--quiet", "-q", action="store_true", help="print nothing but errors")
    return fit


def parse_fit_parameters(texts: list[str]) -> dict[str, Any]:
    """``{name: None | initial | (initial, lower, upper)}`` from the --fit options.

    Raises:
        UsageError: an empty name or a value that is not a number, or not 1 or 3 values.
    """
    out: dict[str, Any] = {}
    for text in texts:
        for item in (part.strip() for part in text.split(",")):
            if not item:
                continue
            name, _, value = item.partition("=")
            name = name.strip()
            if not name:
                raise UsageError(f"--fit {item!r}: give a parameter name, e.g. B.clearance")
            if name in out:
                raise UsageError(f"--fit: parameter {name!r} is given twice; give it once")
            if not value:
                out[name] = None
                continue
            parts = value.split(":")
            try:
                numbers = [float(v) for v in parts]
            except ValueError:
                raise UsageError(
                    f"--fit {item!r}: {value!r} is not INITIAL or INITIAL:LOWER:UPPER (numbers)"
                ) from None
            if len(numbers) == 1:
                out[name] = numbers[0]
            elif len(numbers) == 3:
                out[name] = tuple(numbers)
            else:
                raise UsageError(
                    f"--fit {item!r}: give INITIAL or INITIAL:LOWER:UPPER, got {len(numbers)} numbers"
                )
    if not out:
        raise UsageError("--fit: give at least one parameter, e.g. --fit B.clearance")
    return out


def _noise(texts: list[str]) -> dict[str, float]:
    out = {}
    for text in texts:
        name, sep, value = text.partition("=")
        try:
            sigma = float(value)
        except ValueError:
            sigma = float("nan")
        if not sep or not name or not np.isfinite(sigma) or sigma <= 0:
            raise UsageError(
                f"--noise {text!r}: give NAME=SIGMA with a positive number, e.g. slider_x=1e-6"
            )
        out[name.strip()] = sigma
    return out


def _horizons(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return DEFAULTS.horizons
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise UsageError(
            f"--horizons {text!r}: give comma-separated fractions, e.g. 0.25,0.5,1"
        ) from None


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """Run ``jaxclear fit``.

    Returns:
        0 for a fit that reaches the noise level, ``EXIT_NOT_FITTED`` (3) for one that does not
        (its files are written, fit.json says why).

    Raises:
        UsageError: bad input (exit 2), before anything is solved or written.
        RunError: a failed solve, or results that cannot be written (exit 1).

    The files are written into a staging folder beside ``--out`` and moved into place when
    complete (``_folders.StagedOutput``): a fit that stops early leaves ``--out`` as it was.
    """
    staged: list[StagedOutput] = []
    try:
        return _fit(args, argv, staged)
    finally:
        for s in staged:
            s.discard()  # nothing left after publish


def _fit(args: argparse.Namespace, argv: list[str], staged: list[StagedOutput]) -> int:
    settings = resolve_settings(args)
    config = settings.config
    solver_for(settings)  # reject a bad solver name before any work
    fast_compile = apply_fast_compile(config["solver"]["fast_compile"])  # before JAX starts
    compilation_cache = apply_compilation_cache(config["solver"]["compilation_cache"])
    parameters = parse_fit_parameters(args.fit_parameters)
    noise = _noise(args.noise)
    columns = None
    if args.columns is not None:
        columns = [c.strip() for c in args.columns.split(",") if c.strip()]
    if args.scan_points is not None and args.scan_points < 0:
        raise UsageError(f"--scan-points {args.scan_points}: give 0 or more")
    if args.max_iterations < 1:
        raise UsageError(f"--max-iterations {args.max_iterations}: give 1 or more")
    if args.max_scan_points is not None and args.max_scan_points < 0:
        raise UsageError(f"--max-scan-points {args.max_scan_points}: give 0 or more")
    if args.starts < 1:
        raise UsageError(f"--starts {args.starts}: give 1 or more")
    try:
        fit_settings = FitSettings(
            horizons=_horizons(args.horizons),
            scan_points=args.scan_points,
            max_scan_points=args.max_scan_points,
            starts=args.starts,
            max_iterations=args.max_iterations,
        )
    except jaxclear.ModelError as e:
        raise UsageError(f"--horizons {args.horizons!r}: {one_line(e)}") from None

    mechanism = build_mechanism(settings)
    if config["simulation"]["start"] == "wall" and mechanism.clearance_joints:
        try:
            mechanism = jaxclear.wall_start(mechanism)
        except jaxclear.SimulationError as e:
            raise RunError(
                f"wall start: {one_line(e)} Or start centred (--start centred)."
            ) from None
    try:
        jaxclear.assemble(mechanism)
        data = jaxclear.Measurements.from_csv(
            args.data, known=jaxclear.signal_names(mechanism), columns=columns, noise=noise
        )
        t1, _ = grid(settings)
        if float(data.t[-1]) > t1 * (1 + 1e-12):
            raise UsageError(
                f"{args.data}: data run to t = {float(data.t[-1]):.6g} s, past the simulated span "
                f"[0, {t1:.6g}] s ({config['simulation']['revolutions']:g} revolutions at "
                f"{config['mechanism']['rpm']:g} rpm); raise --revolutions or cut the data"
            )
        check_identification(mechanism, data, parameters, 0.0, None)
    except jaxclear.DataError as e:
        raise UsageError(one_line(e)) from None
    except jaxclear.AssemblyError as e:
        raise UsageError(f"the mechanism cannot be assembled: {one_line(e)}") from None
    except jaxclear.ModelError as e:
        raise UsageError(one_line(e)) from None

    user_solver = any(  # any solver setting given: the fit runs the settings asked for
        settings.sources.get(("solver", key), "default") != "default"
        for key in ("method", "rtol", "atol", "max_steps")
    )
    solver = solver_for(settings, mechanism) if user_solver else None
    quiet = args.quiet
    say = (lambda *a, **k: None) if quiet else print
    out_dir = claim_output(settings, "fit", say)  # all input checked: may it take our results?
    staged.append(StagedOutput(out_dir, settings.source("output", "directory")))
    stage = staged[0].stage
    progress = not (quiet or args.no_progress)  # a bar on a terminal, timed lines in a log
    say(
        f"jaxclear {jaxclear.__version__}: fitting {', '.join(parameters)} to "
        f"{', '.join(data.signals)} of {args.data} ({data.t.shape[0]} instants, "
        f"{float(data.t[0]):.6g} .. {float(data.t[-1]):.6g} s); noise "
        + ", ".join(
            f"{n} {s:.3g}{' (estimated)' if data.noise_estimated.get(n) else ''}"
            for n, s in data.noise.items()
        ),
        flush=True,
    )
    try:
        result = identify(
            mechanism,
            data,
            parameters,
            solver=solver,
            settings=fit_settings,
            progress=progress,
        )
    except jaxclear.ModelError as e:
        raise RunError(one_line(e)) from None

    summary = result.summary()
    info = {
        "format": FIT_FORMAT,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": [PROG, *argv],
        "data_file": str(Path(args.data).resolve()),
        "config_file": str(Path(settings.config_file).resolve()) if settings.config_file else None,
        "config": config,
        "clearance_per_joint": settings.joint_tables,
        **summary,
        "versions": package_versions(),
        "jax_backend": jax.default_backend(),
        "fast_compile": fast_compile,
        "compilation_cache": compilation_cache,
        "files": [FIT_JSON, FIT_CSV, "fit.png", "loss.png"],
    }
    try:
        write_json(stage / FIT_JSON, info)
        atomic_write(stage / FIT_CSV, lambda tmp: _write_fit_csv(tmp, result))
        if config["output"]["plots"]:
            from ..plot import save_fit_plots

            save_fit_plots(result, stage)
        else:
            info["files"] = [FIT_JSON, FIT_CSV]
            write_json(stage / FIT_JSON, info)
        staged[0].publish()
    except OSError as e:
        raise RunError(
            f"cannot write results to {str(out_dir)!r}: {e.strerror or e}; choose another --out folder"
        ) from None
    status = result.status
    if not result.success:  # first, and even when --quiet: the estimates below are not a fit
        print(f"{PROG}: not a fit (exit {EXIT_NOT_FITTED}): {result.reason}", file=sys.stderr)
        status = status.split(f"{result.reason}; ", 1)[-1]  # the reason once is enough
    unreliable = "" if result.success else ", unreliable: not a fit"
    for name, e in result.parameters.items():
        say(
            f"{name} = {e.value:.6g} ± {e.std:.2g} {e.unit} "
            f"(1σ{unreliable}; started {e.initial:.6g})"
        )
    say(
        f"loss {result.loss:.4g} (1 = noise level) over {result.window_end:.6g} s, "
        f"{result.iterations} iterations, {result.time:.1f} s; {status}"
    )
    say(f"wrote {', '.join(info['files'])} to {out_dir}/")
    return 0 if result.success else EXIT_NOT_FITTED


def _write_fit_csv(path: str, result) -> None:
    names = list(result.measured)
    header = ["t"]
    for n in names:
        header += [f"{n}_measured", f"{n}_fitted", f"{n}_residual"]
    rows = [np.asarray(result.t)]
    for n in names:
        rows += [result.measured[n], result.fitted[n], result.fitted[n] - result.measured[n]]
    table = np.column_stack(rows)
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for row in table:
            writer.writerow([CSV_FORMAT % v for v in row])
