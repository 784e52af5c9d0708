"""The Mechanism: bodies, ideal joints, a driver, force elements and clearance joints."""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core._checks import check_finite, check_shape
from .._core._errors import ModelError
from ._body import GROUND, Body
from ._clearance import ClearanceJoint
from ._element import AbstractStateElement
from ._forces import AbstractForceElement
from ._joints import AbstractDriver, AbstractJoint
from ._translational_clearance import TranslationalClearanceJoint


def _array(x):
    return jnp.asarray(x, dtype=float)


class Mechanism(eqx.Module):
    """A planar multibody mechanism (docs/model.md §1).

    Topology (names, counts, which joint connects what) is static; every physical value is an
    array leaf, so ``jax.grad`` and ``jax.vmap`` reach masses, lengths, clearances, stiffnesses, ...

    Coordinates are q = (x_1, y_1, φ_1, x_2, ...) in the order of ``bodies``; the integrator state
    is y = (q, q̇, internal states of the force elements in order of ``force_elements``).

    Attributes:
        bodies: the moving bodies.
        joints: ideal joints (revolute, translational).
        driver: optional driving constraint; its multiplier gives the input torque.
        forces: applied forces, torques, spring–dampers.
        clearance_joints: revolute clearance joints (``ClearanceJoint``; contact forces and
            internal states: impact memory, friction states).
        gravity: acceleration of gravity (g_x, g_y), m/s²; default (0, −9.81).
        baumgarte_alpha, baumgarte_beta: Baumgarte stabilisation α, β, 1/s (default 50, 50). The
            literature value 5 (docs/model.md §1) lets the benchmark slider–crank at 5000 rpm drift to
            3e-5 m at the ideal joints (comparable to contact penetrations); 50 keeps it at 3e-7 m
            for 1.5 % more steps (measured with the 'fast' preset over 200 revolutions).
        translational_clearance_joints: translational clearance joints
            (``TranslationalClearanceJoint``: a slider in a wider guide, corner contact forces and
            per-corner internal states; docs/model.md §2c). Their internal states come after the
            clearance joints' in y.
    """

    bodies: tuple[Body, ...]
    joints: tuple[AbstractJoint, ...] = ()
    driver: AbstractDriver | None = None
    forces: tuple[AbstractForceElement, ...] = ()
    clearance_joints: tuple[ClearanceJoint, ...] = ()
    gravity: Float[Array, "2"] = eqx.field(converter=_array, default=(0.0, -9.81))
    baumgarte_alpha: Float[Array, ""] = eqx.field(converter=_array, default=50.0)
    baumgarte_beta: Float[Array, ""] = eqx.field(converter=_array, default=50.0)
    translational_clearance_joints: tuple[TranslationalClearanceJoint, ...] = ()

    def __check_init__(self):
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ModelError(f"Mechanism: body names must be unique, got {names}.")
        if not self.bodies:
            raise ModelError("Mechanism: needs at least one Body.")
        labels = [c.name for c in self.constraint_elements] + [f.name for f in self.force_elements]
        dupes = sorted({x for x in labels if labels.count(x) > 1})
        if dupes:
            raise ModelError(f"Mechanism: joint/force names must be unique, repeated: {dupes}.")
        for field, kind, members in (
            ("joints", AbstractJoint, self.joints),
            ("forces", AbstractForceElement, self.forces),
            ("clearance_joints", ClearanceJoint, self.clearance_joints),
            (
                "translational_clearance_joints",
                TranslationalClearanceJoint,
                self.translational_clearance_joints,
            ),
        ):
            for member in members:
                if not isinstance(member, kind):
                    raise TypeError(
                        f"Mechanism: {field} holds a {type(member).__name__}; it takes {kind.__name__}s"
                        + (
                            " (clearance joints go in clearance_joints)"
                            if isinstance(member, ClearanceJoint)
                            else ""
                        )
                        + (
                            " (translational clearance joints go in translational_clearance_joints)"
                            if isinstance(member, TranslationalClearanceJoint)
                            else ""
                        )
                        + "."
                    )
        if self.driver is not None and not isinstance(self.driver, AbstractDriver):
            raise TypeError(
                f"Mechanism: driver must be an AbstractDriver, got {type(self.driver).__name__}."
            )
        known = set(names) | {GROUND}
        for element in (*self.constraint_elements, *self.force_elements):
            for body in element.bodies:
                if body not in known:
                    raise ModelError(
                        f"{type(element).__name__} {element.name!r}: body {body!r} is not a body of the "
                        f"mechanism; known bodies: {sorted(known)}."
                    )
        check_shape("Mechanism", "gravity", self.gravity, (2,))
        check_finite("Mechanism", "gravity", self.gravity)

    # --- static layout -------------------------------------------------------------------------
    def index(self, name: str) -> int | None:
        """Coordinate index of body ``name`` (``None`` for ground)."""
        if name == GROUND:
            return None
        for i, body in enumerate(self.bodies):
            if body.name == name:
                return i
        raise ModelError(f"Unknown body {name!r}; known: {[b.name for b in self.bodies]}.")

    def body_index(self, name: str) -> int:
        """Coordinate index of the moving body ``name``; ``ModelError`` for ground or an unknown name."""
        i = self.index(name)
        if i is None:
            raise ModelError(f"{GROUND!r} has no coordinates; pick one of {list(self.body_names)}.")
        return i

    @property
    def body_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bodies)

    @property
    def num_coordinates(self) -> int:
        return 3 * len(self.bodies)

    @property
    def constraint_elements(self) -> tuple:
        """Ideal joints, then the driver: the order of the rows of Φ and of λ."""
        return tuple(self.joints) + ((self.driver,) if self.driver is not None else ())

    @property
    def constraint_slices(self) -> dict[str, slice]:
        """Rows of Φ (and λ) of each constraint element, by name."""
        out, start = {}, 0
        for c in self.constraint_elements:
            out[c.name] = slice(start, start + c.num_equations)
            start += c.num_equations
        return out

    @property
    def num_constraints(self) -> int:
        return sum(c.num_equations for c in self.constraint_elements)

    @property
    def force_elements(self) -> tuple[AbstractStateElement, ...]:
        """Force elements, clearance joints, then translational clearance joints: the order of the
        internal states in y."""
        return (
            tuple(self.forces)
            + tuple(self.clearance_joints)
            + tuple(self.translational_clearance_joints)
        )

    @property
    def state_slices(self) -> dict[str, slice]:
        """Slices of each force element's internal states in y (after q and q̇)."""
        out, start = {}, 2 * self.num_coordinates
        for f in self.force_elements:
            out[f.name] = slice(start, start + f.num_states)
            start += f.num_states
        return out

    @property
    def memory_rows(self):
        """Boolean mask (state_size,) of the rows of y that hold a clearance joint's impact-velocity
        memory (m, or its offset u = m − δ̇ in ``with_memory_offset``). NumPy, static."""
        mask = np.zeros(self.state_size, dtype=bool)
        for joint in (*self.clearance_joints, *self.translational_clearance_joints):
            mask[[self.state_slices[joint.name].start + r for r in joint.memory_state_rows]] = True
        return mask

    @property
    def state_size(self) -> int:
        return 2 * self.num_coordinates + sum(f.num_states for f in self.force_elements)

    @property
    def degrees_of_freedom(self) -> int:
        """Coordinates minus constraints (driver included)."""
        return self.num_coordinates - self.num_constraints

    # --- values ----------------------------------------------------------------------------------
    @property
    def mass_diagonal(self) -> Float[Array, " n"]:
        """Diagonal of M = diag(m_k, m_k, J_k)."""
        return jnp.concatenate([jnp.stack([b.mass, b.mass, b.inertia]) for b in self.bodies])

    def initial_guess(self) -> tuple[Float[Array, " n"], Float[Array, " n"]]:
        """Stacked initial guesses of q and q̇ from the bodies."""
        q = jnp.concatenate([b.position for b in self.bodies])
        qd = jnp.concatenate([b.velocity for b in self.bodies])
        return q, qd

    def split_state(self, y):
        """(q, q̇, {element name: internal state}) from a state vector y."""
        n = self.num_coordinates
        states = {name: y[..., s] for name, s in self.state_slices.items()}
        return y[..., :n], y[..., n : 2 * n], states

    def with_memory_offset(self, offset: bool = True) -> "Mechanism":
        """Copy whose clearance joints carry the impact memory as u = m − δ̇ (``offset=True``) or as m.

        The offset form is what ``lawson-tsit5`` integrates (see ``_impact_memory.py`` beside the
        equations of motion; ``memory_offset_shift`` there converts states between the two forms).
        """
        joints = tuple(dataclasses.replace(c, memory_offset=offset) for c in self.clearance_joints)
        sliders = tuple(
            dataclasses.replace(c, memory_offset=offset)
            for c in self.translational_clearance_joints
        )
        return eqx.tree_at(
            lambda m: (m.clearance_joints, m.translational_clearance_joints),
            self,
            (joints, sliders),
        )

    def replace_bodies(self, **changes):
        """Copy with some bodies replaced: ``mech.replace_bodies(crank=new_body)``."""
        new = tuple(changes.get(b.name, b) for b in self.bodies)
        unknown = set(changes) - set(self.body_names)
        if unknown:
            raise ModelError(f"replace_bodies: unknown bodies {sorted(unknown)}.")
        return eqx.tree_at(lambda m: m.bodies, self, new)


def describe(mechanism: Mechanism) -> str:
    """One-paragraph text summary of a mechanism (bodies, joints, DOF)."""
    lines = [f"{len(mechanism.bodies)} bodies: {', '.join(mechanism.body_names)}"]
    for c in mechanism.constraint_elements:
        lines.append(f"  {type(c).__name__} {c.name!r}: {' - '.join(c.bodies)}")
    for f in mechanism.force_elements:
        lines.append(f"  {type(f).__name__} {f.name!r}")
    lines.append(f"degrees of freedom (driver included): {mechanism.degrees_of_freedom}")
    return "\n".join(lines)
