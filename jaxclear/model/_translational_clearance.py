"""Translational clearance joint (docs/model.md §2c): a rectangular slider in a wider guide, as data.

A ``TranslationalClearanceJoint`` takes the place of an ideal ``TranslationalJoint`` the way a
``ClearanceJoint`` takes the place of a ``RevoluteJoint``: instead of two constraint equations
(relative angle and lateral offset held) it adds two degrees of freedom, the slider's tilt and its
lateral offset in the guide, and contact forces at the slider's four corners. The geometry follows
Flores, Ambrósio, Claro & Lankarani, J. Comput. Nonlinear Dynam. 3(1) 011007 (2008) and Flores,
Leine & Glocker, Multibody Syst. Dyn. 23:165–190 (2010): a slider of half-length a and half-height b
in a guide of half-width b + c. This module holds the joint's parameters and their checks only; its
corner gaps, forces and internal states are computed with the equations of motion
(``_translational_geometry.py`` and ``_translational.py`` of the next stage).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._core._checks import (
    check_finite,
    check_positive,
    check_shape,
    is_concrete,
)
from .._core._errors import ModelError
from ..contact import AdamsImpact, Flores, Hertz
from ..contact._base import AbstractContactLaw, ContactGeometry, Smoothing
from ..contact._damped import AbstractDampedContactLaw
from ..friction import Coulomb
from ..friction._base import AbstractFrictionLaw
from ._element import AbstractStateElement


def _array(x):
    return jnp.asarray(x, dtype=float)


CORNER_LAWS = (Hertz, AbstractDampedContactLaw, AdamsImpact)
"""Contact laws that make sense for a corner on a plane: the point laws K δ^n (undamped, the damped
family, ADAMS IMPACT). The cylindrical, foundation and hybrid laws need a pin in a hole."""

DEFAULT_CORNER_STIFFNESS = 1e10
"""N/m^1.5, the default K of the corner contact law [ours]: a sharp corner on a plane has no Hertz
basis (Flores et al. 2008 treat it as a parameter). With the Flores–Leine–Glocker slider (0.076
kg) hitting at 1 m/s it gives a peak indentation of about 40 µm (K δ^1.5 law, energy balance)."""

DEFAULT_CORNER_RESTITUTION = 0.4
"""Restitution of the default corner law, the value of Flores, Leine & Glocker (2010), Table 1."""

CORNER_NAMES = ("upper_front", "upper_rear", "lower_rear", "lower_front")
"""Corner labels in state and output order: 'upper' faces the guide face on the side of the guide
normal n = axis turned +90°, 'front' lies along +axis from the slider's reference point."""

CORNER_PAIRS = {"upper": slice(0, 2), "lower": slice(2, 4)}
"""The corner pairs, each the two corners (in ``CORNER_NAMES`` order) that face one guide face: a
pair is in contact when one of its corners is; both pairs at once is the slider jammed across the
guide on opposite corners (docs/model.md §2c)."""


def _default_contact_law():
    return Flores(stiffness=DEFAULT_CORNER_STIFFNESS, restitution=DEFAULT_CORNER_RESTITUTION)


def _default_friction_law():
    # Flores, Leine & Glocker (2010), Table 1: μ = 0.01
    return Coulomb(friction_coefficient=0.01)


