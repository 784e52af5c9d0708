"""``jaxclear sweep``'s optional stages after the sweep itself: the bifurcation diagram
(``--sections N``) and the largest Lyapunov exponent (``--lyapunov N``) per value.

Each stage runs after sweep.csv and sweep.json are written, writes its own CSV and PNG as soon as it
finishes, and adds its summary to sweep.json: a stage that fails leaves the finished files on disk.
"""

import argparse
import csv
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import distinct_points
from ..io import atomic_write, write_json
from ..studies import bifurcation_points, lyapunov_solver, lyapunov_sweep
from ._common import RunError, UsageError, one_line

BIFURCATION_CSV = "bifurcation.csv"
LYAPUNOV_CSV = "lyapunov.csv"
DISTINCT_FRACTION = 1e-3
"""Section points of one value closer than this fraction of the signal's range over the whole
diagram count as one point in sweep.json's ``distinct_points`` (1: periodic, k: period k, about
the number of revolutions: quasi-periodic or chaotic; an estimate, see docs/chaos.md)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--sections`` and ``--lyapunov``."""
    parser.add_argument(
        "--sections",
        type=int,
        default=0,
        metavar="N",
        help="also solve each value for N crank revolutions after the skipped ones and write its "
        "Poincare section once per revolution: bifurcation.csv and bifurcation.png (default 0: "
        "none)",
    )
    parser.add_argument(
        "--lyapunov",
        type=int,
        default=0,
        metavar="N",
        help="also estimate each value's largest Lyapunov exponent over N crank revolutions after "
        "the skipped ones (tangent linear system, rtol 1e-9; costly): lyapunov.csv and "
        "lyapunov.png (default 0: none)",
    )


def check(args: argparse.Namespace, mechanism) -> float | None:
    """The crank period (s) the stages need, or ``None`` when no stage is asked for.

    Raises:
        UsageError: a negative count, or a stage asked for without a constant-speed driver.
    """
    for option, value in (("--sections", args.sections), ("--lyapunov", args.lyapunov)):
        if value < 0:
            raise UsageError(f"{option} {value}: give a number of revolutions >= 0 (0: none)")
    if not (args.sections or args.lyapunov):
        return None
    speed = None if mechanism.driver is None else mechanism.driver.constant_speed
    if speed is None or float(np.asarray(speed)) == 0.0:
        raise UsageError(
            "--sections/--lyapunov need a driver at constant speed (sections and intervals are "
            "crank revolutions); this mechanism has none"
        )
    return 2.0 * math.pi / abs(float(np.asarray(speed)))


