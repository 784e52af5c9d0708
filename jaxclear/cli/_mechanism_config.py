"""Mechanisms from the config file: a benchmark by name, or any planar mechanism described in TOML.

A custom mechanism (``[mechanism] name = "custom"``, the default when the file has ``[bodies]``)::

    [ground.points]            # points fixed in the global frame, m
    O = [0.0, 0.0]
    [bodies.crank]             # one table per moving body
    mass = 0.3                 # kg
    inertia = 1e-4             # kg m^2 about the centre of mass
    position = [0.025, 0.0, 0.0]   # initial pose (x, y, phi) of the centre of mass, m, m, rad
    velocity = [0.0, 0.0, 0.0]     # optional initial guess, refined by assembly
    [bodies.crank.points]      # points in the body frame, m
    O = [-0.025, 0.0]
    A = [0.025, 0.0]
    [joints.O]                 # revolute: the two points coincide
    type = "revolute"
    between = ["ground.O", "crank.O"]
    [joints.guide]             # translational: the first point slides along axis fixed in the second body
    type = "translational"
    between = ["slider.C", "ground.G"]
    axis = [1.0, 0.0]
    [driver]                   # constant speed [mechanism] rpm
    body = "crank"
    [springs.k]                # linear spring-damper between two points
    between = ["ground.S", "rocker.S"]
    stiffness = 2000.0         # N/m
    [loads.F]                  # constant force at a point, or constant torque on a body
    type = "force"
    at = "slider.C"
    force = [-50.0, 0.0]

A point is ``"<body>.<point>"``. The schema below (``TABLES``) is the reference of every key; the
error for a bad entry names its table and key and says how to fix it (``UsageError``, exit 2).
"""

import dataclasses
import math
from typing import Any

import equinox as eqx

import jaxclear

from ..contact import (
    CONTACT_LAWS,
    ContactGeometry,
    Smoothing,
    contact_law_from_name,
)
from ..friction import FRICTION_LAWS, friction_law_from_name
from ..mechanisms import FLORES_LEINE_GLOCKER_SLIDER
from ..model._translational_clearance import (
    DEFAULT_CORNER_RESTITUTION,
    DEFAULT_CORNER_STIFFNESS,
    TranslationalClearanceJoint,
)
from ._common import UsageError, one_line
from ._config import Settings
from ._settings import PER_JOINT
from ._tables import LUBRICATION_KEYS, Field, lubrication_from_table
from ._tables import check_keys as _check_keys
from ._tables import fail as _fail
from ._tables import number as _number

TABLES: dict[str, tuple[Field, ...]] = {
    "ground": (
        Field(
            "points", "points", "m", "points fixed in the global frame, name = [x, y]", False, "{}"
        ),
    ),
    "bodies.<name>": (
        Field("mass", "number", "kg", "mass m (> 0)"),
        Field("inertia", "number", "kg m^2", "moment of inertia J about the centre of mass (> 0)"),
        Field(
            "position",
            "vector3",
            "m, m, rad",
            "initial pose (x, y, phi) of the centre of mass; refined by assembly",
        ),
        Field(
            "velocity",
            "vector3",
            "m/s, m/s, rad/s",
            "initial velocity guess; refined by assembly",
            False,
            "[0, 0, 0]",
        ),
        Field("points", "points", "m", "points in the body frame, name = [x, y]", False, "{}"),
    ),
    "joints.<name>": (
        Field("type", "string", "", "revolute or translational"),
        Field(
            "between", "pair", "", 'two points ["body.point", "body.point"] on two different bodies'
        ),
        Field(
            "axis",
            "vector2",
            "",
            "translational: guide direction in the second body's frame",
            False,
            "[1, 0]",
        ),
        Field(
            "angle",
            "number",
            "rad",
            "translational: relative angle phi_1 - phi_2 the joint holds",
            False,
            "0",
        ),
    ),
    "driver": (
        Field(
            "body",
            "string",
            "",
            "driven body; turns at [mechanism] rpm from its initial pose angle",
        ),
        Field("relative_to", "string", "", "reference body of the driven angle", False, "ground"),
    ),
    "springs.<name>": (
        Field("between", "pair", "", "the two attachment points"),
        Field(
            "stiffness",
            "number",
            "N/m",
            "k (>= 0); tension k (length - free_length) + damping rate",
        ),
        Field("damping", "number", "N s/m", "c (>= 0)", False, "0"),
        Field("free_length", "number", "m", "free length (>= 0)", False, "0"),
    ),
    "loads.<name>": (
        Field("type", "string", "", "force or torque"),
        Field("at", "string", "", 'force: point "body.point" where it acts'),
        Field("force", "vector2", "N", "force: global components (fx, fy)"),
        Field("body", "string", "", "torque: body it acts on"),
        Field("torque", "number", "N m", "torque: counter-clockwise positive"),
    ),
}
"""Schema of the custom-mechanism tables (docs/cli.md lists the same)."""

