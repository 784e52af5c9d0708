"""Command line: ``jaxclear run [CONFIG.toml] [options] --out DIR``.

Settings come from three layers, later ones winning: built-in defaults < the TOML config file <
command-line options. Every setting is declared once in ``SETTINGS`` (section, key, type, default,
unit, help, optional command-line flag); the argument parser, the TOML checks, ``--help`` and the
README table are all driven by it, so a new option is one ``Setting`` plus its use in ``_build``.

Exit codes: 0 success; 1 the simulation failed or results could not be written; 2 bad input
(unknown option or config key, wrong type, malformed TOML, invalid value, mechanism that cannot be
built or assembled). Errors are one line on stderr: ``jaxclear: error: <what is wrong and how to
fix it>``.
"""

import argparse
import contextlib
import dataclasses
import difflib
import io
import math
import os
import sys
import time
import tomllib
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

PROG = "jaxclear"
EXIT_FAILURE = 1
EXIT_USAGE = 2
WARMUP_FRACTION = 1e-3
"""The warm-up (compile) call integrates this fraction of the horizon; see ``_timed_simulate``."""


class UsageError(Exception):
    """Bad input: reported as one line, exit code 2."""


class RunError(Exception):
    """The run failed: reported as one line, exit code 1."""


# --- settings -----------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Setting:
    """One configurable value.

    Attributes:
        section: TOML table (``mechanism``, ``simulation``, ``solver``, ``output``).
        key: TOML key; also the name used in run.json.
        kind: ``float``, ``int``, ``str``, ``bool``, or ``"gravity"`` (bool or a number).
        default: built-in default (``None``: decided later, e.g. by the solver preset).
        unit: unit shown in help (``""`` if none).
        help: one-line description.
        flag: command-line option (``None``: config file only).
        check: ``"positive"``, ``"nonnegative"``, ``"finite"`` or ``None``.
        flag_help: help of the flag if it differs from ``help``.
    """

    section: str
    key: str
    kind: Any
    default: Any
    unit: str
    help: str
    flag: str | None = None
    check: str | None = None
    flag_help: str | None = None

    @property
    def dest(self) -> str:
        return f"{self.section}__{self.key}"

    @property
    def label(self) -> str:
        return f"[{self.section}] {self.key}"


def _solver_names() -> tuple[str, ...]:
    from ._solver import METHODS, PRESETS

    return ("auto",) + tuple(PRESETS) + tuple(METHODS)


def _solver_help() -> str:
    from ._solver import METHODS, PRESETS

    return (
        f"auto (imex with LuGre friction, else fast: measured fastest), a preset ({', '.join(PRESETS)}) "
        f"or a method ({', '.join(METHODS)})"
    )


def _contact_names() -> str:
    from .contact import CONTACT_LAWS

    return ", ".join(CONTACT_LAWS)


DEFAULT_SOLVER = "auto"
"""Default: ``auto`` = ``jaxclear.recommended_solver``: ``imex`` (KenCarp5, implicit in the internal
states) with LuGre friction, ``fast`` (Tsit5) otherwise. Measured on the default three-joint run
(hybrid + LuGre, 2 revolutions, 2-core machine, fast_compile on): KenCarp5 compile 5.8 s + run
0.77 s (9 424 steps), Tsit5 4.9 s + 1.52 s (48 011 steps), Kvaerno5 (``robust``) 14.2 s + 3.3 s;
KenCarp5 with closed-form stage solves (``jaxclear._imex``, now used) 4.91 s + 0.477 s."""

