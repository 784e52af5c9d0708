"""The settings table: every configurable value of the commands, declared once (``SETTINGS``).

Settings come from three layers, later ones winning: built-in defaults < the TOML config file <
command-line options. Each ``Setting`` names its TOML section and key, type, default, unit, help,
check and optional command-line flag; the argument parser (``add_setting_arguments``), the TOML
checks (``_config.py``), ``--help`` and the reference in docs/cli.md are all driven by it, so a new
option is one ``Setting`` plus its use. Later subcommands (``fit``, ``montecarlo``, ``sweep``) add
their sections here and reuse the shared ones.

The mechanism itself (bodies, points, joints, driver, springs, loads) is described by tables with
names chosen by the user; their schema is in ``_mechanism_config.py``.
"""

import dataclasses
import inspect
from collections.abc import Mapping
from typing import Any

from .. import mechanisms as _mechanisms
from ..contact import CONTACT_LAWS
from ..friction import FRICTION_LAWS
from ..model._translational_clearance import (
    DEFAULT_CORNER_RESTITUTION,
    DEFAULT_CORNER_STIFFNESS,
)
from ..solve import METHODS, PRESETS

MECHANISMS = ("slider_crank", "four_bar", "custom")
"""Mechanisms ``jaxclear run`` builds: the two benchmarks of ``jaxclear.mechanisms`` by name, or
one described in the config file (``custom``)."""

MAX_RPM = 1e5
"""Upper bound of ``rpm`` (rev/min). Linkage studies with clearance joints run at 200-6000 rpm
(docs/model.md §6); 1e5 rpm is 17 times the top of that range and puts accelerations, which grow with
the square of the speed, 400 times above the 5000 rpm benchmark's. A larger value is almost surely
a unit slip (rad/s, rev/h) and would only make the solver grind."""

MIN_RPM = 1e-2
"""Lower bound of ``rpm`` (rev/min). The solver's steps follow the contacts' time scales
(microseconds to milliseconds), not the crank's, so a revolution costs steps in proportion to its
duration: at 0.01 rev/min one revolution is 6000 s of contact dynamics, about 1000 times the
200 rpm records of docs/identification.md. Below it a linkage is quasi-static, and a subnormal
value overflows the revolution's duration to infinity."""

MAX_HORIZON_REVOLUTIONS = 1000
"""Upper bound of a fixed ``revolutions``. ``jaxclear run`` solves one revolution at a time, about
0.1 s each, and keeps every revolution's results in memory. At 1e9 revolutions each revolution's
contact-event buffer had been sized for the whole horizon (2 TB per joint), and XLA waited forever
for it instead of failing; the buffers are now per revolution (``cli._run.event_capacity``).
Measured peak memory of the default run: 1.01, 1.18 and 1.50 GB at 25, 100 and 200 revolutions
with the whole-horizon buffers, 1.54 GB at 200 with the per-revolution ones (the results
dominate). 1000 revolutions is 12 s of motion at 5000 rpm, 80 times the 12 revolutions of
``auto``'s cap."""

MAX_SAVED_INSTANTS = 10**6
"""Upper bound of revolutions x points_per_revolution (the saved instants of a run): each takes
about 0.6 kB in memory for the benchmark slider-crank with three clearance joints (its
``Trajectory`` arrays), and a row of results.csv. Contact peaks and statistics come from the
solver's steps, not from the saved grid (docs/outputs.md)."""

