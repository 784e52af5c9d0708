"""``jaxclear sweep [CONFIG.toml] --param NAME (--values ... | --range ...)``: one parameter swept."""

import argparse

import numpy as np

import jaxclear

from ..internal import inadmissible_values
from ..studies import EnsembleError, sweep_values
from ._common import UsageError, one_line
from ._ensemble_common import (
    add_ensemble_arguments,
    base_info,
    finish,
    prepare,
    replay,
    run_engine,
)
from ._settings import BY_LABEL, add_setting_arguments, check_value, config_reference
from ._sweep_chaos import add_arguments as add_chaos_arguments
from ._sweep_chaos import check as check_chaos
from ._sweep_chaos import run_stages

DESCRIPTION = """\
Sweep one parameter of the mechanism over given values, everything else nominal: one member per
value, solved together (vectorised chunks spread over the CPU cores or GPUs), and write sweep.csv,
sweep.json and sweep.png into --out DIR.

The mechanism, speed, clearance joints and laws, horizon and solver come from the same config file
and options as 'jaxclear run' (its [montecarlo] table, if any, is ignored). The horizon in seconds
is fixed by the config's rpm and revolutions, also when rpm itself is swept. Members start centred
(--start wall is refused). The same command run again resumes from --out DIR; a changed
configuration is refused. --member K solves value K again by the ensemble's own batched program
and writes what 'jaxclear run' writes into --out DIR/member-K (statistics bitwise equal to its
row)."""

EPILOG = f"""\
parameter names: as jaxclear.parameter_names(mechanism): B.clearance, B.restitution,
B.friction_coefficient, B.young_modulus, rod_mass, slider_mass, rpm, ... (SI units; rpm in rev/min).

examples:
  jaxclear sweep --clearance-joints B --param B.clearance --range 5e-5 5e-4 10 --out sweep-c
  jaxclear sweep --clearance-joints B --param rpm --values 1000 2000 3000 5000 --out sweep-rpm
  jaxclear sweep --clearance-joints B --param B.clearance --range 1e-4 5e-4 9 --sections 30 \
      --lyapunov 4 --out chaos-c

outputs in --out DIR: sweep.csv (one row per value, in order: index, value, statistics including
the contact-mode shares and counts per joint and the share of each combination of joint modes,
solver steps, wall time, status, message), ensemble.json (the engine's manifest, for resuming),
sweep.json (configuration, values, devices, timing, summary, failures, the combinations of
contact modes per value), sweep.png (main statistics against the parameter; failed values
marked), sweep_modes.png (contact-mode shares against the parameter); with --sections N
bifurcation.csv/.png (Poincare section points per value), with --lyapunov N lyapunov.csv/.png
(largest Lyapunov exponent per value). See docs/ensembles.md and docs/chaos.md.

exit codes: 0 at least one value succeeded, 1 all failed, 2 bad input (including an output folder
that holds another configuration).

config file (TOML; every key optional; command-line options override it):
{config_reference()}
"""

SWEEP_JSON = "sweep.json"
SWEEP_CSV = "sweep.csv"
SWEEP_FORMAT = 1


def add_parser(subparsers, parser_class) -> argparse.ArgumentParser:
    """Register the ``sweep`` subcommand."""
    sw = subparsers.add_parser(
        "sweep",
        allow_abbrev=False,
        help="sweep one parameter (clearance, speed, restitution, ...) over values",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sw.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="TOML config file (as for 'run')"
    )
    sw.add_argument(
        "--param",
        required=True,
        metavar="NAME",
        help="the swept parameter, e.g. B.clearance or rpm (jaxclear.parameter_names)",
    )
    values = sw.add_mutually_exclusive_group(required=True)
    values.add_argument(
        "--values",
        nargs="+",
        metavar="V",
        help="the values, SI units, in order; separated by spaces or commas (a first value like "
        "-1e-3 that argparse takes for an option: --values=-1e-3,0,1e-3)",
    )
    values.add_argument(
        "--range",
        nargs=3,
        metavar=("START", "STOP", "N"),
        help="N values evenly spaced from START to STOP (both included)",
    )
    add_chaos_arguments(sw)
    add_setting_arguments(sw, "sweep")
    add_ensemble_arguments(sw)
    return sw