SETTINGS: tuple[Setting, ...] = (
    # [mechanism]: the benchmark slider-crank, MODEL.md §6
    Setting("mechanism", "rpm", float, 5000.0, "rev/min", "crank speed", "--rpm", "positive"),
    Setting("mechanism", "crank_length", float, 0.05, "m", "crank length O-A", None, "positive"),
    Setting("mechanism", "rod_length", float, 0.12, "m", "connecting-rod length A-B (> crank_length)", None, "positive"),
    Setting("mechanism", "crank_mass", float, 0.30, "kg", "crank mass", None, "positive"),
    Setting("mechanism", "rod_mass", float, 0.21, "kg", "connecting-rod mass", None, "positive"),
    Setting("mechanism", "slider_mass", float, 0.14, "kg", "slider mass", None, "positive"),
    Setting("mechanism", "crank_inertia", float, 1.0e-4, "kg m^2", "crank moment of inertia about its centre of mass", None, "positive"),
    Setting("mechanism", "rod_inertia", float, 2.5e-4, "kg m^2", "rod moment of inertia about its centre of mass", None, "positive"),
    Setting("mechanism", "slider_inertia", float, 1.0e-4, "kg m^2", "slider moment of inertia", None, "positive"),
    Setting("mechanism", "initial_angle", float, 0.0, "rad", "crank angle at t = 0 (0 = outer dead centre)", None, "finite"),
    Setting(
        "mechanism",
        "gravity",
        "gravity",
        False,
        "m/s^2",
        "gravity along -y: true (9.81), false (none) or a magnitude",
        "--gravity",
        "nonnegative",
        flag_help="switch gravity (9.81 m/s^2 along -y) on or off; a different magnitude goes in the config file",
    ),
    # [clearance]: revolute clearance joints, MODEL.md §2-§5
    Setting(
        "clearance", "joints", str, "O,A,B", "",
        "clearance joints among O (ground-crank), A (crank-rod), B (rod-slider), comma-separated, or none",
        "--clearance-joints",
    ),
    Setting("clearance", "clearance", float, 5e-4, "m", "radial clearance c = R_B - R_J", "--clearance", "positive"),
    Setting("clearance", "bearing_radius", float, 0.01, "m", "bearing (hole) radius R_B", None, "positive"),
    Setting("clearance", "pin_length", float, 0.01, "m", "pin length h (cylindrical and foundation laws)", None, "positive"),
    Setting("clearance", "young_modulus", float, 207e9, "Pa", "Young's modulus E of bearing and journal", None, "positive"),
    Setting("clearance", "poisson_ratio", float, 0.3, "", "Poisson's ratio of bearing and journal, in (0, 0.5)", None, "positive"),
    Setting("clearance", "contact", str, "hybrid", "", f"normal contact law: {_contact_names()}", "--contact"),
    Setting("clearance", "restitution", float, 0.9, "", "restitution coefficient c_e in (0, 1] (damped laws)", "--restitution", "positive"),
    Setting("clearance", "gauss_points", int, 3, "", "hybrid law: Gauss points per element m1", None, "positive"),
    Setting("clearance", "elements", int, 10, "", "hybrid law: elements over the contact arc m2", None, "positive"),
    Setting("clearance", "friction", str, "lugre", "", "friction law: none, coulomb, modified-coulomb, lugre", "--friction"),
    Setting(
        "clearance", "friction_coefficient", float, None, "",
        "friction coefficient mu (mu_k for LuGre); default: the law's (0.1)", "--friction-coefficient", "nonnegative",
    ),
    Setting("clearance", "static_friction", float, None, "", "LuGre static coefficient mu_s (default 0.15)", None, "nonnegative"),
    Setting("clearance", "bristle_stiffness", float, None, "1/m", "LuGre sigma0 (default 1e5)", None, "positive"),
    Setting("clearance", "bristle_damping", float, None, "s/m", "LuGre sigma1 (default 316)", None, "nonnegative"),
    Setting("clearance", "stribeck_velocity", float, None, "m/s", "LuGre Stribeck velocity v_s (default 1e-3)", None, "positive"),
    Setting("clearance", "penetration_width", float, 1e-7, "m", "smoothing width of the penetration", None, "positive"),
    Setting("clearance", "memory_width", float, 1e-7, "m", "smoothing width of the impact-velocity memory freeze", None, "positive"),
    Setting("clearance", "velocity_width", float, 1e-5, "m/s", "smoothing width of |v| and sign(v)", None, "positive"),
    Setting("clearance", "memory_rate", float, 1e6, "1/s", "relaxation rate k_m of the impact-velocity memory", None, "positive"),
    Setting(
        "clearance", "continuous_fraction", float, 0.05, "",
        "contact lasting at least this fraction of a crank period counts as continuous (else impact)", None, "positive",
    ),
    # [simulation]
    Setting("simulation", "revolutions", float, 2.0, "rev", "simulated crank revolutions (may be fractional)", "--revolutions", "positive"),
    Setting(
        "simulation",
        "points_per_revolution",
        int,
        360,
        "1/rev",
        "saved instants per crank revolution (output grid)",
        "--points-per-revolution",
        "positive",
    ),
    # [solver]
    Setting(
        "solver",
        "method",
        str,
        DEFAULT_SOLVER,
        "",
        _solver_help(),
        "--solver",
    ),
    Setting("solver", "rtol", float, None, "", "relative tolerance of the adaptive step", "--rtol", "positive"),
    Setting("solver", "atol", float, None, "", "absolute tolerance of the adaptive step", "--atol", "positive"),
    Setting("solver", "max_steps", int, None, "", "most solver steps before giving up", "--max-steps", "positive"),
    Setting(
        "solver",
        "fast_compile",
        bool,
        True,
        "",
        "compile with XLA's CPU fusion emitters off (XLA_FLAGS=--xla_cpu_use_fusion_emitters=false): "
        "measured 5.4 -> 2.2 s XLA time for about a tenth longer runs (Tsit5, three joints)",
        "--fast-compile",
    ),
    # [output]
    Setting("output", "directory", str, "jaxclear-out", "", "output folder, relative to the current directory", "--out"),
    Setting("output", "plots", bool, True, "", "write the PNG plots", "--plots"),
)
SECTIONS = tuple(dict.fromkeys(s.section for s in SETTINGS))
_BY_LABEL = {(s.section, s.key): s for s in SETTINGS}