LOAD_KEYS = {"force": ("type", "at", "force"), "torque": ("type", "body", "torque")}

# --- benchmark mechanisms -----------------------------------------------------------------------


def build_mechanism(settings: Settings, clearance: bool = True):
    """The run's ``Mechanism``.

    Args:
        settings: resolved settings (``[mechanism]``, ``[clearance]``, per-joint tables, description).
        clearance: ``False`` for the ideal-joint mechanism (the plots' reference).

    Raises:
        UsageError: a bad description, unknown or translational clearance joint, bad law option,
            or any ``ModelError`` / ``ValueError`` raised while building (named by its entry).
    """
    name = settings.mechanism
    ideal = _custom(settings) if name == "custom" else _benchmark(settings, {})
    names = clearance_joint_names(settings, ideal) if clearance else []
    if not names:
        return ideal
    sliders = translational_names(ideal)
    spec = {
        joint: translational_options(settings, joint)
        if joint in sliders
        else joint_options(settings, joint)
        for joint in names
    }
    films = {joint: spec[joint].pop("lubrication", None) for joint in names}
    mechanism = _custom(settings, spec) if name == "custom" else _benchmark(settings, spec)
    return with_lubrication(mechanism, films)


def translational_names(mechanism) -> list[str]:
    """Names of the ideal translational joints of ``mechanism`` (those a clearance can replace)."""
    return [j.name for j in mechanism.joints if isinstance(j, jaxclear.TranslationalJoint)]


def with_lubrication(mechanism, films: dict):
    """``mechanism`` with the clearance joints named in ``films`` given their ``Lubrication``
    (``None``: the joint stays dry)."""
    for k, joint in enumerate(mechanism.clearance_joints):
        film = films.get(joint.name)
        if film is not None:
            mechanism = eqx.tree_at(
                lambda m, k=k: m.clearance_joints[k].lubrication,
                mechanism,
                film,
                is_leaf=lambda x: x is None,
            )
    return mechanism


def _benchmark(settings: Settings, spec: dict):
    name = settings.mechanism
    params = {k: v for k, v in settings.config["mechanism"].items() if k not in ("name", "gravity")}
    gravity = settings.config["mechanism"]["gravity"]
    builder = getattr(jaxclear.mechanisms, name)
    sliders = {k: v for k, v in spec.items() if "half_length" in v}  # translational_options
    revolute = {k: v for k, v in spec.items() if k not in sliders}
    extra = (
        {"translational_clearance": sliders["slider_guide"]} if "slider_guide" in sliders else {}
    )
    try:
        return builder(
            **{k: float(v) for k, v in params.items()},
            gravity=gravity if isinstance(gravity, bool) else float(gravity),
            clearance_joints=revolute,
            **extra,
        )
    except (jaxclear.ModelError, ValueError, TypeError) as e:
        raise UsageError(f"invalid {name}: {one_line(e)}") from None


