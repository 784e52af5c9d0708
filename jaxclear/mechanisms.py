"""Benchmark mechanisms: the slider–crank of docs/model.md §6 and a four-bar linkage."""

import jax
import jax.numpy as jnp
from jaxtyping import ArrayLike

from ._core._errors import ModelError
from .model._body import Body
from .model._clearance import ClearanceJoint
from .model._joints import ConstantSpeedDriver, RevoluteJoint, TranslationalJoint
from .model._mechanism import Mechanism
from .model._translational_clearance import TranslationalClearanceJoint

RPM = 2.0 * jnp.pi / 60.0  # rad/s per rpm

SLIDER_CRANK_JOINTS = ("O", "A", "B")
"""Revolute joints of the slider–crank: O (ground–crank), A (crank–rod), B (rod–slider)."""


def _gravity(gravity: bool | float):
    g = 9.81 if gravity is True else (0.0 if gravity is False else float(gravity))
    return (0.0, -g)


def slider_crank(
    *,
    rpm: ArrayLike | None = 5000.0,
    crank_length: ArrayLike = 0.05,
    rod_length: ArrayLike = 0.12,
    crank_mass: ArrayLike = 0.30,
    rod_mass: ArrayLike = 0.21,
    slider_mass: ArrayLike = 0.14,
    crank_inertia: ArrayLike = 1.0e-4,
    rod_inertia: ArrayLike = 2.5e-4,
    slider_inertia: ArrayLike = 1.0e-4,
    initial_angle: ArrayLike = 0.0,
    gravity: bool | float = False,
    clearance_joints=(),
    translational_clearance=None,
    initial_speed: ArrayLike | None = None,
    **clearance_options,
) -> Mechanism:
    """The benchmark slider–crank (docs/model.md §6): crank O–A, connecting rod A–B, slider at B.

    Crank pivot O at the origin, slider on the global x axis through O, crank angle 0 at outer dead
    centre (slider at x = r + l), centres of mass at link mid-points, crank driven at constant speed.

    Args:
        rpm: crank speed, rev/min; ``None`` for a free (undriven) crank, see ``initial_speed``.
        crank_length, rod_length: r and l, m (l > r).
        crank_mass, rod_mass, slider_mass: kg. crank_inertia, rod_inertia, slider_inertia: kg m².
        initial_angle: crank angle at t = 0, rad.
        gravity: ``True`` for 9.81 m/s² along −y, ``False`` for none, or a magnitude in m/s².
        clearance_joints: which of ``"O"``, ``"A"``, ``"B"`` have clearance: a sequence of names
            (e.g. ``("O", "A", "B")`` or ``"B"``), or a mapping ``{name: dict of options}`` for
            per-joint options.
        **clearance_options: options shared by every clearance joint, passed to
            ``ClearanceJoint.replacing``: ``clearance`` (m, default 0.5 mm with R_B = 10 mm),
            ``journal_body`` (the body carrying the pin; default the joint's second body, e.g.
            ``"slider"`` at B), ``geometry``, ``contact_law``, ``friction_law``, ``smoothing``,
            ``initial_eccentricity``, ``lubrication`` (a ``jaxclear.Lubrication`` film,
            docs/model.md §3b; e.g. ``clearance_joints={"B": {"lubrication": film}}``).
        translational_clearance: ``None`` (default) for an ideal slider guide; else the guide
            ``slider_guide`` becomes a ``TranslationalClearanceJoint`` (docs/model.md §2c): a
            clearance c in m, or a mapping of ``TranslationalClearanceJoint.replacing`` options
            (``clearance``, ``half_length``, ``half_height``, ``contact_law``, ``friction_law``,
            ``smoothing``, ``initial_offset``, ``initial_tilt``). Defaults: the slider of Flores,
            Leine & Glocker (2010), a = 0.05 m, b = 0.025 m, c = 1 mm.
        initial_speed: with ``rpm=None`` (no driver: the crank turns freely), the crank's angular
            velocity at t = 0, rad/s (default 0); the other bodies start with the matching
            velocities of the ideal mechanism.

    Returns:
        The ``Mechanism`` with bodies ``crank``, ``rod``, ``slider``; ideal joints ``O``, ``A``,
        ``B`` (revolute) and ``slider_guide`` (translational, or a translational clearance joint);
        driver ``driver`` (none with ``rpm=None``).
    """
    crank, rod = crank_length, rod_length
    if isinstance(crank, float | int) and isinstance(rod, float | int) and not rod > crank > 0:
        raise ModelError(
            f"slider_crank: need rod_length > crank_length > 0, got rod_length={rod}, crank_length={crank}; "
            "a shorter rod cannot reach the slider guide at every crank angle."
        )
    th = initial_angle
    if rpm is None:
        if initial_speed is None:
            initial_speed = 0.0
    elif initial_speed is not None:
        raise ModelError(
            "slider_crank: initial_speed is for a free crank (rpm=None); a driven crank turns at rpm."
        )

    def positions(th):
        c, s = jnp.cos(th), jnp.sin(th)
        ax, ay = crank * c, crank * s
        bx = ax + jnp.sqrt(jnp.maximum(rod**2 - ay**2, 0.0))
        rod_phi = jnp.arctan2(-ay, bx - ax)
        return (
            jnp.stack([0.5 * ax, 0.5 * ay, th]),
            jnp.stack([0.5 * (ax + bx), 0.5 * ay, rod_phi]),
            jnp.stack([bx, jnp.zeros_like(bx), jnp.zeros_like(bx)]),
        )

    th = jnp.asarray(th, dtype=float)
    places = positions(th)
    if rpm is None:
        speeds = jax.jvp(positions, (th,), (jnp.asarray(initial_speed, dtype=float),))[1]
    else:
        speeds = (jnp.zeros(3),) * 3
    bodies = (
        Body("crank", crank_mass, crank_inertia, position=places[0], velocity=speeds[0]),
        Body("rod", rod_mass, rod_inertia, position=places[1], velocity=speeds[1]),
        Body("slider", slider_mass, slider_inertia, position=places[2], velocity=speeds[2]),
    )
    revolute = {
        "O": RevoluteJoint("O", "ground", (0.0, 0.0), "crank", (-0.5 * crank, 0.0)),
        "A": RevoluteJoint("A", "crank", (0.5 * crank, 0.0), "rod", (-0.5 * rod, 0.0)),
        "B": RevoluteJoint("B", "rod", (0.5 * rod, 0.0), "slider", (0.0, 0.0)),
    }
    clearance_elements = make_clearance_joints(
        revolute, clearance_joints, clearance_options, "slider_crank"
    )
    joints = tuple(
        j for name, j in revolute.items() if name not in {c.name for c in clearance_elements}
    )
    guide = TranslationalJoint(
        "slider_guide", "slider", (0.0, 0.0), "ground", (0.0, 0.0), axis=(1.0, 0.0)
    )
    sliders = make_translational_clearance(guide, translational_clearance, "slider_crank")
    return Mechanism(
        bodies=bodies,
        joints=(*joints, guide) if not sliders else tuple(joints),
        driver=(
            None
            if rpm is None
            else ConstantSpeedDriver(body="crank", speed=rpm * RPM, initial_angle=initial_angle)
        ),
        clearance_joints=clearance_elements,
        gravity=_gravity(gravity),
        translational_clearance_joints=sliders,
    )