def _fmt_default(s: Setting) -> str:
    if s.default is None and s.section == "solver":
        from ._solver import PRESETS

        by_value: dict[str, list[str]] = {}
        for name, preset in PRESETS.items():
            by_value.setdefault(f"{getattr(preset, s.key):g}", []).append(name)
        return "preset's: " + ", ".join(f"{'/'.join(names)} {value}" for value, names in by_value.items())
    if s.default is None:
        return "law's default"
    if isinstance(s.default, bool):
        return "true" if s.default else "false"
    return f"{s.default:g}" if isinstance(s.default, float) else str(s.default)


def config_reference() -> str:
    """Text listing every config-file key (used in ``--help`` and the README)."""
    lines = []
    for section in SECTIONS:
        lines.append(f"  [{section}]")
        for s in SETTINGS:
            if s.section != section:
                continue
            unit = f" [{s.unit}]" if s.unit else ""
            flag = f" ({s.flag})" if s.flag else ""
            lines.append(f"    {s.key}{unit} = {_fmt_default(s)}{flag}: {s.help}")
    return "\n".join(lines)


# --- argument parsing ---------------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line and exit code 2."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def _usage_hint(message: str, argv: list[str]) -> str:
    """Add close matches of mistyped options and where to find help."""
    prefix = "unrecognized arguments: "
    if message.startswith(prefix):
        flags = [a for s in SETTINGS if s.flag for a in (s.flag, "--no-" + s.flag[2:])] + ["--no-progress", "--quiet", "--help"]
        guesses = []
        for token in message[len(prefix) :].split():
            match = difflib.get_close_matches(token.split("=")[0], flags, n=1, cutoff=0.75)
            if token.startswith("--") and match:
                guesses.append(f"did you mean {match[0]} for {token}?")
        message = "; ".join([message, *guesses])
    where = "jaxclear run --help" if "run" in argv else "jaxclear --help"
    return f"{message} (see '{where}')"


def _number(kind):
    def convert(text: str):
        try:
            value = kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"needs {what}, got {text!r}") from None
        return value

    return convert