def clearance_joint_names(settings: Settings, ideal) -> list[str]:
    """The clearance joints of the run, checked against the ideal mechanism's revolute joints.

    Raises:
        UsageError: unknown or repeated joint, a translational joint without its own
            ``[clearance.<joint>] clearance``, or a per-joint table ``[clearance.<joint>]`` for a
            joint that is not listed.
    """
    source = settings.source("clearance", "joints")
    text = settings.config["clearance"]["joints"].strip()
    names = [] if text.lower() == "none" else [n.strip() for n in text.split(",") if n.strip()]
    revolute = [j.name for j in ideal.joints if isinstance(j, jaxclear.RevoluteJoint)]
    # a translational joint takes a translational clearance (docs/model.md §2c) when its own table
    # gives the guide's clearance: the shared [clearance] values describe pins in holes
    guides = [
        n for n in translational_names(ideal) if "clearance" in settings.joint_tables.get(n, {})
    ]
    other = {
        j.name: type(j).__name__
        for j in ideal.joints
        if not isinstance(j, jaxclear.RevoluteJoint) and j.name not in guides
    }
    for joint in names:
        if joint in other:
            hint = (
                f", or to a translational joint given its guide's clearance in a table "
                f"[clearance.{joint}] clearance = c"
                if other[joint] == "TranslationalJoint"
                else ""
            )
            raise UsageError(
                f"{source}: joint {joint!r} is a {other[joint]}; clearance applies to revolute joints only "
                f"({', '.join(revolute) or 'the mechanism has none'}){hint}"
            )
    revolute += guides
    bad = [n for n in names if n not in revolute]
    if bad or len(set(names)) != len(names) or (not names and text.lower() != "none"):
        raise UsageError(
            f"{source} must list distinct joints among {', '.join(revolute)} (or 'none'), got {text!r}"
        )
    if source.startswith("--"):
        return (
            names  # a flag overrides the file's list: per-joint tables of other joints are unused
        )
    for joint in settings.joint_tables:
        if joint not in names:
            where = (
                "is not a joint of the mechanism"
                if joint not in revolute and joint not in other
                else "has no clearance"
            )
            raise UsageError(
                f"[clearance.{joint}] in {settings.config_file!r}: joint {joint!r} {where}; "
                f"add it to [clearance] joints (now {text!r}) or remove the table"
            )
    return names


def joint_options(settings: Settings, joint: str) -> dict:
    """``ClearanceJoint.replacing`` options of one joint: shared [clearance] values overridden by
    ``[clearance.<joint>]``."""
    c: dict[str, Any] = {s.key: settings.config["clearance"].get(s.key) for s in PER_JOINT}
    override = settings.joint_tables.get(joint, {})
    c.update(override)

    def where(key: str) -> str:
        if key in override:
            return f"[clearance.{joint}] {key}"
        return settings.source("clearance", key)

    for key in TRANSLATIONAL_KEYS:
        if override.get(key) is not None:
            raise UsageError(
                f"{where(key)}: applies to translational clearance joints only; {joint!r} is a "
                "revolute joint (its contact stiffness follows from bearing_radius, pin_length, "
                "young_modulus and poisson_ratio)"
            )
    if c["contact"] not in CONTACT_LAWS:
        raise UsageError(
            f"{where('contact')}: contact law {c['contact']!r} is unknown; choose one of {', '.join(CONTACT_LAWS)}"
        )
    if c["friction"] not in FRICTION_LAWS:
        raise UsageError(
            f"{where('friction')}: friction law {c['friction']!r} is unknown; choose one of {', '.join(FRICTION_LAWS)}"
        )
    if c["clearance"] >= c["bearing_radius"]:
        raise UsageError(
            f"{where('clearance')}: clearance {c['clearance']} m at joint {joint} must be smaller than bearing_radius "
            f"{c['bearing_radius']} m"
        )
    if not 0 < c["poisson_ratio"] < 0.5:
        raise UsageError(
            f"{where('poisson_ratio')} must be in (0, 0.5), got {c['poisson_ratio']}; steel is 0.3"
        )
    geometry = ContactGeometry(
        c["bearing_radius"],
        c["bearing_radius"] - c["clearance"],
        length=c["pin_length"],
        bearing_young=c["young_modulus"],
        journal_young=c["young_modulus"],
        bearing_poisson=c["poisson_ratio"],
        journal_poisson=c["poisson_ratio"],
    )
    fields = {f.name for f in dataclasses.fields(CONTACT_LAWS[c["contact"]])}
    contact_params = {"restitution": c["restitution"]} if "restitution" in fields else {}
    if "num_gauss_points" in fields:
        contact_params.update(num_gauss_points=c["gauss_points"], num_elements=c["elements"])
    friction_params = _friction_params(c, where, joint)
    try:
        contact_law = contact_law_from_name(c["contact"], **contact_params)
        friction_law = friction_law_from_name(c["friction"], **friction_params)
    except (jaxclear.ModelError, ValueError, TypeError) as e:
        raise UsageError(f"clearance joint {joint}: {one_line(e)}") from None
    options = dict(
        clearance=c["clearance"],
        geometry=geometry,
        contact_law=contact_law,
        friction_law=friction_law,
        smoothing=_smoothing(c),
    )
    if c.get("journal_body") is not None:
        options["journal_body"] = c["journal_body"]
    if c.get("lubrication") is not None:
        options["lubrication"] = lubrication_from_table(where("lubrication"), c["lubrication"])
    return options