def _values(args: argparse.Namespace) -> np.ndarray:
    try:
        if args.values is not None:
            texts = [t.strip() for v in args.values for t in v.split(",")]
            if not all(texts):
                raise UsageError(
                    f"--values {' '.join(args.values)}: an empty item between commas; give one "
                    "number between each pair of commas"
                )
            try:
                numbers = [float(t) for t in texts]
            except ValueError:
                raise UsageError(
                    f"--values {' '.join(args.values)}: give numbers separated by spaces or commas"
                ) from None
            return sweep_values(values=numbers)
        start, stop, num = args.range
        try:
            start, stop = float(start), float(stop)
        except ValueError:
            raise UsageError(
                f"--range {' '.join(args.range)}: START and STOP must be numbers"
            ) from None
        try:
            count = int(num)
        except ValueError:
            raise UsageError(
                f"--range {' '.join(args.range)}: N must be an integer (the number of values)"
            ) from None
        if count == 1 and start != stop:
            raise UsageError(
                f"--range {' '.join(args.range)}: N = 1 gives START alone and leaves STOP out; "
                "give N >= 2, or one value with --values"
            )
        return sweep_values(start=start, stop=stop, num=count)
    except EnsembleError as e:
        option = "--values" if args.values is not None else "--range"
        raise UsageError(f"{option}: {one_line(e)}") from None


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """Run ``jaxclear sweep``; returns 0, raises ``UsageError`` (2) or ``RunError`` (1)."""
    values = _values(args)
    prepared = prepare(args, "sweep")
    settings = prepared.settings
    try:
        info = jaxclear.parameter_info(prepared.mechanism, args.param)
    except jaxclear.ModelError as e:
        raise UsageError(f"--param: {one_line(e)}") from None
    _check_admissible(prepared.mechanism, args.param, values)
    period = check_chaos(args, prepared.mechanism)
    say = (lambda *a, **k: None) if args.quiet else print
    unit = f" {info.unit}" if info.unit else ""
    say(
        f"jaxclear {jaxclear.__version__}: sweep of {args.param} over {len(values)} values "
        f"({values.min():.6g} .. {values.max():.6g}{unit}), {settings.mechanism}, "
        f"{prepared.t1:.6g} s, {prepared.num_points} points, statistics from "
        f"{prepared.statistics_start:.6g} s, solver {prepared.solver.method}"
    )

    if args.member is not None:
        values_of = {args.param: values}
        return replay(prepared, args, argv, values_of, SWEEP_CSV, "sweep", say)

    def call(**options):
        return jaxclear.sweep(
            prepared.mechanism, args.param, values.tolist(), prepared.t1, **options
        )

    outcome = run_engine(prepared, args, call, len(values), SWEEP_CSV, say)
    summary = base_info(prepared, outcome, argv, SWEEP_FORMAT)
    summary.update(
        kind="sweep", parameter=args.param, unit=info.unit, values=[float(v) for v in values]
    )
    summary.update(_combinations(outcome.result, prepared.mechanism))
    plots = settings.config["output"]["plots"]
    code = finish(outcome, summary, SWEEP_JSON, SWEEP_CSV, "sweep", plots, say)
    run_stages(args, prepared, outcome, values, period, summary, SWEEP_JSON, plots, say)
    return code


def _check_admissible(mechanism, name: str, values: np.ndarray) -> None:
    """Refuse, before anything is solved, values that ``jaxclear run`` would refuse for the same
    parameter (rpm: from ``MIN_RPM`` to ``MAX_RPM``) or that lie outside the parameter's
    admissible range (a negative clearance, a restitution above 1, ...).

    Raises:
        UsageError: naming the first offending value and how many there are.
    """
    if name == "rpm":
        setting = BY_LABEL[("mechanism", "rpm")]
        for v in values:
            check_value(setting, float(v), "--param rpm: a value")
    why = [w for w in inadmissible_values(mechanism, (name,), values[:, None]) if w]
    if why:
        more = (
            f" (and {len(why) - 1} more value{'s' if len(why) > 2 else ''})" if len(why) > 1 else ""
        )
        raise UsageError(f"--param {name}: {why[0]}{more}; sweep admissible values only")


def _combinations(result, mechanism) -> dict:
    """sweep.json's contact modes per value: the combinations that occur, with their time shares
    (from the contacts located in each member's solve)."""
    joints = [j.name for j in mechanism.clearance_joints]
    if not joints:
        return {}
    prefix, suffix = "combination_", "_share"
    names = [n for n in result.statistics if n.startswith(prefix) and n.endswith(suffix)]
    per_value = []
    for i in range(len(result)):
        shares = {
            n[len(prefix) : -len(suffix)]: float(result.statistics[n][i])
            for n in names
            if result.statistics[n][i] > 0
        }
        per_value.append(dict(sorted(shares.items(), key=lambda kv: -kv[1])))
    return {
        "contact_mode_combinations": per_value,
        "combination_rule": (
            f"labels give each joint's mode in the order {'-'.join(joints)}: F free flight, "
            "I impact, C continuous contact; time shares over the kept window, from the contacts "
            "located in each member's solve (failed values: empty)"
        ),
    }