TRANSLATIONAL_CLEARANCE_OPTIONS = frozenset(
    {
        "clearance",
        "half_length",
        "half_height",
        "contact_law",
        "friction_law",
        "smoothing",
        "initial_offset",
        "initial_tilt",
    }
)
"""Keyword arguments of ``TranslationalClearanceJoint.replacing`` accepted by ``slider_crank``."""

FLORES_LEINE_GLOCKER_SLIDER = {"half_length": 0.05, "half_height": 0.025, "clearance": 1e-3}
"""Slider and guide of Flores, Leine & Glocker (2010), Table 1: a, b, c in m."""


def make_translational_clearance(joint, spec, owner: str) -> tuple:
    """``()`` for ``spec=None``, else a one-joint tuple: the ``TranslationalClearanceJoint`` that
    replaces the ideal translational ``joint``, from a clearance (m) or a mapping of options."""
    if spec is None or spec is False:
        return ()
    if spec is True:
        spec = {}
    if not isinstance(spec, dict):
        spec = {"clearance": spec}
    bad = set(spec) - TRANSLATIONAL_CLEARANCE_OPTIONS
    if bad:
        raise TypeError(
            f"{owner}: unknown translational_clearance option(s) {sorted(bad)}; options are "
            f"{sorted(TRANSLATIONAL_CLEARANCE_OPTIONS)}."
        )
    options = {**FLORES_LEINE_GLOCKER_SLIDER, **spec}
    return (TranslationalClearanceJoint.replacing(joint, **options),)


