"""Mechanism parameters by dotted name: read and replace array leaves, for fits, designs and ensembles.

Names (``parameter_names(mechanism)`` lists those of a given mechanism):

- ``<body>_mass`` (kg), ``<body>_inertia`` (kg m²) of each moving body, e.g. ``rod_mass``;
- ``<body>_com_x``, ``<body>_com_y`` (m): a design change, not a stored value: shift the body's
  centre of mass along its own frame's axes, all its attachment points (joints, clearance joints,
  forces) kept where they are on the body (their local coordinates move by the opposite amount);
  ``get_parameter`` gives 0 (a shift relative to the mechanism it is applied to);
- ``rpm`` (rev/min): speed of a constant-speed driver;
- per clearance joint ``J``: ``J.clearance`` (radial clearance c = R_B − R_J, m; sets the journal
  radius, keeps the bearing radius), ``J.bearing_radius``, ``J.journal_radius``, ``J.length`` (m),
  ``J.young_modulus`` (Pa, both materials), ``J.poisson_ratio`` (both), ``J.bearing_young``,
  ``J.journal_young``, ``J.bearing_poisson``, ``J.journal_poisson``; every scalar array field of its
  contact law (``J.restitution``, ``J.stiffness`` when given, ...), of its friction law
  (``J.friction_coefficient``, ``J.bristle_stiffness``, ...), of its ``Smoothing``
  (``J.penetration_width``, ...) and, for a lubricated joint, of its ``Lubrication``
  (``J.viscosity``, ``J.transition_eccentricity``, ``J.transition_width``, and the bearing length
  as ``J.lubrication.length``, since ``J.length`` is the pin length);
- per translational clearance joint ``J`` (docs/model.md §2c): ``J.clearance`` (the guide's
  clearance c, m: its half-width is b + c), ``J.half_length`` (a), ``J.half_height`` (b, m), and
  every scalar array field of its corner contact law (``J.stiffness``, ``J.restitution``, ...),
  friction law and ``Smoothing``, named as for a revolute clearance joint;
- per force element ``F``: its scalar fields (``F.stiffness``, ``F.damping``, ``F.free_length``,
  ``F.torque``);
- ``baumgarte_alpha``, ``baumgarte_beta`` (1/s).

``with_parameters`` is a pure function of the values (``eqx.tree_at``), so it works under
``jax.jit``, ``jax.grad`` and ``jax.vmap``: build the mechanism once, then replace the parameters
inside the function you transform. Each name also has a ``ParameterInfo`` (unit and the open
interval of admissible values) that fitting and sampling code uses for its transforms.
"""

import dataclasses
import difflib
import math
from collections.abc import Callable, Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._core._errors import ModelError
from ._joints import ConstantSpeedDriver, RevoluteJoint, TranslationalJoint
from ._mechanism import Mechanism

RPM_TO_RAD_PER_S = math.pi / 30.0

POSITIVE = (0.0, math.inf)
UNBOUNDED = (-math.inf, math.inf)


@dataclasses.dataclass(frozen=True)
class ParameterInfo:
    """What a named parameter is.

    Attributes:
        name: dotted name. unit: SI unit (``""`` dimensionless). description: one line.
        domain: open interval (lower, upper) of admissible values (``math.inf`` for none).
    """

    name: str
    unit: str
    description: str
    domain: tuple[float, float]


@dataclasses.dataclass(frozen=True)
class _Entry:
    info: ParameterInfo
    get: Callable[[Mechanism], Array]
    set: Callable[[Mechanism, Array], Mechanism]


