"""Revolute clearance joint (docs/model.md §2): a pin (journal) in a hole (bearing), as data.

A ``ClearanceJoint`` takes the place of an ideal ``RevoluteJoint``: instead of two constraint
equations it adds two degrees of freedom and contact forces. Its internal states (the
impact-velocity memory m and the friction law's states, e.g. LuGre z) live in the integrator state.
This module holds the joint's parameters and their checks only; its kinematics, contact forces and
impact memory are computed with the equations of motion (``_clearance.py`` of the next stage).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._core._checks import (
    check_finite,
    check_nonnegative,
    check_open_interval,
    check_positive,
    check_shape,
    is_concrete,
)
from .._core._errors import ModelError
from ..contact import Hybrid
from ..contact._base import AbstractContactLaw, ContactGeometry, Smoothing
from ..contact._lubrication import Lubrication
from ..friction import LuGre
from ..friction._base import AbstractFrictionLaw
from ._element import AbstractStateElement


def _array(x):
    return jnp.asarray(x, dtype=float)


class ClearanceJoint(AbstractStateElement):
    """A revolute joint with radial clearance c = R_B − R_J.

    The bearing (hole, radius R_B) is on ``bearing_body`` at ``bearing_point``; the journal (pin,
    radius R_J) on ``journal_body`` at ``journal_point``. Eccentricity e = r_journal − r_bearing;
    penetration δ = ‖e‖ − c; contact force on the journal f = −F_N n + F_T t applied at
    Q_II = r_II + R_J n, the opposite on the bearing at Q_I = r_I + R_B n (docs/model.md §2).

    Attributes:
        name: label used in outputs (static).
        bearing_body, journal_body: body names (static; ``"ground"`` allowed).
        bearing_point, journal_point: local joint points, m.
        geometry: radii, pin length and materials (``ContactGeometry``).
        contact_law: normal contact law (default: the paper's hybrid L-N + EFM law).
        friction_law: friction law (default: LuGre).
        smoothing: regularisation widths (``Smoothing``).
        initial_eccentricity: journal offset at assembly (global components), m; default centred.
        memory_offset: carry the impact memory as u = m − δ̇ instead of m (static; set inside the
            solve by ``lawson-tsit5`` through ``Mechanism.with_memory_offset``, see
            ``_impact_memory.py`` beside the equations of motion).
        lubrication: a hydrodynamic film in the clearance (``jaxclear.contact.Lubrication``:
            viscosity, bearing length, short/long theory, blend to dry contact; docs/model.md
            §3b), or ``None`` (default) for a dry joint. The film's force acts at the journal
            centre; the dry contact law and friction take over at the wall.
        initial_impact_velocity: v₀ ≥ 0, m/s: the impact-velocity memory starts at max(δ̇(t0), v₀)
            for v₀ > 0, at δ̇(t0) for v₀ = 0 (default: a journal that starts off the wall, whose
            memory tracks δ̇ in free flight anyway). For a journal that starts on its wall
            (``jaxclear.wall_start`` sets it; docs/model.md §5c).
    """

    name: str = eqx.field(static=True)
    bearing_body: str = eqx.field(static=True)
    bearing_point: Float[Array, "2"] = eqx.field(converter=_array)
    journal_body: str = eqx.field(static=True)
    journal_point: Float[Array, "2"] = eqx.field(converter=_array)
    geometry: ContactGeometry = eqx.field(default_factory=lambda: ContactGeometry(0.01, 0.0095))
    contact_law: AbstractContactLaw = eqx.field(default_factory=Hybrid)
    friction_law: AbstractFrictionLaw = eqx.field(default_factory=LuGre)
    smoothing: Smoothing = eqx.field(default_factory=Smoothing)
    initial_eccentricity: Float[Array, "2"] = eqx.field(converter=_array, default=(0.0, 0.0))
    memory_offset: bool = eqx.field(static=True, default=False)
    lubrication: Lubrication | None = None
    initial_impact_velocity: Float[Array, ""] = eqx.field(converter=_array, default=0.0)

    def __check_init__(self):
        owner = f"ClearanceJoint {self.name!r}"
        for attr in ("bearing_point", "journal_point", "initial_eccentricity"):
            check_shape(owner, attr, getattr(self, attr), (2,))
            check_finite(owner, attr, getattr(self, attr))
        check_shape(owner, "initial_impact_velocity", self.initial_impact_velocity, ())
        check_nonnegative(
            owner,
            "initial_impact_velocity",
            self.initial_impact_velocity,
            "m/s",
            "pass 0 (the memory starts at the initial penetration rate) or a speed in m/s",
        )
        g = self.geometry
        check_positive(owner, "bearing_radius", g.bearing_radius, "m")
        check_positive(owner, "journal_radius", g.journal_radius, "m")
        check_positive(owner, "length (pin length h)", g.length, "m")
        check_positive(owner, "bearing_young", g.bearing_young, "Pa")
        check_positive(owner, "journal_young", g.journal_young, "Pa")
        for attr in ("bearing_poisson", "journal_poisson"):
            check_open_interval(owner, attr, getattr(g, attr), 0.0, 0.5, "steel is 0.3")
        if is_concrete(g.bearing_radius) and is_concrete(g.journal_radius):
            if not float(g.journal_radius) < float(g.bearing_radius):
                raise ModelError(
                    f"{owner}: journal_radius ({float(g.journal_radius)} m) must be smaller than bearing_radius "
                    f"({float(g.bearing_radius)} m); the clearance c = R_B - R_J must be positive."
                )
        self.smoothing.check(owner)
        if not isinstance(self.contact_law, AbstractContactLaw):
            raise TypeError(
                f"{owner}: contact_law must be an AbstractContactLaw, got {type(self.contact_law).__name__}."
            )
        if not isinstance(self.friction_law, AbstractFrictionLaw):
            raise TypeError(
                f"{owner}: friction_law must be an AbstractFrictionLaw, got {type(self.friction_law).__name__}."
            )
        if self.lubrication is not None and not isinstance(self.lubrication, Lubrication):
            raise TypeError(
                f"{owner}: lubrication must be a jaxclear.contact.Lubrication or None, got "
                f"{type(self.lubrication).__name__}."
            )
        if all(
            is_concrete(x) for x in (self.initial_eccentricity, g.bearing_radius, g.journal_radius)
        ):
            if np.linalg.norm(np.asarray(self.initial_eccentricity)) > float(
                g.bearing_radius - g.journal_radius
            ):
                raise ModelError(
                    f"{owner}: initial_eccentricity lies outside the clearance circle."
                )

    @classmethod
    def replacing(
        cls, joint, clearance: ArrayLike | None = None, journal_body: str | None = None, **kwargs
    ) -> "ClearanceJoint":
        """A clearance joint at the place of an ideal ``RevoluteJoint``.

        Args:
            joint: the ``RevoluteJoint`` to replace (name, bodies and points are taken from it).
            clearance: radial clearance c, m; sets the journal radius to R_B − c (R_B from
                ``geometry`` or 10 mm).
            journal_body: which of the joint's two bodies carries the pin (journal); the other
                carries the hole (bearing). Default ``joint.body_j`` (bearing on ``joint.body_i``).
            **kwargs: other ``ClearanceJoint`` fields (geometry, contact_law, friction_law, ...).

        Returns:
            The clearance joint, named like ``joint``.

        Raises:
            ModelError: ``journal_body`` is not one of the joint's two bodies, or ``clearance`` is
                not positive and smaller than the bearing radius.
        """
        owner = f"ClearanceJoint {joint.name!r}"
        if journal_body is None:
            journal_body = joint.body_j
        if journal_body not in (joint.body_i, joint.body_j):
            raise ModelError(
                f"{owner}: journal_body={journal_body!r} is not a body of joint {joint.name!r}; "
                f"choose {joint.body_i!r} or {joint.body_j!r}."
            )
        geometry = kwargs.pop("geometry", None) or ContactGeometry(0.01, 0.0095)
        if clearance is not None:
            check_positive(owner, "clearance", clearance, "m")
            geometry = eqx.tree_at(
                lambda g: g.journal_radius, geometry, geometry.bearing_radius - clearance
            )
            if is_concrete(geometry.journal_radius) and not float(geometry.journal_radius) > 0:
                raise ModelError(
                    f"{owner}: clearance {clearance} m is not smaller than the bearing radius."
                )
        if journal_body == joint.body_j:
            bearing = (joint.body_i, joint.point_i)
            journal = (joint.body_j, joint.point_j)
        else:
            bearing = (joint.body_j, joint.point_j)
            journal = (joint.body_i, joint.point_i)
        return cls(joint.name, *bearing, *journal, geometry=geometry, **kwargs)

    # --- layout of the internal state: [memory m (or u = m − δ̇ if memory_offset), friction states]
    memory_state_rows: ClassVar[tuple[int, ...]] = (0,)
    """Which internal states hold the impact-velocity memory (``Mechanism.memory_rows``)."""

    @property
    def num_states(self) -> int:
        """Internal states in the integrator state: the impact memory, then the friction law's."""
        return 1 + self.friction_law.num_states

    @property
    def bodies(self) -> tuple[str, str]:
        """(bearing body, journal body)."""
        return (self.bearing_body, self.journal_body)