def four_bar(
    *,
    ground_length: ArrayLike = 0.30,
    crank_length: ArrayLike = 0.10,
    coupler_length: ArrayLike = 0.30,
    rocker_length: ArrayLike = 0.25,
    crank_mass: ArrayLike = 0.2,
    coupler_mass: ArrayLike = 0.5,
    rocker_mass: ArrayLike = 0.4,
    initial_angle: ArrayLike = jnp.pi / 3,
    rpm: ArrayLike | None = 60.0,
    gravity: bool | float = True,
    clearance_joints=(),
    **clearance_options,
) -> Mechanism:
    """A four-bar linkage O2–A–B–O4 with uniform slender links (J = m L²/12).

    Ground pivots O2 at the origin and O4 at (ground_length, 0); crank O2–A, coupler A–B, rocker
    B–O4; the open (elbow-up) assembly branch. Revolute joints ``O2``, ``A``, ``B``, ``O4``.

    Args:
        ground_length, crank_length, coupler_length, rocker_length: m.
        crank_mass, coupler_mass, rocker_mass: kg.
        initial_angle: crank angle at t = 0, rad.
        rpm: constant crank speed, or ``None`` for an undriven (free) linkage.
        gravity: ``True`` (9.81 m/s² along −y), ``False`` or a magnitude.
        clearance_joints: as in ``slider_crank``, among ``"O2"``, ``"A"``, ``"B"``, ``"O4"``.
        **clearance_options: as in ``slider_crank``.
    """
    d, a, b, c = ground_length, crank_length, coupler_length, rocker_length
    th = initial_angle
    ax, ay = a * jnp.cos(th), a * jnp.sin(th)
    # B: intersection of circles |B - A| = b and |B - O4| = c, upper branch.
    dx, dy = d - ax, -ay
    dist = jnp.sqrt(dx**2 + dy**2)
    along = (b**2 - c**2 + dist**2) / (2 * dist)
    h = jnp.sqrt(jnp.maximum(b**2 - along**2, 0.0))
    ex, ey = dx / dist, dy / dist
    bx, by = ax + along * ex - h * ey, ay + along * ey + h * ex
    coupler_phi = jnp.arctan2(by - ay, bx - ax)
    rocker_phi = jnp.arctan2(by, bx - d)
    bodies = (
        Body("crank", crank_mass, crank_mass * a**2 / 12, position=(0.5 * ax, 0.5 * ay, th)),
        Body(
            "coupler",
            coupler_mass,
            coupler_mass * b**2 / 12,
            position=(0.5 * (ax + bx), 0.5 * (ay + by), coupler_phi),
        ),
        Body(
            "rocker",
            rocker_mass,
            rocker_mass * c**2 / 12,
            position=(0.5 * (d + bx), 0.5 * by, rocker_phi),
        ),
    )
    revolute = {
        "O2": RevoluteJoint("O2", "ground", (0.0, 0.0), "crank", (-0.5 * a, 0.0)),
        "A": RevoluteJoint("A", "crank", (0.5 * a, 0.0), "coupler", (-0.5 * b, 0.0)),
        "B": RevoluteJoint("B", "coupler", (0.5 * b, 0.0), "rocker", (0.5 * c, 0.0)),
        "O4": RevoluteJoint("O4", "ground", (d, 0.0), "rocker", (-0.5 * c, 0.0)),
    }
    clearance = make_clearance_joints(revolute, clearance_joints, clearance_options, "four_bar")
    driver = (
        None
        if rpm is None
        else ConstantSpeedDriver(body="crank", speed=rpm * RPM, initial_angle=th)
    )
    return Mechanism(
        bodies=bodies,
        joints=tuple(j for n, j in revolute.items() if n not in {c.name for c in clearance}),
        driver=driver,
        clearance_joints=clearance,
        gravity=_gravity(gravity),
    )


CLEARANCE_OPTIONS = frozenset(
    {
        "clearance",
        "journal_body",
        "geometry",
        "contact_law",
        "friction_law",
        "smoothing",
        "initial_eccentricity",
        "lubrication",
    }
)
"""Keyword arguments of ``ClearanceJoint.replacing`` accepted as shared or per-joint options."""


def make_clearance_joints(revolute: dict, spec, shared: dict, owner: str) -> tuple:
    """Clearance joints replacing some of the ideal revolute joints ``revolute`` (name → joint).

    Args:
        revolute: the mechanism's ideal revolute joints by name.
        spec: names (sequence or comma-separated string) or ``{name: options}`` (per-joint
            options override ``shared``; e.g. ``{"B": {"journal_body": "rod"}}``).
        shared: options common to all (``ClearanceJoint.replacing`` keyword arguments).
        owner: mechanism name for error messages.
    """
    if isinstance(spec, str):
        spec = [s.strip() for s in spec.split(",") if s.strip() and s.strip().lower() != "none"]
    if not isinstance(spec, dict):
        spec = {name: {} for name in spec}
    unknown = set(spec) - set(revolute)
    if unknown:
        joined = [u for u in sorted(unknown) if len(u) > 1 and all(c in revolute for c in u)]
        hint = (
            f" (several joints are separated by commas: {','.join(joined[0])!r} or "
            f"{tuple(joined[0])!r})"
            if joined
            else ""
        )
        raise ModelError(
            f"{owner}: clearance joints must be among {', '.join(revolute)}; got "
            f"{sorted(unknown)}{hint}."
        )
    for where, options in [("", shared)] + [
        (f" of joint {name!r}", spec[name] or {}) for name in spec
    ]:
        bad = set(options) - CLEARANCE_OPTIONS
        if bad:
            raise TypeError(
                f"{owner}: unknown option(s){where} {sorted(bad)}; clearance options are {sorted(CLEARANCE_OPTIONS)}."
            )
    if "clearance" not in shared and "geometry" not in shared:
        shared = {**shared, "clearance": 5e-4}
    return tuple(
        ClearanceJoint.replacing(revolute[name], **{**shared, **(spec[name] or {})})
        for name in revolute
        if name in spec
    )


def is_slider_crank(mechanism) -> bool:
    """Whether ``mechanism`` is the benchmark slider–crank (bodies ``crank``, ``rod``, ``slider``),
    whose results keep their established columns ``slider_x``, ``slider_v``, ``slider_a``."""
    return tuple(mechanism.body_names) == ("crank", "rod", "slider")