# Units and domains of known field names; other scalar fields are taken as positive and unitless
# only if listed here, else unbounded with an empty unit.
_FIELD_INFO = {
    "restitution": ("", (0.0, 1.0), "coefficient of restitution"),
    "stiffness": ("N/m^n", POSITIVE, "contact stiffness"),
    "exponent": ("", POSITIVE, "force exponent"),
    "friction_coefficient": ("", (0.0, math.inf), "friction coefficient"),
    "velocity_tolerance": ("m/s", POSITIVE, "velocity tolerance of the friction law"),
    "lower_velocity": ("m/s", POSITIVE, "lower velocity of the friction ramp"),
    "upper_velocity": ("m/s", POSITIVE, "upper velocity of the friction ramp"),
    "bristle_stiffness": ("1/m", POSITIVE, "LuGre bristle stiffness σ0"),
    "bristle_damping": ("s/m", POSITIVE, "LuGre bristle damping σ1"),
    "viscous_friction": ("s/m", (0.0, math.inf), "LuGre viscous coefficient σ2"),
    "static_friction": ("", POSITIVE, "static friction coefficient"),
    "kinetic_friction": ("", POSITIVE, "kinetic friction coefficient"),
    "stribeck_velocity": ("m/s", POSITIVE, "Stribeck velocity"),
    "layer_thickness": ("m", POSITIVE, "elastic-foundation layer thickness"),
    "foundation_modulus": ("Pa", POSITIVE, "elastic-foundation modulus"),
    "max_damping": ("N s/m", POSITIVE, "maximum damping"),
    "max_damping_penetration": ("m", POSITIVE, "penetration of maximum damping"),
    "coefficient_a": ("", UNBOUNDED, "fit coefficient a"),
    "coefficient_b": ("", UNBOUNDED, "fit coefficient b"),
    "fit_length_unit": ("m", POSITIVE, "length unit of the fit"),
    "penetration_width": ("m", POSITIVE, "smoothing width of the penetration"),
    "velocity_width": ("m/s", POSITIVE, "smoothing width of slip velocities"),
    "memory_width": ("m", POSITIVE, "smoothing width of the impact-memory switch"),
    "memory_rate": ("1/s", POSITIVE, "relaxation rate of the impact memory"),
    "min_impact_velocity": ("m/s", POSITIVE, "floor of the latched impact velocity"),
    "force_width": ("", POSITIVE, "smoothing width of the damping factor"),
    "damping": ("N s/m", (0.0, math.inf), "damping"),
    "free_length": ("m", (0.0, math.inf), "free length"),
    "torque": ("N m", UNBOUNDED, "applied torque"),
    "viscosity": ("Pa s", POSITIVE, "lubricant viscosity"),
    "transition_eccentricity": ("", (0.0, 1.0), "eccentricity ratio where the film starts to fade"),
    "transition_width": ("", (0.0, 1.0), "width of the film-to-dry blend in eccentricity ratio"),
}


def _concrete(x, default: float) -> float:
    """float(x) for a concrete value, ``default`` for a tracer (inside a transformation)."""
    try:
        return float(x)
    except (TypeError, jax.errors.ConcretizationTypeError):
        return default


def _scalar_fields(module) -> list[str]:
    """Names of the fields of an equinox Module that hold a scalar array (not None, not static)."""
    names = []
    for field in dataclasses.fields(module):
        if field.metadata.get("static", False):
            continue
        value = getattr(module, field.name)
        if isinstance(value, jnp.ndarray | float) and jnp.ndim(value) == 0:
            names.append(field.name)
    return names


def _info(name: str, field: str, owner: str) -> ParameterInfo:
    unit, domain, description = _FIELD_INFO.get(field, ("", UNBOUNDED, field.replace("_", " ")))
    return ParameterInfo(name, unit, f"{description} of {owner}", domain)


def _body_entries(mechanism: Mechanism) -> list[_Entry]:
    entries = []
    for k, body in enumerate(mechanism.bodies):
        for field, unit, what in (
            ("mass", "kg", "mass"),
            ("inertia", "kg m^2", "moment of inertia"),
        ):
            entries.append(
                _Entry(
                    ParameterInfo(
                        f"{body.name}_{field}", unit, f"{what} of body {body.name!r}", POSITIVE
                    ),
                    lambda m, k=k, field=field: getattr(m.bodies[k], field),
                    lambda m, v, k=k, field=field: eqx.tree_at(
                        lambda m: getattr(m.bodies[k], field), m, jnp.asarray(v, dtype=float)
                    ),
                )
            )
        for axis in (0, 1):
            entries.append(
                _Entry(
                    ParameterInfo(
                        f"{body.name}_com_{'xy'[axis]}",
                        "m",
                        f"shift of the centre of mass of {body.name!r} along its frame's "
                        f"{'xy'[axis]} axis (attachment points kept on the body)",
                        UNBOUNDED,
                    ),
                    lambda m: jnp.zeros(()),
                    lambda m, v, name=body.name, axis=axis: _shift_centre_of_mass(m, name, axis, v),
                )
            )
    return entries


