"""The settings schema: every configurable value of ``jaxclear run``, declared once.

Settings come from three layers, later ones winning: built-in defaults < the TOML config file <
command-line options. Each ``Setting`` names its TOML section and key, type, default, unit, help,
check and optional command-line flag; the argument parser (``add_setting_arguments``), the TOML
checks (``_config.py``), ``--help`` and the reference in docs/cli.md are all driven by it, so a new
option is one ``Setting`` plus its use. Later subcommands (``fit``, ``montecarlo``, ``sweep``) add
their sections here and reuse the shared ones.

The mechanism itself (bodies, points, joints, driver, springs, loads) is described by tables with
names chosen by the user; their schema is in ``_mechanism_config.py``.
"""

import argparse
import dataclasses
import inspect
import math
from collections.abc import Mapping
from typing import Any

from .. import mechanisms as _mechanisms
from ..contact import CONTACT_LAWS
from ..friction import FRICTION_LAWS
from ..solve import METHODS, PRESETS
from ._common import UsageError

MECHANISMS = ("slider_crank", "four_bar", "custom")
"""Mechanisms ``jaxclear run`` builds: the two benchmarks of ``jaxclear.mechanisms`` by name, or
one described in the config file (``custom``)."""

MAX_RPM = 1e5
"""Upper bound of ``rpm`` (rev/min). Linkage studies with clearance joints run at 200-6000 rpm
(docs/model.md §6); 1e5 rpm is 17 times the top of that range and puts accelerations, which grow with
the square of the speed, 400 times above the 5000 rpm benchmark's. A larger value is almost surely
a unit slip (rad/s, rev/h) and would only make the solver grind."""

STARTS = ("wall", "centred")
"""Initial journal positions: on the bearing wall along the ideal joint's reaction
(``jaxclear.wall_start``), or centred in the bearing."""


def _library_defaults(key: str) -> dict[str, Any]:
    """Defaults of ``key`` in the benchmark builders, by mechanism name (read from their signatures,
    so the command line cannot drift from the library)."""
    out = {}
    for name in ("slider_crank", "four_bar"):
        parameter = inspect.signature(getattr(_mechanisms, name)).parameters.get(key)
        if parameter is not None:
            out[name] = parameter.default
    return out