MAX_STEPS = 10**9
"""Upper bound of ``max_steps`` (per solve): about 15 hours at the ~54 us a step of the default
run (11 894 steps in 0.64 s over its 6 revolutions); values beyond 2**63 do not even fit the solver's step counter."""

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
        kind: ``float``, ``int``, ``str``, ``bool``, ``"gravity"`` (bool or a number),
            ``"revolutions"`` (a number or ``"auto"``), or ``dict``
            (a TOML inline table with its own schema, checked where it is read:
            ``lubrication``, ``_mechanism_config.LUBRICATION_KEYS``).
        default: built-in default, or a mapping mechanism name -> default where it differs per
            mechanism (``None``: decided later, e.g. by the solver preset or the law).
        unit: unit shown in help (``""`` if none).
        help: one-line description.
        flag: command-line option (``None``: config file only).
        check: ``"positive"``, ``"nonnegative"``, ``"finite"``, ``"fraction"`` (in (0, 1)),
            ``"rpm"`` (from ``MIN_RPM`` to ``MAX_RPM``), ``"revolutions"`` (positive, at most
            ``MAX_HORIZON_REVOLUTIONS``), ``"steps"`` (positive, at most ``MAX_STEPS``) or
            ``None``.
        flag_help: help of the flag if it differs from ``help``.
        mechanisms: the mechanisms the key applies to (``None``: all).
        choices: allowed values of a string setting (``None``: any, checked where used).
        shared: allowed in its section's table (for ``[clearance]``: the shared defaults).
        per_joint: allowed in a per-joint table ``[clearance.<joint>]``, where it overrides the shared
            value for that joint.
        command_defaults: ``(command, default)`` pairs where a command's default differs from
            ``default`` (``revolutions``: auto for ``jaxclear run``, a fixed horizon elsewhere).
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
    command_defaults: tuple[tuple[str, Any], ...] = ()

    @property
    def dest(self) -> str:
        return f"{self.section}__{self.key}"

    @property
    def label(self) -> str:
        return f"[{self.section}] {self.key}"

    def default_for(self, mechanism: str, command: str | None = None) -> Any:
        """The default for ``mechanism`` in ``command`` (``None`` where it has none)."""
        for name, value in self.command_defaults:
            if name == command:
                return value
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
"""Default: ``auto`` = ``jaxclear.recommended_solver``: ``imex`` (KenCarp4; implicit in the internal
states) with LuGre friction, ``fast`` (Tsit5) otherwise (measurements: docs/solvers.md, "Choosing
the method")."""

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
        f"speed of the driven body ({MIN_RPM:g} to {MAX_RPM:g}: larger values are unit slips); required for custom",
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
        "lubrication",
        dict,
        None,
        "",
        "hydrodynamic film of a lubricated joint, an inline table { viscosity = ..., length = ..., "
        'theory = "short" } (its keys: docs/cli.md; the model: docs/model.md §3b); absent: a dry joint',
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
    # per-joint keys of a translational clearance joint (docs/model.md §2c; `clearance` is the
    # guide's clearance c, the guide half-width b + c)
    Setting(
        "clearance",
        "half_length",
        float,
        None,
        "m",
        "translational clearance joints: slider half-length a (default "
        f"{_mechanisms.FLORES_LEINE_GLOCKER_SLIDER['half_length']:g} m, the slider of Flores, "
        "Leine & Glocker 2010)",
        None,
        "positive",
        shared=False,
        per_joint=True,
    ),
    Setting(
        "clearance",
        "half_height",
        float,
        None,
        "m",
        "translational clearance joints: slider half-height b; the guide's half-width is b + "
        f"clearance (default {_mechanisms.FLORES_LEINE_GLOCKER_SLIDER['half_height']:g} m)",
        None,
        "positive",
        shared=False,
        per_joint=True,
    ),
    Setting(
        "clearance",
        "contact_stiffness",
        float,
        None,
        "N/m^n",
        "translational clearance joints: stiffness K of the corner contact law K δ^n (a corner on "
        f"a plane has no Hertz stiffness; default {DEFAULT_CORNER_STIFFNESS:g} N/m^1.5 [ours]); "
        f"where the file gives none, their contact law is flores with restitution "
        f"{DEFAULT_CORNER_RESTITUTION:g}",
        None,
        "positive",
        shared=False,
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
        "revolutions",
        2.0,
        "rev",
        "simulated revolutions of the driven body (may be fractional), or auto (jaxclear run "
        "only, its default): until the response settles into a period-k orbit, at most 12 "
        "(docs/outputs.md); the ensembles and fit need a number",
        "--revolutions",
        "revolutions",
        command_defaults=(("run", "auto"),),
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
        "bearing wall, pushed along the ideal joint's reaction: jaxclear.wall_start; no hysteresis damping "
        "until the journal first leaves the wall, docs/model.md §5c)",
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
        "steps",
    ),
    Setting(
        "solver",
        "fast_compile",
        bool,
        False,
        "",
        "compile with XLA's CPU fusion emitters off (XLA_FLAGS=--xla_cpu_use_fusion_emitters=false): "
        "measured 5.4 -> 2.2 s XLA time for about a tenth longer runs (Tsit5, three joints), but then "
        "the solver's steps depend on the number of saved points (docs/outputs.md); off by default, "
        "on for jaxclear fit, whose saved points are the record's (README's fit: 40 -> 27 s cold, "
        "the same estimate to 2e-9)",
        "--fast-compile",
        command_defaults=(("fit", True),),
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
    Setting(
        "output",
        "force",
        bool,
        False,
        "",
        "replace an output folder that holds other results (another command's, another "
        "configuration's, or files without their manifest): it is moved aside first, not deleted",
        "--force",
    ),
)