class TranslationalClearanceJoint(AbstractStateElement):
    """A prismatic joint with clearance: a rectangular slider (half-length a, half-height b) on
    ``slider_body`` in a guide of half-width b + c on ``guide_body``.

    The guide's centre line passes through ``guide_point`` along ``axis`` (both in the guide body's
    frame; global for ground). The slider's reference point ``slider_point`` is the centre of the
    rectangle, whose long sides are parallel to the guide when the relative angle φ_slider − φ_guide
    equals ``angle`` (as for ``TranslationalJoint``). Each corner k has a penetration
    δ_k = s_k nᵀ(r_k − r_Q) − (b + c) into the guide face on its side (s_k = +1 upper, −1 lower),
    a normal force from ``contact_law`` along ∓n, and friction from ``friction_law`` along the
    guide axis (docs/model.md §2c).

    Attributes:
        name: label used in outputs (static).
        slider_body, guide_body: body names (static; ``"ground"`` allowed for the guide).
        slider_point: the slider rectangle's centre in the slider's frame, m.
        guide_point: a point of the guide's centre line, m.
        axis: guide direction in the guide body's frame (normalised internally).
        angle: relative angle φ_slider − φ_guide at which the slider is parallel to the guide, rad.
        half_length: a, m. half_height: b, m. clearance: c, m (guide half-width b + c).
        contact_law: corner normal law; a point law with an explicit stiffness (``CORNER_LAWS``;
            default ``Flores(stiffness=1e10, restitution=0.4)`` [ours]).
        friction_law: friction along the guide at each corner (default Coulomb, μ = 0.01).
        smoothing: regularisation widths (``Smoothing``).
        initial_offset: lateral offset of the slider centre from the guide line at assembly, m.
        initial_tilt: slider tilt at assembly, rad.
        memory_offset: carry the impact memories as u = m − δ̇ (static; set inside the solve by
            ``lawson-tsit5`` through ``Mechanism.with_memory_offset``).
    """

    name: str = eqx.field(static=True)
    slider_body: str = eqx.field(static=True)
    slider_point: Float[Array, "2"] = eqx.field(converter=_array)
    guide_body: str = eqx.field(static=True)
    guide_point: Float[Array, "2"] = eqx.field(converter=_array)
    half_length: Float[Array, ""] = eqx.field(converter=_array)
    half_height: Float[Array, ""] = eqx.field(converter=_array)
    clearance: Float[Array, ""] = eqx.field(converter=_array)
    axis: Float[Array, "2"] = eqx.field(converter=_array, default=(1.0, 0.0))
    angle: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    contact_law: AbstractContactLaw = eqx.field(default_factory=_default_contact_law)
    friction_law: AbstractFrictionLaw = eqx.field(default_factory=_default_friction_law)
    smoothing: Smoothing = eqx.field(default_factory=Smoothing)
    initial_offset: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    initial_tilt: Float[Array, ""] = eqx.field(converter=_array, default=0.0)
    memory_offset: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        owner = f"TranslationalClearanceJoint {self.name!r}"
        for attr in ("slider_point", "guide_point", "axis"):
            check_shape(owner, attr, getattr(self, attr), (2,))
            check_finite(owner, attr, getattr(self, attr))
        for attr in ("half_length", "half_height", "clearance", "angle"):
            check_shape(owner, attr, getattr(self, attr), ())
        check_positive(
            owner, "half_length", self.half_length, "m", "pass a > 0, the slider's half-length"
        )
        check_positive(
            owner, "half_height", self.half_height, "m", "pass b > 0, the slider's half-height"
        )
        check_positive(
            owner, "clearance", self.clearance, "m", "pass c > 0 (guide half-width b + c)"
        )
        check_finite(owner, "angle", self.angle)
        check_finite(owner, "initial_offset", self.initial_offset)
        check_finite(owner, "initial_tilt", self.initial_tilt)
        if is_concrete(self.axis) and not np.linalg.norm(np.asarray(self.axis)) > 0:
            raise ModelError(f"{owner}: axis must be a non-zero direction, got {self.axis}.")
        if all(is_concrete(x) for x in (self.initial_offset, self.initial_tilt, self.clearance)):
            room = float(self.clearance)
            if abs(float(self.initial_offset)) > room:
                raise ModelError(
                    f"{owner}: initial_offset {float(self.initial_offset)} m lies outside the guide "
                    f"(|offset| <= c = {room} m)."
                )
        self.smoothing.check(owner)
        if not isinstance(self.contact_law, CORNER_LAWS):
            raise ModelError(
                f"{owner}: contact_law {type(self.contact_law).__name__} does not apply to a corner on "
                "a plane; use a point law: hertz, lankarani-nikravesh, hunt-crossley, flores, "
                "gonthier, zhiying-qishao or impact, with an explicit stiffness."
            )
        if getattr(self.contact_law, "stiffness", None) is None:
            raise ModelError(
                f"{owner}: contact_law needs an explicit stiffness (a corner on a plane has no Hertz "
                f"stiffness); pass e.g. {type(self.contact_law).__name__}(stiffness=1e10)."
            )
        if not isinstance(self.friction_law, AbstractFrictionLaw):
            raise TypeError(
                f"{owner}: friction_law must be an AbstractFrictionLaw, got {type(self.friction_law).__name__}."
            )

    @classmethod
    def replacing(
        cls,
        joint,
        clearance: ArrayLike,
        half_length: ArrayLike,
        half_height: ArrayLike,
        **kwargs,
    ) -> "TranslationalClearanceJoint":
        """A translational clearance joint at the place of an ideal ``TranslationalJoint``.

        Args:
            joint: the ``TranslationalJoint`` to replace: its body_i is the slider (point_i its
                centre), body_j the guide (point_j on the guide line, ``axis``, ``angle``).
            clearance: c, m (guide half-width b + c).
            half_length, half_height: a and b of the slider, m.
            **kwargs: other fields (contact_law, friction_law, smoothing, initial_offset, ...).

        Returns:
            The joint, named like ``joint``.
        """
        return cls(
            joint.name,
            joint.body_i,
            joint.point_i,
            joint.body_j,
            joint.point_j,
            half_length=half_length,
            half_height=half_height,
            clearance=clearance,
            axis=joint.axis,
            angle=joint.angle,
            **kwargs,
        )

    # --- layout of the internal state: [m_1..m_4 (or u_k = m_k − δ̇_k), friction states per corner]
    num_corners: ClassVar[int] = 4
    memory_state_rows: ClassVar[tuple[int, ...]] = (0, 1, 2, 3)
    """Which internal states hold the impact-velocity memories (``Mechanism.memory_rows``)."""

    @property
    def num_states(self) -> int:
        """Internal states: four impact memories, then the friction law's states of each corner."""
        return self.num_corners * (1 + self.friction_law.num_states)

    @property
    def bodies(self) -> tuple[str, str]:
        """(guide body, slider body)."""
        return (self.guide_body, self.slider_body)

    @property
    def contact_geometry(self) -> ContactGeometry:
        """What the contact laws' signature asks for: a ``ContactGeometry`` with R_B = b + c and
        R_J = b, so that its ``clearance`` is c. The corner laws use their explicit stiffness, so
        the radii enter no force."""
        return ContactGeometry(self.half_height + self.clearance, self.half_height)