EPILOG = f"""\
config file (TOML; every key optional; command-line options override it):
{config_reference()}

example config:
  [mechanism]
  rpm = 3000
  gravity = true
  [clearance]
  joints = "B"
  contact = "lankarani-nikravesh"
  friction = "modified-coulomb"
  [simulation]
  revolutions = 4
  [solver]
  method = "robust"
  rtol = 1e-8

outputs in --out DIR: results.csv and results.npz (t [s], crank_angle [deg, unwrapped from the
initial angle], slider_x [m], slider_v [m/s], slider_a [m/s^2], crank_torque [N m], <joint>_Fx,
<joint>_Fy [N] for the ideal joints among O, A, B, slider_guide_moment [N m],
slider_guide_normal [N], per clearance joint J: J_ecc_x, J_ecc_y [m], J_penetration [m],
J_penetration_rate [m/s], J_normal_force, J_friction_force, J_tangential_force [N],
J_slip_velocity, J_impact_velocity [m/s], J_friction_state [m] (LuGre only), J_mode (0 free,
1 impact, 2 continuous contact); constraint_violation [m], velocity_violation [m/s]), run.json
(configuration, versions, solver statistics, compile_time_s, run_time_s, clearance_joints,
contact_mode_shares) and PNG plots (with clearance joints also normal_force.png and
orbit_<J>.png, and the other plots show the ideal-joint run dashed grey behind).

exit codes: 0 success, 1 simulation failed, 2 bad input.
"""


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog=PROG,
        allow_abbrev=False,
        description="Simulate planar mechanisms with revolute clearance joints (jaxclear).",
        epilog="Run 'jaxclear run --help' for the options and config-file keys.",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)
    run = sub.add_parser(
        "run",
        allow_abbrev=False,
        help="simulate the benchmark slider-crank and write results and plots",
        description=(
            "Simulate the benchmark slider-crank (crank 0.05 m, rod 0.12 m, revolute joints O, A, B,\n"
            "slider on a guide) driven at constant crank speed, and write results.csv, results.npz,\n"
            "run.json and PNG plots into --out DIR. Defaults: clearance joints O, A, B (c = 0.5 mm,\n"
            "hybrid contact law, LuGre friction), 5000 rpm, 2 revolutions, 360 points per revolution,\n"
            "no gravity, solver 'auto' (imex with LuGre friction, else fast; measured fastest here).\n"
            "'--clearance-joints none' gives ideal joints."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("config", nargs="?", metavar="CONFIG.toml", help="TOML config file (keys below)")
    for s in SETTINGS:
        if s.flag is None:
            continue
        unit = f" [{s.unit}]" if s.unit else ""
        default = "" if s.default is None and s.section != "solver" else f" (default: {_fmt_default(s)})"
        if s.kind is bool or s.kind == "gravity":
            text = s.flag_help or s.help
            run.add_argument(s.flag, dest=s.dest, action=argparse.BooleanOptionalAction, default=None, help=f"{text}{default}")
        elif s.kind is str:
            metavar = {"directory": "DIR", "joints": "LIST", "contact": "LAW", "friction": "LAW"}.get(s.key, "NAME")
            run.add_argument(s.flag, dest=s.dest, default=None, metavar=metavar, help=f"{s.help}{default}")
        else:
            metavar = "N" if s.kind is int else "X"
            run.add_argument(s.flag, dest=s.dest, type=_number(s.kind), default=None, metavar=metavar, help=f"{s.help}{unit}{default}")
    run.add_argument("--no-progress", action="store_true", help="no progress bar (it is shown only on a terminal anyway)")
    run.add_argument("--quiet", "-q", action="store_true", help="print nothing but errors (implies --no-progress)")
    return parser


# --- config file ----------------------------------------------------------------------------------


def _type_ok(s: Setting, value) -> bool:
    if s.kind is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if s.kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if s.kind == "gravity":
        return isinstance(value, int | float)
    return isinstance(value, s.kind)


def _type_name(s: Setting) -> str:
    return {float: "a number", int: "an integer", str: "a string", bool: "true or false", "gravity": "true, false or a number"}[s.kind]


def read_config(path: str) -> dict[tuple[str, str], Any]:
    """Values of a TOML config file keyed by (section, key); raises ``UsageError`` on any problem."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise UsageError(f"config file {path!r} not found; give the path of a TOML file") from None
    except IsADirectoryError:
        raise UsageError(f"config file {path!r} is a directory; give the path of a TOML file") from None
    except OSError as e:
        raise UsageError(f"cannot read config file {path!r}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"config file {path!r} is not valid TOML: {e}") from None
    values = {}
    known_sections = ", ".join(f"[{s}]" for s in SECTIONS)
    for section, table in data.items():
        if not isinstance(table, dict):
            where = next((f"[{x.section}]" for x in SETTINGS if x.key == section), None)
            hint = f"put it under {where}" if where else f"keys belong in the sections {known_sections}"
            raise UsageError(f"top-level key {section!r} in {path!r} is not in a section; {hint}")
        if section not in SECTIONS:
            raise UsageError(f"unknown section [{section}] in {path!r}; known sections: {known_sections}")
        for key, value in table.items():
            s = _BY_LABEL.get((section, key))
            if s is None:
                known = ", ".join(x.key for x in SETTINGS if x.section == section)
                raise UsageError(f"unknown key {key!r} in [{section}] of {path!r}; known keys: {known}")
            if not _type_ok(s, value):
                raise UsageError(f"{s.label} in {path!r} must be {_type_name(s)}, got {value!r}")
            values[(section, key)] = value
    return values


# --- merging and validation -----------------------------------------------------------------------


def resolve_settings(args: argparse.Namespace) -> tuple[dict[str, dict[str, Any]], dict[tuple[str, str], str]]:
    """Defaults < config file < options: ``({section: {key: value}}, {(section, key): source})``."""
    file_values = read_config(args.config) if args.config else {}
    config: dict[str, dict[str, Any]] = {section: {} for section in SECTIONS}
    sources = {}
    for s in SETTINGS:
        value, source = s.default, "default"
        if (s.section, s.key) in file_values:
            value, source = file_values[(s.section, s.key)], f"{s.label} in {args.config!r}"
        cli = getattr(args, s.dest, None) if s.flag else None
        if cli is not None:
            value, source = cli, s.flag
        config[s.section][s.key] = value
        sources[(s.section, s.key)] = source
    for s in SETTINGS:
        _check(s, config[s.section][s.key], sources[(s.section, s.key)])
    return config, sources


def _check(s: Setting, value, source: str) -> None:
    if value is None or s.check is None or isinstance(value, bool):
        return
    if not math.isfinite(value):
        raise UsageError(f"{source} must be finite, got {value!r}")
    if s.check == "positive" and not value > 0:
        raise UsageError(f"{source} must be positive, got {value!r}")
    if s.check == "nonnegative" and not value >= 0:
        raise UsageError(f"{source} must be zero or positive, got {value!r}")


def _solver(config: dict, sources: dict, mechanism=None):
    """The run's SolverConfig; ``auto`` is decided from ``mechanism`` (``recommended_solver``)."""
    from ._solver import recommended_solver, solver_config

    section = config["solver"]
    name = section["method"]
    if name == "auto":
        name = recommended_solver(mechanism).method if mechanism is not None else "fast"
    if name not in _solver_names():
        source = sources[("solver", "method")]
        raise UsageError(f"{source}: solver {name!r} is unknown; choose a {_solver_help()}")
    solver = solver_config(name)
    changes = {k: section[k] for k in ("rtol", "atol", "max_steps") if section[k] is not None}
    changes = {k: float(v) if k != "max_steps" else v for k, v in changes.items()}
    return solver.replace(**changes) if changes else solver


def _clearance_names(config: dict) -> list[str]:
    text = config["clearance"]["joints"].strip()
    if text.lower() in ("", "none"):
        return []
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in ("O", "A", "B")]
    if bad or len(set(names)) != len(names):
        raise UsageError(f"--clearance-joints must list distinct joints among O, A, B (or 'none'), got {text!r}")
    return names


def _clearance_options(config: dict) -> dict:
    """ClearanceJoint options (geometry, laws, smoothing) from the [clearance] settings."""
    from .contact import CONTACT_LAWS, ContactGeometry, Smoothing, contact_law_from_name
    from .friction import FRICTION_LAWS, friction_law_from_name

    c = config["clearance"]
    if c["contact"] not in CONTACT_LAWS:
        raise UsageError(f"--contact {c['contact']!r} is unknown; choose one of {', '.join(CONTACT_LAWS)}")
    if c["friction"] not in FRICTION_LAWS:
        raise UsageError(f"--friction {c['friction']!r} is unknown; choose one of {', '.join(FRICTION_LAWS)}")
    if c["clearance"] >= c["bearing_radius"]:
        raise UsageError(f"clearance {c['clearance']} m must be smaller than bearing_radius {c['bearing_radius']} m")
    geometry = ContactGeometry(
        c["bearing_radius"], c["bearing_radius"] - c["clearance"], length=c["pin_length"],
        bearing_young=c["young_modulus"], journal_young=c["young_modulus"],
        bearing_poisson=c["poisson_ratio"], journal_poisson=c["poisson_ratio"],
    )
    contact_cls = CONTACT_LAWS[c["contact"]]
    fields = {f.name for f in dataclasses.fields(contact_cls)}
    contact_params = {"restitution": c["restitution"]} if "restitution" in fields else {}
    if "num_gauss_points" in fields:
        contact_params.update(num_gauss_points=c["gauss_points"], num_elements=c["elements"])
    friction_cls = FRICTION_LAWS[c["friction"]]
    ffields = {f.name for f in dataclasses.fields(friction_cls)}
    mu = c["friction_coefficient"]
    friction_params = {}
    if mu is not None:
        key = "kinetic_friction" if "kinetic_friction" in ffields else "friction_coefficient"
        if key not in ffields:
            raise UsageError(f"--friction-coefficient does not apply to friction law {c['friction']!r}")
        friction_params[key] = mu
    for key in ("static_friction", "bristle_stiffness", "bristle_damping", "stribeck_velocity"):
        if c[key] is not None:
            if key not in ffields:
                raise UsageError(f"[clearance] {key} applies to the lugre friction law only")
            friction_params[key] = c[key]
    smoothing = Smoothing(
        penetration_width=c["penetration_width"], memory_width=c["memory_width"],
        velocity_width=c["velocity_width"], memory_rate=c["memory_rate"],
    )
    return dict(
        geometry=geometry,
        contact_law=contact_law_from_name(c["contact"], **contact_params),
        friction_law=friction_law_from_name(c["friction"], **friction_params),
        smoothing=smoothing,
    )


def _mechanism(config: dict, clearance: bool = True):
    from .mechanisms import slider_crank

    m = dict(config["mechanism"])
    gravity = m.pop("gravity")
    names = _clearance_names(config) if clearance else []
    options = _clearance_options(config) if names else {}
    return slider_crank(
        **{k: float(v) for k, v in m.items()},
        gravity=gravity if isinstance(gravity, bool) else float(gravity),
        clearance_joints=names,
        **options,
    )


def _grid(config: dict) -> tuple[float, int]:
    """(end time in s, number of saved instants)."""
    rpm = config["mechanism"]["rpm"]
    revolutions = config["simulation"]["revolutions"]
    intervals = max(1, round(revolutions * config["simulation"]["points_per_revolution"]))
    return 60.0 * revolutions / rpm, intervals + 1


# --- running ----------------------------------------------------------------------------------------


def _block(traj):
    import jax

    jax.block_until_ready(traj.t)
    return traj


def _timed_simulate(mechanism, t1: float, num_points: int, solver, progress: bool):
    """Simulate, timing compilation and the run separately.

    A warm-up call over ``WARMUP_FRACTION`` of the horizon, with the same number of output points,
    solver settings and progress setting, triggers the one compilation (the end time is a traced
    value, so the full run reuses the compiled code); its wall time is ``compile_time_s`` (tracing,
    XLA compilation, assembly and a negligible solve). The full call is then timed alone as
    ``run_time_s``.
    """
    from ._simulate import simulate

    start = time.perf_counter()
    sink = io.StringIO()
    with contextlib.redirect_stderr(sink):  # keep the warm-up's progress bar off the terminal
        _block(simulate(mechanism, t1 * WARMUP_FRACTION, num_points=num_points, solver=solver, progress=progress, throw=False))
    compile_time = time.perf_counter() - start
    start = time.perf_counter()
    traj = _block(simulate(mechanism, t1, num_points=num_points, solver=solver, progress=progress, throw=False))
    return traj, compile_time, time.perf_counter() - start


def _mode_shares(traj, config: dict) -> dict:
    """Time share of each combination of contact modes over the saved instants (MODEL.md §7)."""
    from ._outputs import clearance_joint_names
    from .analysis import combination_shares, trajectory_modes

    modes = trajectory_modes(traj, config["clearance"]["continuous_fraction"])
    return combination_shares({name: modes[name] for name in clearance_joint_names(traj)})  # O, A, B order


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return text or type(error).__name__


def _run(args: argparse.Namespace, argv: list[str]) -> int:
    from . import __version__
    from ._errors import AssemblyError, ModelError, SimulationError
    from ._outputs import RUN_FORMAT, package_versions, write_results

    config, sources = resolve_settings(args)
    _solver(config, sources)  # reject a bad solver name before any work
    fast_compile = apply_fast_compile(config["solver"]["fast_compile"])  # before JAX's backend starts
    try:
        mechanism = _mechanism(config)
    except (ModelError, ValueError, TypeError) as e:
        raise UsageError(f"invalid mechanism: {_one_line(e)}") from None
    solver = _solver(config, sources, mechanism)
    t1, num_points = _grid(config)
    out_dir = Path(config["output"]["directory"])
    if out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"--out {str(out_dir)!r} exists and is not a folder; choose another path")
    quiet = args.quiet
    progress = not (quiet or args.no_progress) and sys.stderr.isatty()
    say = (lambda *a, **k: None) if quiet else print
    rpm, revs = config["mechanism"]["rpm"], config["simulation"]["revolutions"]
    names = _clearance_names(config)
    cl = config["clearance"]
    joints_text = (
        f"clearance joints {','.join(names)} (c = {cl['clearance'] * 1e3:g} mm, {cl['contact']} contact, "
        f"{'no' if cl['friction'] == 'none' else cl['friction']} friction)"
        if names
        else "ideal joints"
    )
    say(
        f"jaxclear {__version__}: slider-crank, {joints_text}, {rpm:g} rpm, {revs:g} rev "
        f"({t1:.6g} s, {num_points} points), solver {config['solver']['method']} "
        f"({solver.method}, rtol {solver.rtol:g}, atol {solver.atol:g})"
    )
    say("compiling (one-off) and simulating ...", flush=True)
    try:
        traj, compile_time, run_time = _timed_simulate(mechanism, t1, num_points, solver, progress)
    except AssemblyError as e:
        raise UsageError(f"the mechanism cannot be assembled: {_one_line(e)}") from None
    except ModelError as e:
        raise UsageError(f"invalid mechanism: {_one_line(e)}") from None
    except SimulationError as e:
        raise RunError(_one_line(e)) from None
    failure = None
    if not bool(traj.succeeded):
        # keep what was computed: the saved instants before the failure are written as usual,
        # run.json says status "failed" with the solver's message, and the exit code is 1
        from ._simulate import failure_error

        failure = failure_error(traj, solver)
        traj = traj.truncated()

    reference = None
    if names and config["output"]["plots"] and failure is None:
        say("ideal-joint reference run for the plots ...", flush=True)
        from ._simulate import simulate

        reference = _block(simulate(_mechanism(config, clearance=False), t1, num_points=num_points, solver="fast"))
    files = []
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        if config["output"]["plots"]:
            from .plot import save_standard_plots

            files = [p.name for p in save_standard_plots(traj, out_dir, reference=reference)]
        import jax

        info = dict(
            format=RUN_FORMAT,
            status="complete" if failure is None else "failed",
            error=None if failure is None else _one_line(failure),
            created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            command=[PROG, *argv],
            config_file=str(Path(args.config).resolve()) if args.config else None,
            config=config,
            sources={f"{sec}.{key}": src for (sec, key), src in sources.items()},
            mechanism="slider_crank",
            clearance_joints=names,
            contact_mode_shares=_mode_shares(traj, config) if names else {},
            t_end_s=t1,
            num_points=num_points,
            solver={f.name: getattr(solver, f.name) for f in dataclasses.fields(solver)},
            stats=traj.stats(),
            compile_time_s=compile_time,
            run_time_s=run_time,
            fast_compile=fast_compile,
            timing=(
                "compile_time_s: wall time of a warm-up simulate call over "
                f"{WARMUP_FRACTION:g} of the horizon with identical shapes and settings (tracing, XLA "
                "compilation, assembly and a negligible solve); run_time_s: wall time of the full "
                "simulate call afterwards, which reuses the compiled code."
            ),
            versions=package_versions(),
            jax_backend=jax.default_backend(),
            files=files,
        )
        paths = write_results(out_dir, traj, info, config["clearance"]["continuous_fraction"])
    except OSError as e:
        raise RunError(f"cannot write results to {str(out_dir)!r}: {e.strerror or e}; choose another --out folder") from None

    stats = traj.stats()
    acc = np.asarray(traj.accelerations("slider"))[:, 0]
    torque = np.asarray(traj.input_torque)
    say(
        f"compile {compile_time:.2f} s, run {run_time:.3f} s, {stats['num_steps']} steps "
        f"({stats['num_rejected_steps']} rejected)"
    )
    say(
        f"slider acceleration {acc.min():.6g} .. {acc.max():.6g} m/s^2; crank torque {torque.min():.6g} .. "
        f"{torque.max():.6g} N m; max constraint violation {float(np.max(traj.constraint_violation)):.3g} m"
    )
    say(f"wrote {', '.join(sorted([p.name for p in paths.values()] + files))} to {out_dir}/")
    if failure is not None:
        raise RunError(
            f"{_one_line(failure)} Partial results up to t = {float(traj.t[-1]):.6g} s are in {out_dir}/ "
            "(run.json status 'failed')."
        )
    return 0