def _smoothing(c: dict) -> Smoothing:
    return Smoothing(
        penetration_width=c["penetration_width"],
        memory_width=c["memory_width"],
        velocity_width=c["velocity_width"],
        memory_rate=c["memory_rate"],
    )


def _friction_params(c: dict, where, joint: str) -> dict:
    """Keyword arguments of the joint's friction law from the resolved per-joint values ``c``."""
    ffields = {f.name for f in dataclasses.fields(FRICTION_LAWS[c["friction"]])}
    friction_params = {}
    if c["friction_coefficient"] is not None:
        key = "kinetic_friction" if "kinetic_friction" in ffields else "friction_coefficient"
        if key not in ffields:
            raise UsageError(
                f"{where('friction_coefficient')} does not apply to friction law {c['friction']!r}"
            )
        friction_params[key] = c["friction_coefficient"]
    for key in ("static_friction", "bristle_stiffness", "bristle_damping", "stribeck_velocity"):
        if c[key] is not None:
            if key not in ffields:
                raise UsageError(
                    f"{where(key)} applies to the lugre friction law only (joint {joint} uses {c['friction']!r})"
                )
            friction_params[key] = c[key]
    return friction_params


CORNER_CONTACT_LAWS = (
    "flores",
    "lankarani-nikravesh",
    "hunt-crossley",
    "gonthier",
    "zhiying-qishao",
    "hertz",
    "impact",
)
"""Contact laws a translational clearance joint accepts (point laws: a corner on a plane); the
first is its default where ``contact`` is not given."""

TRANSLATIONAL_KEYS = {
    "half_length": ("m", "slider half-length a", FLORES_LEINE_GLOCKER_SLIDER["half_length"]),
    "half_height": ("m", "slider half-height b", FLORES_LEINE_GLOCKER_SLIDER["half_height"]),
    "contact_stiffness": ("N/m^n", "corner contact stiffness K", DEFAULT_CORNER_STIFFNESS),
}
"""Per-joint keys of a translational clearance joint besides the shared ones (``clearance`` is the
guide's clearance c, the guide half-width being b + c): unit, meaning, default. They are read
from ``[clearance.<joint>]`` where the settings table declares them (``_settings.PER_JOINT``)."""