def _shift_centre_of_mass(mechanism: Mechanism, body: str, axis: int, value) -> Mechanism:
    """Move ``body``'s centre of mass by ``value`` along its local ``axis``: every point attached to
    the body moves by ``-value`` in body coordinates; the body's initial position guess moves with
    the centre of mass (assembly refines it)."""
    shift = jnp.zeros(2).at[axis].set(jnp.asarray(value, dtype=float))
    m = mechanism
    k = [b.name for b in m.bodies].index(body)
    phi = m.bodies[k].position[2]
    c, s = jnp.cos(phi), jnp.sin(phi)
    world = jnp.stack([c * shift[0] - s * shift[1], s * shift[0] + c * shift[1]])
    m = eqx.tree_at(lambda m: m.bodies[k].position, m, m.bodies[k].position.at[:2].add(world))
    for group in ("joints", "clearance_joints", "translational_clearance_joints", "forces"):
        for j, element in enumerate(getattr(m, group)):
            for end in ("i", "j", "bearing", "journal", "slider", "guide", ""):
                body_attr = (
                    f"body_{end}" if end in ("i", "j") else (f"{end}_body" if end else "body")
                )
                point_attr = (
                    f"point_{end}" if end in ("i", "j") else (f"{end}_point" if end else "point")
                )
                if getattr(element, body_attr, None) == body and hasattr(element, point_attr):
                    m = eqx.tree_at(
                        lambda m, group=group, j=j, point_attr=point_attr: getattr(
                            getattr(m, group)[j], point_attr
                        ),
                        m,
                        getattr(element, point_attr) - shift,
                    )
    return m


def _clearance_entries(mechanism: Mechanism) -> list[_Entry]:
    entries = []
    for k, joint in enumerate(mechanism.clearance_joints):
        J = joint.name
        owner = f"clearance joint {J!r}"

        def geometry(m, k=k):
            return m.clearance_joints[k].geometry

        def set_geometry(m, fields, values, k=k):
            return eqx.tree_at(
                lambda m: tuple(getattr(m.clearance_joints[k].geometry, f) for f in fields),
                m,
                tuple(jnp.asarray(v, dtype=float) for v in values),
            )

        entries.append(
            _Entry(
                ParameterInfo(
                    f"{J}.clearance",
                    "m",
                    f"radial clearance c = R_B - R_J of {owner} (sets R_J, keeps R_B)",
                    (0.0, _concrete(joint.geometry.bearing_radius, math.inf)),
                ),
                lambda m, geometry=geometry: geometry(m).clearance,
                lambda m, v, geometry=geometry, set_geometry=set_geometry: set_geometry(
                    m, ("journal_radius",), (geometry(m).bearing_radius - v,)
                ),
            )
        )
        for field, unit, what in (
            ("bearing_radius", "m", "bearing radius R_B"),
            ("journal_radius", "m", "journal radius R_J"),
            ("length", "m", "pin length"),
            ("bearing_young", "Pa", "Young's modulus of the bearing"),
            ("journal_young", "Pa", "Young's modulus of the journal"),
            ("bearing_poisson", "", "Poisson's ratio of the bearing"),
            ("journal_poisson", "", "Poisson's ratio of the journal"),
        ):
            domain = (0.0, 0.5) if "poisson" in field else POSITIVE
            entries.append(
                _Entry(
                    ParameterInfo(f"{J}.{field}", unit, f"{what} of {owner}", domain),
                    lambda m, geometry=geometry, field=field: getattr(geometry(m), field),
                    lambda m, v, set_geometry=set_geometry, field=field: set_geometry(
                        m, (field,), (v,)
                    ),
                )
            )
        for name, pair, unit, domain, what in (
            (
                "young_modulus",
                ("bearing_young", "journal_young"),
                "Pa",
                POSITIVE,
                "Young's modulus",
            ),
            (
                "poisson_ratio",
                ("bearing_poisson", "journal_poisson"),
                "",
                (0.0, 0.5),
                "Poisson's ratio",
            ),
        ):
            entries.append(
                _Entry(
                    ParameterInfo(
                        f"{J}.{name}", unit, f"{what} of both materials of {owner}", domain
                    ),
                    lambda m, geometry=geometry, pair=pair: getattr(geometry(m), pair[0]),
                    lambda m, v, set_geometry=set_geometry, pair=pair: set_geometry(
                        m, pair, (v, v)
                    ),
                )
            )
        parts = ("contact_law", "friction_law", "smoothing")
        if joint.lubrication is not None:
            parts += ("lubrication",)
        taken = {e.info.name for e in entries}
        entries += _part_entries(joint, "clearance_joints", k, parts, owner, taken)
    return entries