@dataclasses.dataclass(frozen=True)
class Setting:
    """One configurable value.

    Attributes:
        section: TOML table (``mechanism``, ``clearance``, ``simulation``, ``solver``, ``output``).
        key: TOML key; also the name used in run.json.
        kind: ``float``, ``int``, ``str``, ``bool``, or ``"gravity"`` (bool or a number).
        default: built-in default, or a mapping mechanism name -> default where it differs per
            mechanism (``None``: decided later, e.g. by the solver preset or the law).
        unit: unit shown in help (``""`` if none).
        help: one-line description.
        flag: command-line option (``None``: config file only).
        check: ``"positive"``, ``"nonnegative"``, ``"finite"``, ``"fraction"`` (in (0, 1)),
            ``"rpm"`` (positive, at most ``MAX_RPM``) or ``None``.
        flag_help: help of the flag if it differs from ``help``.
        mechanisms: the mechanisms the key applies to (``None``: all).
        choices: allowed values of a string setting (``None``: any, checked where used).
        shared: allowed in its section's table (for ``[clearance]``: the shared defaults).
        per_joint: allowed in a per-joint table ``[clearance.<joint>]``, where it overrides the shared
            value for that joint.
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
    mechanisms: tuple[str, ...] | None = None
    choices: tuple[str, ...] | None = None
    shared: bool = True
    per_joint: bool = False

    @property
    def dest(self) -> str:
        return f"{self.section}__{self.key}"

    @property
    def label(self) -> str:
        return f"[{self.section}] {self.key}"

    def default_for(self, mechanism: str) -> Any:
        """The default for ``mechanism`` (``None`` where it has none)."""
        if isinstance(self.default, Mapping):
            return self.default.get(mechanism)
        return self.default


def solver_names() -> tuple[str, ...]:
    """Names ``[solver] method`` accepts."""
    return ("auto",) + tuple(PRESETS) + tuple(METHODS)


def solver_help() -> str:
    return (
        f"auto (imex with LuGre friction, else fast: measured fastest), a preset ({', '.join(PRESETS)}) "
        f"or a method ({', '.join(METHODS)})"
    )


DEFAULT_SOLVER = "auto"
"""Default: ``auto`` = ``jaxclear.recommended_solver``: ``imex`` (KenCarp4 since issue 13's work,
KenCarp5 before; implicit in the internal states) with LuGre friction, ``fast`` (Tsit5) otherwise. Measured on the default three-joint run
(hybrid + LuGre, 2 revolutions, 2-core machine, fast_compile on): KenCarp5 compile 5.8 s + run
0.77 s (9 424 steps), Tsit5 4.9 s + 1.52 s (48 011 steps), Kvaerno5 (``robust``) 14.2 s + 3.3 s;
KenCarp5 with closed-form stage solves (``jaxclear.solve._imex``, now used) 4.91 s + 0.477 s."""

SC, FB = ("slider_crank",), ("four_bar",)
BENCHMARKS = ("slider_crank", "four_bar")
_rpm_default = {**_library_defaults("rpm")}
_gravity_default = {**_library_defaults("gravity"), "custom": False}

SETTINGS: tuple[Setting, ...] = (
    # [mechanism]: which mechanism, its speed and gravity; the benchmarks' dimensions (docs/model.md §6)
    Setting(
        "mechanism",
        "name",
        str,
        None,
        "",
        "slider_crank, four_bar, or custom (the mechanism described by [bodies], [joints], [driver], ...); "
        "default: custom when the file has [bodies], else slider_crank",
        "--mechanism",
        choices=MECHANISMS,
    ),
    Setting(
        "mechanism",
        "rpm",
        float,
        _rpm_default,
        "rev/min",
        f"speed of the driven body (at most {MAX_RPM:g}: larger values are unit slips); required for custom",
        "--rpm",
        "rpm",
    ),
    Setting(
        "mechanism",
        "gravity",
        "gravity",
        _gravity_default,
        "m/s^2",
        "gravity along -y: true (9.81), false (none) or a magnitude",
        "--gravity",
        "nonnegative",
        flag_help="switch gravity (9.81 m/s^2 along -y) on or off; a different magnitude goes in the config file",
    ),
    Setting(
        "mechanism",
        "initial_angle",
        float,
        _library_defaults("initial_angle"),
        "rad",
        "crank angle at t = 0 (slider_crank: 0 = outer dead centre)",
        None,
        "finite",
        mechanisms=BENCHMARKS,
    ),
    Setting(
        "mechanism",
        "crank_length",
        float,
        _library_defaults("crank_length"),
        "m",
        "crank length",
        None,
        "positive",
        mechanisms=BENCHMARKS,
    ),
    Setting(
        "mechanism",
        "rod_length",
        float,
        _library_defaults("rod_length"),
        "m",
        "connecting-rod length A-B (> crank_length)",
        None,
        "positive",
        mechanisms=SC,
    ),
    Setting(
        "mechanism",
        "ground_length",
        float,
        _library_defaults("ground_length"),
        "m",
        "distance of the ground pivots O2-O4",
        None,
        "positive",
        mechanisms=FB,
    ),
    Setting(
        "mechanism",
        "coupler_length",
        float,
        _library_defaults("coupler_length"),
        "m",
        "coupler length A-B",
        None,
        "positive",
        mechanisms=FB,
    ),
    Setting(
        "mechanism",
        "rocker_length",
        float,
        _library_defaults("rocker_length"),
        "m",
        "rocker length B-O4",
        None,
        "positive",
        mechanisms=FB,
    ),
    Setting(
        "mechanism",
        "crank_mass",
        float,
        _library_defaults("crank_mass"),
        "kg",
        "crank mass",
        None,
        "positive",
        mechanisms=BENCHMARKS,
    ),
    Setting(
        "mechanism",
        "rod_mass",
        float,
        _library_defaults("rod_mass"),
        "kg",
        "connecting-rod mass",
        None,
        "positive",
        mechanisms=SC,
    ),
    Setting(
        "mechanism",
        "slider_mass",
        float,
        _library_defaults("slider_mass"),
        "kg",
        "slider mass",
        None,
        "positive",
        mechanisms=SC,
    ),
    Setting(
        "mechanism",
        "coupler_mass",
        float,
        _library_defaults("coupler_mass"),
        "kg",
        "coupler mass (J = m L^2/12)",
        None,
        "positive",
        mechanisms=FB,
    ),
    Setting(
        "mechanism",
        "rocker_mass",
        float,
        _library_defaults("rocker_mass"),
        "kg",
        "rocker mass (J = m L^2/12)",
        None,
        "positive",
        mechanisms=FB,
    ),
    Setting(
        "mechanism",
        "crank_inertia",
        float,
        _library_defaults("crank_inertia"),
        "kg m^2",
        "crank moment of inertia about its centre of mass",
        None,
        "positive",
        mechanisms=SC,
    ),
    Setting(
        "mechanism",
        "rod_inertia",
        float,
        _library_defaults("rod_inertia"),
        "kg m^2",
        "rod moment of inertia about its centre of mass",
        None,
        "positive",
        mechanisms=SC,
    ),
    Setting(
        "mechanism",
        "slider_inertia",
        float,
        _library_defaults("slider_inertia"),
        "kg m^2",
        "slider moment of inertia",
        None,
        "positive",
        mechanisms=SC,
    ),
    # [clearance]: revolute clearance joints, docs/model.md §2-§5; [clearance.<joint>] overrides per joint
    Setting(
        "clearance",
        "joints",
        str,
        {"slider_crank": "O,A,B", "four_bar": "none", "custom": "none"},
        "",
        "revolute joints with clearance, comma-separated (slider_crank: O, A, B; four_bar: O2, A, B, O4; "
        "custom: names of [joints] tables), or none for ideal joints",
        "--clearance-joints",
    ),
    Setting(
        "clearance",
        "clearance",
        float,
        5e-4,
        "m",
        "radial clearance c = R_B - R_J",
        "--clearance",
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "journal_body",
        str,
        None,
        "",
        "which of the joint's two bodies carries the pin (journal); the other carries the hole (bearing); "
        "default: the joint's second body (slider_crank B: slider)",
        shared=False,
        per_joint=True,
    ),
    Setting(
        "clearance",
        "bearing_radius",
        float,
        0.01,
        "m",
        "bearing (hole) radius R_B",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "pin_length",
        float,
        0.01,
        "m",
        "pin length h (cylindrical and foundation laws)",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "young_modulus",
        float,
        207e9,
        "Pa",
        "Young's modulus E of bearing and journal",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "poisson_ratio",
        float,
        0.3,
        "",
        "Poisson's ratio of bearing and journal, in (0, 0.5)",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "contact",
        str,
        "hybrid",
        "",
        f"normal contact law: {', '.join(CONTACT_LAWS)}",
        "--contact",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "restitution",
        float,
        0.9,
        "",
        "restitution coefficient c_e in (0, 1] (damped laws)",
        "--restitution",
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "gauss_points",
        int,
        3,
        "",
        "hybrid law: Gauss points per element m1",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "elements",
        int,
        10,
        "",
        "hybrid law: elements over the contact arc m2",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "friction",
        str,
        "lugre",
        "",
        f"friction law: {', '.join(FRICTION_LAWS)}",
        "--friction",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "friction_coefficient",
        float,
        None,
        "",
        "friction coefficient mu (mu_k for LuGre); default: the law's (0.1)",
        "--friction-coefficient",
        "nonnegative",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "static_friction",
        float,
        None,
        "",
        "LuGre static coefficient mu_s (default 0.15)",
        None,
        "nonnegative",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "bristle_stiffness",
        float,
        None,
        "1/m",
        "LuGre sigma0 (default 1e5)",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "bristle_damping",
        float,
        None,
        "s/m",
        "LuGre sigma1 (default 316)",
        None,
        "nonnegative",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "stribeck_velocity",
        float,
        None,
        "m/s",
        "LuGre Stribeck velocity v_s (default 1e-3)",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "penetration_width",
        float,
        1e-7,
        "m",
        "smoothing width of the penetration",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "memory_width",
        float,
        1e-7,
        "m",
        "smoothing width of the impact-velocity memory freeze",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "velocity_width",
        float,
        1e-5,
        "m/s",
        "smoothing width of |v| and sign(v)",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "memory_rate",
        float,
        1e6,
        "1/s",
        "relaxation rate k_m of the impact-velocity memory",
        None,
        "positive",
        per_joint=True,
    ),
    Setting(
        "clearance",
        "continuous_fraction",
        float,
        0.02,
        "",
        "contact lasting at least this fraction of a crank period counts as continuous (else impact); in (0, 1)",
        None,
        "fraction",
    ),
    # [simulation]
    Setting(
        "simulation",
        "revolutions",
        float,
        2.0,
        "rev",
        "simulated revolutions of the driven body (may be fractional)",
        "--revolutions",
        "positive",
    ),
    Setting(
        "simulation",
        "points_per_revolution",
        int,
        360,
        "1/rev",
        "saved instants per revolution (output grid)",
        "--points-per-revolution",
        "positive",
    ),
    Setting(
        "simulation",
        "skip_revolutions",
        float,
        1.0,
        "rev",
        "first revolutions left out of the plots, statistics and contact-mode shares (the start-up transient); "
        "results.csv keeps every instant; must be smaller than revolutions",
        "--skip-revolutions",
        "nonnegative",
    ),
    Setting(
        "simulation",
        "start",
        str,
        "centred",
        "",
        "initial journal positions: centred (eccentricity 0, as measured data may begin) or wall (on the "
        "bearing wall, pushed along the ideal joint's reaction: jaxclear.wall_start; no impact has happened, "
        "so the damped contact laws see the minimum impact velocity and damp heavily while contact lasts)",
        "--start",
        choices=STARTS,
    ),
    # [solver]
    Setting("solver", "method", str, DEFAULT_SOLVER, "", solver_help(), "--solver"),
    Setting(
        "solver",
        "rtol",
        float,
        None,
        "",
        "relative tolerance of the adaptive step",
        "--rtol",
        "positive",
    ),
    Setting(
        "solver",
        "atol",
        float,
        None,
        "",
        "absolute tolerance of the adaptive step",
        "--atol",
        "positive",
    ),
    Setting(
        "solver",
        "max_steps",
        int,
        None,
        "",
        "most solver steps before giving up",
        "--max-steps",
        "positive",
    ),
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
    Setting(
        "solver",
        "compilation_cache",
        bool,
        True,
        "",
        "keep compiled solves in a persistent cache (folder: $JAXCLEAR_CACHE_DIR, else "
        "~/.cache/jaxclear/xla), so a later run of the same configuration loads them instead of "
        "compiling",
        "--compilation-cache",
    ),
    # [output]
    Setting(
        "output",
        "directory",
        str,
        "jaxclear-out",
        "",
        "output folder (created; must be writable)",
        "--out",
    ),
    Setting("output", "plots", bool, True, "", "write the PNG plots", "--plots"),
)
SECTIONS = tuple(dict.fromkeys(s.section for s in SETTINGS))
BY_LABEL = {(s.section, s.key): s for s in SETTINGS}
PER_JOINT = tuple(s for s in SETTINGS if s.per_joint)


def format_default(s: Setting) -> str:
    """The default of ``s`` as shown in ``--help`` and docs/cli.md."""
    if s.default is None and s.section == "solver":
        by_value: dict[str, list[str]] = {}
        for name, preset in PRESETS.items():
            by_value.setdefault(f"{getattr(preset, s.key):g}", []).append(name)
        return "preset's: " + ", ".join(
            f"{'/'.join(names)} {value}" for value, names in by_value.items()
        )
    if s.default is None:
        return "see description"
    if isinstance(s.default, Mapping):
        return ", ".join(f"{name} {_format_value(value)}" for name, value in s.default.items())
    return _format_value(s.default)


def _format_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.10g}"
    return str(value)


def config_reference() -> str:
    """Text listing every key of the settings sections (``--help``; docs/cli.md holds the same)."""
    lines = []
    for section in SECTIONS:
        lines.append(f"  [{section}]")
        for s in SETTINGS:
            if s.section != section:
                continue
            unit = f" [{s.unit}]" if s.unit else ""
            flag = f" ({s.flag})" if s.flag else ""
            where = f" ({', '.join(s.mechanisms)} only)" if s.mechanisms else ""
            scope = (
                " (per-joint table only)"
                if not s.shared
                else (" (also per joint)" if s.per_joint else "")
            )
            lines.append(f"    {s.key}{unit} = {format_default(s)}{flag}{where}{scope}: {s.help}")
    return "\n".join(lines)


# --- checks -----------------------------------------------------------------------------------------


def type_ok(s: Setting, value) -> bool:
    """Whether a TOML value has the type ``s`` needs (bools are not numbers)."""
    if s.kind is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if s.kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if s.kind == "gravity":
        return isinstance(value, int | float)
    return isinstance(value, s.kind)


def type_name(s: Setting) -> str:
    return {
        float: "a number",
        int: "an integer",
        str: "a string",
        bool: "true or false",
        "gravity": "true, false or a number",
    }[s.kind]


def check_value(s: Setting, value, source: str) -> None:
    """Raise ``UsageError`` naming ``source`` if ``value`` fails the setting's check or choices."""
    if value is None:
        return
    if s.choices is not None and value not in s.choices:
        raise UsageError(f"{source} must be one of {', '.join(s.choices)}, got {value!r}")
    if s.kind is str:
        if not value.strip():
            raise UsageError(f"{source} is empty; {_empty_hint(s)}")
        return
    if s.check is None or isinstance(value, bool):
        return
    if not math.isfinite(value):
        raise UsageError(f"{source} must be finite, got {value!r}")
    if s.check in ("positive", "rpm") and not value > 0:
        raise UsageError(f"{source} must be positive, got {value!r}")
    if s.check == "rpm" and value > MAX_RPM:
        raise UsageError(
            f"{source} = {value:g} rev/min is implausible (at most {MAX_RPM:g}; linkages run at 200-6000 rpm); "
            "give the speed in revolutions per minute"
        )
    if s.check == "nonnegative" and not value >= 0:
        raise UsageError(f"{source} must be zero or positive, got {value!r}")
    if s.check == "fraction" and not 0 < value < 1:
        raise UsageError(
            f"{source} must be in (0, 1), got {value!r}; it is a fraction of a crank period"
        )