FAST_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"


def apply_fast_compile(on: bool) -> str:
    """Add ``FAST_COMPILE_FLAG`` to XLA_FLAGS if ``on`` and JAX's backend has not started yet.

    XLA reads its flags once, when the backend starts (the first array is made); this runs before.
    Returns what happened, for run.json: ``"on"``, ``"off"``, ``"set by XLA_FLAGS"`` or
    ``"not applied: JAX backend already started"`` (e.g. ``main()`` called from a Python process
    that already used JAX).
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags:
        return "set by XLA_FLAGS"
    if not on:
        return "off"
    try:
        from jax._src import xla_bridge

        started = xla_bridge.backends_are_initialized()
    except (ImportError, AttributeError):  # private API: assume started, change nothing
        started = True
    if started:
        return "not applied: JAX backend already started"
    os.environ["XLA_FLAGS"] = f"{flags} {FAST_COMPILE_FLAG}".strip()
    return "on"


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxclear`` command. Returns 0; on error raises ``SystemExit`` (1 or 2)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        try:
            args = build_parser().parse_args(argv)
        except UsageError as e:
            raise UsageError(_usage_hint(str(e), argv)) from None
        if args.command == "run":
            return _run(args, argv)
        raise UsageError(f"unknown command {args.command!r}")  # unreachable: argparse checks choices
    except UsageError as e:
        _fail(str(e), EXIT_USAGE)
    except RunError as e:
        _fail(str(e), EXIT_FAILURE)
    except KeyboardInterrupt:
        _fail("interrupted", 130)
    except Exception as e:  # one line for anything unexpected; JAXCLEAR_TRACEBACK=1 shows it all
        if os.environ.get("JAXCLEAR_TRACEBACK"):
            raise
        _fail(f"{type(e).__name__}: {_one_line(e)} (set JAXCLEAR_TRACEBACK=1 for the traceback)", EXIT_FAILURE)


def _fail(message: str, code: int) -> NoReturn:
    print(f"{PROG}: error: {' '.join(message.split())}", file=sys.stderr)
    raise SystemExit(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
