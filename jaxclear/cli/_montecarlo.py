"""``jaxclear montecarlo [CONFIG.toml]``: Monte Carlo over manufacturing tolerances."""

import argparse
import math
from collections.abc import Mapping
from typing import Any

import jaxclear

from ..studies import AbstractDistribution, IsoFit, Normal, distribution_from_spec
from ._common import UsageError, one_line
from ._ensemble_common import (
    DEVICE_COUNT_FLAG,
    add_ensemble_arguments,
    base_info,
    finish,
    prepare,
    replay,
    run_engine,
)
from ._settings import add_setting_arguments, config_reference

DESCRIPTION = f"""\
Monte Carlo over manufacturing tolerances: draw --samples members of the mechanism with the
parameters of the config file's [montecarlo] table drawn from their distributions (ISO 286 fits,
uniform, normal, lognormal, fixed), solve them all (vectorised chunks spread over the CPU cores or
GPUs) and write samples.csv, summary.json, histograms.png and scatter.png into --out DIR.

The mechanism, speed, clearance joints and laws, horizon (revolutions, skip_revolutions,
points_per_revolution) and solver come from the same config file and options as 'jaxclear run'.
Members start centred (--start wall is refused: the wall start is per nominal clearance).

Finished members are written after every chunk; the same command run again resumes from --out
DIR, and a changed configuration (seed, samples, a distribution, an option) is refused. On a CPU
the cores are exposed to JAX as devices ({DEVICE_COUNT_FLAG}=N in XLA_FLAGS, N = --devices or
every usable core) unless XLA_FLAGS already sets it.

To look at an outlier, run the same command again with --member K: member K is solved again by
the ensemble's own batched program and written as 'jaxclear run' writes a run (results.csv, plots,
modes.csv, run.json) into --out DIR/member-K, with statistics bitwise equal to its row."""

EPILOG = f"""\
distributions, in the config file (SI units; names as jaxclear.parameter_names(mechanism)):
  [montecarlo]
  rod_mass = {{ distribution = "normal", mean = 0.21, std = 0.005 }}   # optional low, high
  "A.clearance" = {{ distribution = "uniform", low = 3e-4, high = 6e-4 }}
  crank_mass = {{ distribution = "lognormal", median = 0.5, sigma = 0.02 }}  # or mean, std
  slider_mass = 0.5                                                  # fixed
  [montecarlo.B]                                                     # per joint: B.<key>
  clearance = {{ fit = "H7/g6", diameter = 0.02 }}   # within = "uniform" (default) or "normal"

example:
  jaxclear montecarlo examples/montecarlo_h7g6.toml --samples 256 --seed 1 --out mc-h7g6

outputs in --out DIR: samples.csv (one row per member: index, drawn values, statistics, solver
steps, wall time, status, message), ensemble.json (the engine's manifest, for resuming),
summary.json (configuration, distributions, seed, devices, timing, percentiles 5/50/95, mean and
standard error of every statistic, failures), histograms.png (main statistics), scatter.png (main
statistics against each drawn parameter). See docs/ensembles.md.

exit codes: 0 at least one member succeeded, 1 all failed, 2 bad input (including an output folder
that holds another configuration).

config file (TOML; every key optional; command-line options override it):
{config_reference()}
"""

SUMMARY_JSON = "summary.json"
SAMPLES_CSV = "samples.csv"
SUMMARY_FORMAT = 1
SPEC_KEYS = frozenset({"distribution", "fit"})
"""Keys that make a table a distribution, not a per-joint table ``[montecarlo.<joint>]``."""
DIAMETER_MISMATCH = 0.01
"""A fit's nominal diameter more than 1 % off the joint's bearing diameter gets a note."""
NORMAL_REACH = 6.0
"""An untruncated normal is taken to reach mean ± 6 std for the admissible-range note (a draw
beyond has probability 2e-9)."""


def add_parser(subparsers, parser_class) -> argparse.ArgumentParser:
    """Register the ``montecarlo`` subcommand."""
    mc = subparsers.add_parser(
        "montecarlo",
        allow_abbrev=False,
        help="Monte Carlo over tolerances ([montecarlo] distributions, ISO 286 fits)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    mc.add_argument(
        "config",
        nargs="?",
        metavar="CONFIG.toml",
        help="TOML config file with a [montecarlo] table (and the keys of 'run')",
    )
    mc.add_argument(
        "--samples", type=int, required=True, metavar="N", help="number of members to draw"
    )
    mc.add_argument(
        "--seed",
        type=int,
        default=0,
        metavar="S",
        help="seed of the draws (default 0); each parameter has its own stream",
    )
    add_setting_arguments(mc, "montecarlo")
    add_ensemble_arguments(mc)
    return mc