def translational_options(settings: Settings, joint: str) -> dict:
    """``TranslationalClearanceJoint.replacing`` options of a translational joint (docs/model.md
    §2c): ``clearance``, ``half_length``, ``half_height``, the corner contact law (``contact``
    among ``CORNER_CONTACT_LAWS``, default flores; ``restitution``; ``contact_stiffness``), the
    friction law and the smoothing widths; shared [clearance] values overridden by
    ``[clearance.<joint>]``.

    Raises:
        UsageError: a contact law that does not apply to a corner, a non-positive length, or a key
            that applies to revolute joints only (``journal_body``, ``lubrication``).
    """
    c: dict[str, Any] = {s.key: settings.config["clearance"].get(s.key) for s in PER_JOINT}
    override = settings.joint_tables.get(joint, {})
    c.update(override)

    def where(key: str) -> str:
        if key in override:
            return f"[clearance.{joint}] {key}"
        return settings.sources.get(("clearance", key), f"[clearance] {key} default")

    for key in ("journal_body", "lubrication"):
        if override.get(key) is not None:
            raise UsageError(
                f"{where(key)}: applies to revolute clearance joints only; {joint!r} is a "
                "translational joint (keys: clearance, half_length, half_height, contact, "
                "restitution, contact_stiffness, friction, ...)"
            )
    contact = c["contact"]
    if contact not in CORNER_CONTACT_LAWS:
        if "contact" not in override and settings.source("clearance", "contact") == "default":
            contact = CORNER_CONTACT_LAWS[0]
        else:
            raise UsageError(
                f"{where('contact')}: contact law {contact!r} does not apply to the corners of "
                f"translational clearance joint {joint!r}; choose one of "
                f"{', '.join(CORNER_CONTACT_LAWS)}"
            )
    if c["friction"] not in FRICTION_LAWS:
        raise UsageError(
            f"{where('friction')}: friction law {c['friction']!r} is unknown; choose one of {', '.join(FRICTION_LAWS)}"
        )
    sizes = {key: c.get(key) for key in TRANSLATIONAL_KEYS}
    sizes = {
        key: TRANSLATIONAL_KEYS[key][2] if value is None else value for key, value in sizes.items()
    }
    for key, value in (("clearance", c["clearance"]), *sizes.items()):
        if not value > 0:
            raise UsageError(
                f"{where(key)} must be positive, got {value} ({TRANSLATIONAL_KEYS.get(key, ('m', 'guide clearance c'))[1]})"
            )
    fields = {f.name for f in dataclasses.fields(CONTACT_LAWS[contact])}
    contact_params: dict[str, Any] = {"stiffness": sizes["contact_stiffness"]}
    if "restitution" in fields:
        given = (
            "restitution" in override or settings.source("clearance", "restitution") != "default"
        )
        # the shared default restitution describes pins in holes, as the shared contact law does
        contact_params["restitution"] = c["restitution"] if given else DEFAULT_CORNER_RESTITUTION
    try:
        contact_law = contact_law_from_name(contact, **contact_params)
        friction_law = friction_law_from_name(c["friction"], **_friction_params(c, where, joint))
    except (jaxclear.ModelError, ValueError, TypeError) as e:
        raise UsageError(f"clearance joint {joint}: {one_line(e)}") from None
    return dict(
        clearance=c["clearance"],
        half_length=sizes["half_length"],
        half_height=sizes["half_height"],
        contact_law=contact_law,
        friction_law=friction_law,
        smoothing=_smoothing(c),
    )


# --- custom mechanisms ----------------------------------------------------------------------------


def _vector(where: str, value, size: int) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != size:
        _fail(where, f"must be a list of {size} numbers, got {value!r}")
    return tuple(_number(where, v) for v in value)