def _empty_hint(s: Setting) -> str:
    if s.key == "joints":
        return "use 'none' for ideal joints, or list joints like 'O,A,B'"
    if s.key == "directory":
        return "give the path of an output folder"
    if s.choices:
        return f"choose one of {', '.join(s.choices)}"
    return "give a value"


# --- command-line options ---------------------------------------------------------------------------


def _number(kind):
    def convert(text: str):
        try:
            return kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"needs {what}, got {text!r}") from None

    return convert


METAVARS = {
    "directory": "DIR",
    "joints": "LIST",
    "contact": "LAW",
    "friction": "LAW",
    "name": "NAME",
    "start": "HOW",
    "method": "NAME",
}


def add_setting_arguments(
    parser: argparse.ArgumentParser, sections: tuple[str, ...] = SECTIONS
) -> None:
    """Add a flag for every ``Setting`` of ``sections`` that has one (the shared run options).

    Values land in ``args.<section>__<key>`` (``None`` when not given), read by
    ``_config.resolve_settings``.
    """
    for s in SETTINGS:
        if s.flag is None or s.section not in sections:
            continue
        unit = f" [{s.unit}]" if s.unit else ""
        default = (
            ""
            if s.default is None and s.section != "solver"
            else f" (default: {format_default(s)})"
        )
        if s.kind is bool or s.kind == "gravity":
            text = s.flag_help or s.help
            parser.add_argument(
                s.flag,
                dest=s.dest,
                action=argparse.BooleanOptionalAction,
                default=None,
                help=f"{text}{default}",
            )
        elif s.kind is str:
            parser.add_argument(
                s.flag,
                dest=s.dest,
                default=None,
                metavar=METAVARS.get(s.key, "NAME"),
                help=f"{s.help}{default}",
            )
        else:
            metavar = "N" if s.kind is int else "X"
            parser.add_argument(
                s.flag,
                dest=s.dest,
                type=_number(s.kind),
                default=None,
                metavar=metavar,
                help=f"{s.help}{unit}{default}",
            )