def _write_rows(path: Path, header: list[str], rows: list[list[Any]]) -> Path:
    def write(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(header)
            w.writerows([[repr(float(v)) if isinstance(v, float) else v for v in r] for r in rows])

    return atomic_write(path, write)


def _failed_stage(stage: str, out_dir: Path, error: Exception) -> RunError:
    return RunError(
        f"the {stage} stage failed ({one_line(error)}); the sweep's results and any earlier "
        f"stage's are in {out_dir}/"
    )


def run_stages(
    args: argparse.Namespace,
    prepared,
    outcome,
    values: np.ndarray,
    period: float | None,
    info: dict[str, Any],
    json_name: str,
    plots: bool,
    say: Callable[..., None],
) -> None:
    """Run the stages asked for, each written when done (CSV, PNG, sweep.json updated).

    Raises:
        RunError: a stage failed (the files written before it stay).
    """
    if period is None:
        return
    out_dir = outcome.out_dir
    mechanism = prepared.mechanism
    skip = math.ceil(prepared.statistics_start / period - 1e-9)
    if args.sections:
        say(
            f"bifurcation diagram: {args.sections} revolutions per value after {skip} ...",
            flush=True,
        )
        try:
            diagram = bifurcation_points(
                mechanism,
                args.param,
                values,
                args.sections,
                skip_revolutions=skip,
                solver=prepared.solver,
                settings=outcome.settings,
            )
        except (ValueError, RuntimeError) as e:
            raise _failed_stage("bifurcation", out_dir, e) from None
        names = list(diagram.points)
        rows = [
            [i, float(v), k, float(diagram.times[i, k])]
            + [float(diagram.points[n][i, k]) for n in names]
            for i, v in enumerate(values)
            for k in range(args.sections)
        ]
        files = [_write_rows(out_dir / BIFURCATION_CSV, ["index", args.param, "revolution",
                                                          "time_s", *names], rows).name]  # fmt: skip
        distinct = {}
        for n in names:
            span = float(np.nanmax(diagram.points[n]) - np.nanmin(diagram.points[n]))
            tolerance = DISTINCT_FRACTION * span if np.isfinite(span) else 0.0
            distinct[n] = {"tolerance": tolerance,
                           "counts": distinct_points(diagram.points[n], tolerance).tolist()}  # fmt: skip
        if plots:
            from ..plot import plot_bifurcation, save_figure

            files.append(
                save_figure(plot_bifurcation(diagram), out_dir, "bifurcation.png", 110).name
            )
        info["bifurcation"] = {
            "revolutions": args.sections,
            "skip_revolutions": skip,
            "signals": names,
            "succeeded": diagram.succeeded.tolist(),
            "distinct_points": distinct,
            "distinct_rule": f"points closer than {DISTINCT_FRACTION:g} of the signal's range "
            "over the diagram are one point",
        }
        info["files"] = list(info.get("files", [])) + files
        write_json(out_dir / json_name, info)
        ok = int(diagram.succeeded.sum())
        first = names[0]
        counts = distinct[first]["counts"]
        say(
            f"  {ok} of {len(values)} values solved; distinct section points of {first} per "
            f"value: {', '.join(map(str, counts))}"
        )
        say(f"wrote {', '.join(files)} to {out_dir}/")
    if args.lyapunov:
        config = lyapunov_solver(mechanism)
        say(
            f"Lyapunov exponents: {args.lyapunov} revolutions per value after {skip}, "
            f"{config.method} rtol {config.rtol:g} ...",
            flush=True,
        )
        try:
            sweep = lyapunov_sweep(
                mechanism,
                args.param,
                values,
                (skip + args.lyapunov) * period,
                interval=period,
                transient=skip * period,
                solver=config,
                settings=outcome.settings,
            )
        except (ValueError, RuntimeError) as e:
            raise _failed_stage("Lyapunov", out_dir, e) from None
        rows = [
            [i, float(v), float(sweep.exponents[i]), float(sweep.spread[i]),
             float(sweep.exponents[i] * period), int(sweep.succeeded[i])]
            for i, v in enumerate(values)
        ]  # fmt: skip
        header = ["index", args.param, "exponent_per_s", "spread_per_s",
                  "exponent_per_revolution", "succeeded"]  # fmt: skip
        files = [_write_rows(out_dir / LYAPUNOV_CSV, header, rows).name]
        if plots:
            from ..plot import plot_lyapunov_sweep, save_figure

            files.append(save_figure(plot_lyapunov_sweep(sweep), out_dir, "lyapunov.png", 110).name)
        info["lyapunov"] = {
            "revolutions": args.lyapunov,
            "skip_revolutions": skip,
            "interval_s": sweep.interval,
            "solver": {"method": config.method, "rtol": config.rtol, "atol": config.atol},
            "exponent_per_s": [None if not np.isfinite(x) else float(x) for x in sweep.exponents],
            "spread_per_s": [None if not np.isfinite(x) else float(x) for x in sweep.spread],
            "succeeded": sweep.succeeded.tolist(),
        }
        info["files"] = list(info.get("files", [])) + files
        write_json(out_dir / json_name, info)
        finite = sweep.exponents[np.isfinite(sweep.exponents)]
        if finite.size:
            say(
                f"  largest Lyapunov exponent {finite.min():.4g} .. {finite.max():.4g} 1/s; "
                f"{int(np.sum(finite > 0))} of {len(values)} values positive"
            )
        say(f"wrote {', '.join(files)} to {out_dir}/")