def _part_entries(joint, group: str, k: int, parts, owner: str, taken: set) -> list[_Entry]:
    """Entries ``<J>.<field>`` for every scalar array field of the ``parts`` (contact law, friction
    law, smoothing, ...) of ``joint``, entry ``k`` of the mechanism's tuple ``group``; a name
    already in ``taken`` becomes ``<J>.<part>.<field>`` (``J.lubrication.length``)."""
    entries = []
    for part in parts:
        for field in _scalar_fields(getattr(joint, part)):
            name = f"{joint.name}.{field}"
            if name in taken:
                name = f"{joint.name}.{part.split('_')[0]}.{field}"
            taken.add(name)
            entries.append(
                _Entry(
                    _info(name, field, f"the {part.replace('_', ' ')} of {owner}"),
                    lambda m, part=part, field=field: getattr(
                        getattr(getattr(m, group)[k], part), field
                    ),
                    lambda m, v, part=part, field=field: eqx.tree_at(
                        lambda m: getattr(getattr(getattr(m, group)[k], part), field),
                        m,
                        jnp.asarray(v, dtype=float),
                    ),
                )
            )
    return entries


def _translational_entries(mechanism: Mechanism) -> list[_Entry]:
    """Entries of the translational clearance joints (docs/model.md §2c): per joint ``J``,
    ``J.clearance`` (c, the guide's half-width being b + c), ``J.half_length`` (a),
    ``J.half_height`` (b) and the scalar fields of its corner contact law (``J.stiffness``,
    ``J.restitution``, ...), friction law and ``Smoothing``."""
    group = "translational_clearance_joints"
    entries = []
    for k, joint in enumerate(mechanism.translational_clearance_joints):
        owner = f"translational clearance joint {joint.name!r}"
        for field, what in (
            ("clearance", "guide clearance c (guide half-width b + c)"),
            ("half_length", "slider half-length a"),
            ("half_height", "slider half-height b (guide half-width b + c)"),
        ):
            entries.append(
                _Entry(
                    ParameterInfo(f"{joint.name}.{field}", "m", f"{what} of {owner}", POSITIVE),
                    lambda m, k=k, field=field: getattr(getattr(m, group)[k], field),
                    lambda m, v, k=k, field=field: eqx.tree_at(
                        lambda m: getattr(getattr(m, group)[k], field),
                        m,
                        jnp.asarray(v, dtype=float),
                    ),
                )
            )
        taken = {e.info.name for e in entries}
        parts = ("contact_law", "friction_law", "smoothing")
        entries += _part_entries(joint, group, k, parts, owner, taken)
    return entries


def _driver(mechanism: Mechanism) -> ConstantSpeedDriver:
    driver = mechanism.driver
    assert isinstance(driver, ConstantSpeedDriver)
    return driver


def _other_entries(mechanism: Mechanism) -> list[_Entry]:
    entries = []
    if isinstance(mechanism.driver, ConstantSpeedDriver):
        entries.append(
            _Entry(
                ParameterInfo("rpm", "rev/min", "speed of the constant-speed driver", UNBOUNDED),
                lambda m: _driver(m).speed / RPM_TO_RAD_PER_S,
                lambda m, v: eqx.tree_at(
                    lambda m: _driver(m).speed, m, jnp.asarray(v, dtype=float) * RPM_TO_RAD_PER_S
                ),
            )
        )
    for k, element in enumerate(mechanism.forces):
        for field in _scalar_fields(element):
            entries.append(
                _Entry(
                    _info(f"{element.name}.{field}", field, f"force element {element.name!r}"),
                    lambda m, k=k, field=field: getattr(m.forces[k], field),
                    lambda m, v, k=k, field=field: eqx.tree_at(
                        lambda m: getattr(m.forces[k], field), m, jnp.asarray(v, dtype=float)
                    ),
                )
            )
    for field in ("baumgarte_alpha", "baumgarte_beta"):
        entries.append(
            _Entry(
                ParameterInfo(field, "1/s", f"Baumgarte gain {field[-5:]}", POSITIVE),
                lambda m, field=field: getattr(m, field),
                lambda m, v, field=field: eqx.tree_at(
                    lambda m: getattr(m, field), m, jnp.asarray(v, dtype=float)
                ),
            )
        )
    return entries