def all_flags() -> list[str]:
    """Every settings flag (with the ``--no-`` forms of switches), for 'did you mean' hints."""
    flags = []
    for s in SETTINGS:
        if s.flag:
            flags.append(s.flag)
            if s.kind is bool or s.kind == "gravity":
                flags.append("--no-" + s.flag[2:])
    return flags


def markdown_reference() -> str:
    """The settings reference as Markdown tables, one per section (docs/cli.md embeds it verbatim;
    ``tests/test_cli.py`` checks that it is current)."""
    out = []
    for section in SECTIONS:
        out += [
            f"### `[{section}]`",
            "",
            "| key | unit | default | flag | description |",
            "| --- | --- | --- | --- | --- |",
        ]
        for s in SETTINGS:
            if s.section != section:
                continue
            notes = []
            if s.mechanisms:
                notes.append(f"{' and '.join(s.mechanisms)} only")
            if not s.shared:
                notes.append(f"per-joint table `[{section}.<joint>]` only")
            elif s.per_joint:
                notes.append(f"also in `[{section}.<joint>]`")
            note = f" ({'; '.join(notes)})" if notes else ""
            flag = f"`{s.flag}`" if s.flag else ""
            text = s.help.replace("|", "\\|")
            out.append(f"| `{s.key}` | {s.unit} | {format_default(s)} | {flag} | {text}{note} |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"