def distributions(
    table: Mapping[str, Any], mechanism, where: str
) -> dict[str, AbstractDistribution]:
    """``{parameter name: distribution}`` from a ``[montecarlo]`` table, checked.

    A key that names a parameter (``rod_mass``, ``"B.clearance"``), or whose value is a number or
    a table with ``distribution`` or ``fit``, is one parameter; any other table is a per-joint (or
    per-element) table ``[montecarlo.<J>]`` whose keys are ``<J>.<key>``.

    Raises:
        UsageError: an unknown parameter (with the closest names), a bad spec (naming the
            parameter), a parameter given twice.
    """
    names = set(jaxclear.parameter_names(mechanism))
    specs: dict[str, tuple[Any, str]] = {}

    def add(name: str, spec: Any, label: str) -> None:
        if name in specs:
            raise UsageError(
                f"{where}: {name} is given twice ({specs[name][1]} and {label}); give it once"
            )
        specs[name] = (spec, label)

    for key, value in table.items():
        if isinstance(value, Mapping) and key not in names and not SPEC_KEYS & set(value):
            for sub, spec in value.items():
                add(f"{key}.{sub}", spec, f"[montecarlo.{key}] {sub}")
        else:
            add(key, value, f"[montecarlo] {key}")
    out = {}
    for name, (spec, _) in specs.items():
        try:
            jaxclear.parameter_info(mechanism, name)
        except jaxclear.ModelError as e:
            raise UsageError(f"{where}: {one_line(e)}") from None
        try:
            out[name] = distribution_from_spec(spec, name)
        except ValueError as e:
            raise UsageError(f"{where}: {one_line(e)}") from None
    return out


def notes(dists: Mapping[str, AbstractDistribution], mechanism) -> list[str]:
    """Warnings about distributions that may draw inadmissible values or fits of another size."""
    out = []
    for name, d in dists.items():
        low, high = d.support()
        if isinstance(d, Normal):
            low = max(low, d.mean - NORMAL_REACH * d.std)
            high = min(high, d.mean + NORMAL_REACH * d.std)
        domain = jaxclear.parameter_info(mechanism, name).domain
        if low < domain[0] or high > domain[1]:
            out.append(
                f"note: {name} may draw values outside its admissible range "
                f"({domain[0]:g}, {domain[1]:g}); such members are recorded as failed"
            )
        if isinstance(d, IsoFit) and name.endswith(".clearance"):
            joint = name.rsplit(".", 1)[0]
            bearing = 2.0 * float(jaxclear.get_parameter(mechanism, f"{joint}.bearing_radius"))
            if not math.isclose(d.diameter, bearing, rel_tol=DIAMETER_MISMATCH):
                out.append(
                    f"note: {name} fit {d.fit} is for a {d.diameter * 1e3:g} mm diameter, and "
                    f"joint {joint}'s bearing diameter is {bearing * 1e3:g} mm"
                )
    return out


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """Run ``jaxclear montecarlo``; returns 0, raises ``UsageError`` (2) or ``RunError`` (1)."""
    if args.samples < 1:
        raise UsageError(f"--samples {args.samples}: give 1 or more members")
    if args.seed < 0:
        raise UsageError(f"--seed {args.seed}: give a non-negative integer")
    prepared = prepare(args, "montecarlo")
    settings = prepared.settings
    where = f"[montecarlo] in {settings.config_file!r}" if settings.config_file else "[montecarlo]"
    if not settings.montecarlo:
        raise UsageError(
            "no distributions: give a config file with a [montecarlo] table, e.g. [montecarlo.B] "
            'clearance = { fit = "H7/g6", diameter = 0.02 } (see jaxclear montecarlo --help)'
        )
    dists = distributions(settings.montecarlo, prepared.mechanism, where)
    say = (lambda *a, **k: None) if args.quiet else print
    say(
        f"jaxclear {jaxclear.__version__}: Monte Carlo, {args.samples} members of "
        f"{settings.mechanism} (seed {args.seed}), {prepared.t1:.6g} s, {prepared.num_points} "
        f"points, statistics from {prepared.statistics_start:.6g} s, solver "
        f"{prepared.solver.method}; drawn: {', '.join(dists)}"
    )
    for line in notes(dists, prepared.mechanism):
        say(line)
    if args.member is not None:
        values = jaxclear.studies.draw(dists, args.samples, args.seed)
        return replay(prepared, args, argv, values, SAMPLES_CSV, "montecarlo", say)

    def call(**options):
        return jaxclear.montecarlo(
            prepared.mechanism, dists, args.samples, prepared.t1, seed=args.seed, **options
        )

    outcome = run_engine(prepared, args, call, args.samples, SAMPLES_CSV, say)
    info = base_info(prepared, outcome, argv, SUMMARY_FORMAT)
    info.update(
        kind="montecarlo",
        distributions={n: d.describe() for n, d in dists.items()},
        seed=args.seed,
        samples=args.samples,
    )
    return finish(
        outcome,
        info,
        SUMMARY_JSON,
        SAMPLES_CSV,
        "montecarlo",
        settings.config["output"]["plots"],
        say,
    )