def _entries(mechanism: Mechanism) -> dict[str, _Entry]:
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"expected a jaxclear Mechanism, got {type(mechanism).__name__}.")
    entries = (
        _body_entries(mechanism)
        + _clearance_entries(mechanism)
        + _translational_entries(mechanism)
        + _other_entries(mechanism)
    )
    return {e.info.name: e for e in entries}


def _unknown(name: str, entries: Mapping[str, _Entry], mechanism: Mechanism) -> ModelError:
    joint, _, field = name.partition(".")
    ideal = {j.name for j in mechanism.joints if isinstance(j, RevoluteJoint)}
    if field and joint in ideal and f"{joint}.{field}" not in entries:
        with_clearance = [j.name for j in mechanism.clearance_joints]
        named = ",".join([*with_clearance, joint])
        return ModelError(
            f"{name!r}: joint {joint!r} is an ideal revolute joint and has no clearance, so it has "
            f"no {field!r}; give it one first: clearance_joints={named!r} in "
            f"jaxclear.mechanisms.slider_crank or four_bar, --clearance-joints {named} on the "
            f'command line, or joints = "{named}" under [clearance] in the config file'
        )
    guides = {j.name for j in mechanism.joints if isinstance(j, TranslationalJoint)}
    if field and joint in guides and f"{joint}.{field}" not in entries:
        return ModelError(
            f"{name!r}: joint {joint!r} is an ideal translational joint and has no clearance, so "
            f"it has no {field!r}; give it one first: translational_clearance=c in "
            f"jaxclear.mechanisms.slider_crank, or joints = {joint!r} under [clearance] and a table "
            f"[clearance.{joint}] with clearance = c in the config file"
        )
    close = difflib.get_close_matches(name, list(entries), n=3)
    hint = f"did you mean {' or '.join(map(repr, close))}? " if close else ""
    return ModelError(
        f"unknown parameter {name!r}; {hint}this mechanism has: {', '.join(entries)} "
        "(jaxclear.parameter_names(mechanism))."
    )


def _entry(mechanism: Mechanism, name: str) -> _Entry:
    entries = _entries(mechanism)
    if name not in entries:
        raise _unknown(name, entries, mechanism)
    return entries[name]


def parameter_names(mechanism: Mechanism) -> tuple[str, ...]:
    """The dotted names ``get_parameter``/``with_parameters`` accept for ``mechanism`` (module doc)."""
    return tuple(_entries(mechanism))


def parameter_info(mechanism: Mechanism, name: str) -> ParameterInfo:
    """Unit, description and admissible interval of a named parameter.

    Raises:
        ModelError: ``name`` is not a parameter of ``mechanism`` (the message lists those that are).
    """
    return _entry(mechanism, name).info


def get_parameter(mechanism: Mechanism, name: str) -> Array:
    """The value of a named parameter (a JAX scalar; traceable).

    Raises:
        ModelError: unknown ``name``.
    """
    return jnp.asarray(_entry(mechanism, name).get(mechanism))


def with_parameters(mechanism: Mechanism, values: Mapping[str, ArrayLike]) -> Mechanism:
    """A copy of ``mechanism`` with the named parameters replaced, applied in the mapping's order.

    Pure and traceable: use inside ``jax.jit``/``jax.grad``/``jax.vmap``. Values are not checked
    here (they may be tracers); an eager ``simulate`` checks the mechanism it is given.

    Args:
        mechanism: the mechanism to copy.
        values: ``{name: value}`` with names from ``parameter_names(mechanism)``, SI units.

    Raises:
        ModelError: an unknown name (the message lists the valid ones).
    """
    entries = _entries(mechanism)
    unknown = [n for n in values if n not in entries]
    if unknown:
        raise _unknown(unknown[0], entries, mechanism)
    for name, value in values.items():
        mechanism = entries[name].set(mechanism, jnp.asarray(value, dtype=float))
    return mechanism