def _fields(table_name: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    fields = TABLES[table_name]
    return tuple(f.key for f in fields), tuple(f.key for f in fields if f.required)


class _Points:
    """Named points of ground and the bodies; resolves ``"body.point"`` references."""

    def __init__(self, description: dict):
        self.points: dict[str, dict[str, tuple[float, float]]] = {"ground": {}}
        ground = description.get("ground", {})
        allowed, required = _fields("ground")
        _check_keys("[ground]", ground, allowed, required)
        self.points["ground"] = self._table("[ground] points", ground.get("points", {}))

    def _table(self, where: str, table) -> dict:
        if not isinstance(table, dict):
            _fail(where, f"must be a table of name = [x, y], got {table!r}")
        return {name: _vector(f"{where} {name}", value, 2) for name, value in table.items()}

    def add_body(self, name: str, table: dict) -> None:
        self.points[name] = self._table(f"[bodies.{name}] points", table)

    def resolve(self, where: str, reference) -> tuple[str, tuple[float, float]]:
        """(body, local point) of ``"body.point"``."""
        if not isinstance(reference, str) or "." not in reference:
            _fail(where, f'a point is written "body.point", got {reference!r}')
        body, point = reference.rsplit(".", 1)
        if body not in self.points:
            _fail(
                where, f"unknown body {body!r} in {reference!r}; bodies: {', '.join(self.points)}"
            )
        if point not in self.points[body]:
            known = ", ".join(self.points[body]) or "none"
            table = "[ground.points]" if body == "ground" else f"[bodies.{body}.points]"
            _fail(
                where,
                f"missing point {point!r} on {body!r} in {reference!r}; add it to {table} (its points: {known})",
            )
        return body, self.points[body][point]

    def pair(self, where: str, value) -> tuple[tuple[str, tuple], tuple[str, tuple]]:
        if not isinstance(value, list) or len(value) != 2:
            _fail(where, f'must be two points ["body.point", "body.point"], got {value!r}')
        first, second = self.resolve(where, value[0]), self.resolve(where, value[1])
        if first[0] == second[0]:
            _fail(
                where,
                f"connects body {first[0]!r} to itself; a joint or spring joins two different bodies",
            )
        return first, second


def _named_tables(description: dict, section: str) -> dict:
    tables = description.get(section, {})
    for name, table in tables.items():
        if not isinstance(table, dict):
            _fail(f"[{section}] {name}", f"must be a table [{section}.{name}]")
    return tables


def _custom(settings: Settings, spec: dict | None = None):
    """The custom mechanism; ``spec`` = clearance options by joint name (``None``: ideal joints)."""
    d = settings.description
    points = _Points(d)
    bodies = []
    allowed, required = _fields("bodies.<name>")
    for name, table in _named_tables(d, "bodies").items():
        where = f"[bodies.{name}]"
        _check_keys(where, table, allowed, required)
        if name == "ground":
            _fail(
                where,
                "'ground' is the fixed frame; give its points in [ground.points] and name the body otherwise",
            )
        mass, inertia = (
            _number(f"{where} mass", table["mass"]),
            _number(f"{where} inertia", table["inertia"]),
        )
        for key, value in (("mass", mass), ("inertia", inertia)):
            if not value > 0:
                _fail(f"{where} {key}", f"must be positive, got {value}")
        position = _vector(f"{where} position", table["position"], 3)
        velocity = _vector(f"{where} velocity", table.get("velocity", [0.0, 0.0, 0.0]), 3)
        bodies.append(jaxclear.Body(name, mass, inertia, position=position, velocity=velocity))
        points.add_body(name, table.get("points", {}))
    if not bodies:
        _fail("[bodies]", "a custom mechanism needs at least one [bodies.<name>] table")
    poses = {b.name: b.position for b in bodies}

    joints = []
    allowed, required = _fields("joints.<name>")
    for name, table in _named_tables(d, "joints").items():
        where = f"[joints.{name}]"
        _check_keys(where, table, allowed, required)
        kind = table["type"]
        (body_i, point_i), (body_j, point_j) = points.pair(f"{where} between", table["between"])
        if kind == "revolute":
            extra = [k for k in ("axis", "angle") if k in table]
            if extra:
                _fail(where, f"{', '.join(extra)} apply to translational joints only")
            joints.append(jaxclear.RevoluteJoint(name, body_i, point_i, body_j, point_j))
        elif kind == "translational":
            axis = _vector(f"{where} axis", table.get("axis", [1.0, 0.0]), 2)
            if math.hypot(*axis) == 0:
                _fail(f"{where} axis", "must not be zero")
            angle = _number(f"{where} angle", table.get("angle", 0.0))
            joints.append(
                jaxclear.TranslationalJoint(
                    name, body_i, point_i, body_j, point_j, axis=axis, angle=angle
                )
            )
        else:
            _fail(f"{where} type", f'must be "revolute" or "translational", got {kind!r}')

    if "driver" not in d:
        _fail(
            "[driver]",
            'missing; the run\'s length is in revolutions of a driven body: add [driver] body = "<body>"',
        )
    driver_table = d["driver"]
    allowed, required = _fields("driver")
    _check_keys("[driver]", driver_table, allowed, required)
    body = driver_table["body"]
    relative_to = driver_table.get("relative_to", "ground")
    for key, value in (("body", body), ("relative_to", relative_to)):
        if value not in poses and not (key == "relative_to" and value == "ground"):
            _fail(f"[driver] {key}", f"unknown body {value!r}; bodies: {', '.join(poses)}")
    if body == relative_to:
        _fail(
            "[driver]",
            f"body and relative_to are both {body!r}; a driver turns one body against another",
        )
    initial = float(poses[body][2]) - (
        float(poses[relative_to][2]) if relative_to != "ground" else 0.0
    )
    rpm = settings.config["mechanism"]["rpm"]
    driver = jaxclear.ConstantSpeedDriver(
        body=body, speed=rpm * 2.0 * math.pi / 60.0, initial_angle=initial, relative_to=relative_to
    )

    forces = []
    allowed, required = _fields("springs.<name>")
    for name, table in _named_tables(d, "springs").items():
        where = f"[springs.{name}]"
        _check_keys(where, table, allowed, required)
        (body_i, point_i), (body_j, point_j) = points.pair(f"{where} between", table["between"])
        values = {
            k: _number(f"{where} {k}", table.get(k, 0.0))
            for k in ("stiffness", "damping", "free_length")
        }
        for key, value in values.items():
            if value < 0:
                _fail(f"{where} {key}", f"must be zero or positive, got {value}")
        forces.append(jaxclear.SpringDamper(name, body_i, point_i, body_j, point_j, **values))
    for name, table in _named_tables(d, "loads").items():
        where = f"[loads.{name}]"
        kind = table.get("type")
        if kind not in LOAD_KEYS:
            _fail(f"{where} type", f'must be "force" or "torque", got {kind!r}')
        _check_keys(where, table, LOAD_KEYS[kind], LOAD_KEYS[kind])
        if kind == "force":
            target, point = points.resolve(f"{where} at", table["at"])
            if target == "ground":
                _fail(f"{where} at", "a load on ground does nothing; put it on a moving body")
            forces.append(
                jaxclear.AppliedForce(
                    name, target, point, _vector(f"{where} force", table["force"], 2)
                )
            )
        else:
            target = table["body"]
            if target not in poses:
                _fail(f"{where} body", f"unknown body {target!r}; bodies: {', '.join(poses)}")
            forces.append(
                jaxclear.AppliedTorque(
                    name=name, body=target, torque=_number(f"{where} torque", table["torque"])
                )
            )

    gravity = settings.config["mechanism"]["gravity"]
    g = 9.81 if gravity is True else (0.0 if gravity is False else float(gravity))
    revolute = {j.name: j for j in joints if isinstance(j, jaxclear.RevoluteJoint)}
    try:
        spec = spec or {}
        guides = {j.name: j for j in joints if isinstance(j, jaxclear.TranslationalJoint)}
        sliders = tuple(
            TranslationalClearanceJoint.replacing(guides[name], **options)
            for name, options in spec.items()
            if name in guides
        )
        clearance = jaxclear.mechanisms.make_clearance_joints(
            revolute, {k: v for k, v in spec.items() if k not in guides}, {}, "custom mechanism"
        )
        replaced = {c.name for c in clearance} | {c.name for c in sliders}
        return jaxclear.Mechanism(
            bodies=tuple(bodies),
            joints=tuple(j for j in joints if j.name not in replaced),
            driver=driver,
            forces=tuple(forces),
            clearance_joints=clearance,
            gravity=(0.0, -g),
            translational_clearance_joints=sliders,
        )
    except (jaxclear.ModelError, ValueError, TypeError) as e:
        raise UsageError(f"invalid custom mechanism: {one_line(e)}") from None


def markdown_reference() -> str:
    """The custom-mechanism tables (``TABLES``) and the keys of a per-joint ``lubrication`` table
    (``LUBRICATION_KEYS``) as Markdown (embedded verbatim in docs/cli.md)."""
    out = []
    for table, fields in TABLES.items():
        out += [
            f"### `[{table}]`",
            "",
            "| key | unit | required | description |",
            "| --- | --- | --- | --- |",
        ]
        for f in fields:
            required = "yes" if f.required else f"no (default {f.default})"
            if table == "loads.<name>" and f.key not in ("type",):
                required = f"for type {'force' if f.key in LOAD_KEYS['force'] else 'torque'}"
            out.append(f"| `{f.key}` | {f.unit} | {required} | {f.help} |")
        out.append("")
    out += [
        "### `lubrication = { ... }` in `[clearance.<joint>]`",
        "",
        "| key | unit | required | description |",
        "| --- | --- | --- | --- |",
    ]
    for f in LUBRICATION_KEYS:
        required = "yes" if f.required else f"no (default {f.default})"
        out.append(f"| `{f.key}` | {f.unit} | {required} | {f.help} |")
    return "\n".join(out).rstrip() + "\n"
