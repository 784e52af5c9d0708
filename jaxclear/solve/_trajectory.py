"""The result object of ``simulate``."""

import dataclasses

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ..model import Mechanism
from ._extremes import Extremes, combine_extremes

PER_INSTANT = (
    "t",
    "q",
    "qd",
    "qdd",
    "internal_state",
    "multipliers",
    "input_torque",
    "reactions",
    "constraint_violation",
    "velocity_violation",
    "clearance",
)
"""``Trajectory`` fields with one entry per saved instant (the others are per run)."""


class Trajectory(eqx.Module):
    """A simulated trajectory sampled on the output grid.

    Shapes below are for one run; a batched run adds a leading batch axis to every array.

    Attributes:
        t: saved times (N,), s.
        q: coordinates (N, 3·bodies): x, y in m, φ in rad, per body in ``mechanism.bodies`` order.
        qd: velocities (N, 3·bodies), m/s and rad/s.
        qdd: accelerations (N, 3·bodies), m/s² and rad/s².
        internal_state: clearance/force-element internal states (N, S) (impact-velocity memory, LuGre z).
        multipliers: Lagrange multipliers λ (N, m) in ``mechanism.constraint_elements`` row order.
        input_torque: torque the driver applies to the driven body (N,), N m; positive when it acts
            in the positive (counter-clockwise) sense, so τ·ω > 0 means the motor does work. Zero
            without a driver.
        reactions: per ideal joint, its multipliers (N, k). For a revolute joint this is minus the
            force (N) that body_j exerts on body_i at the joint (see ``joint_force``).
        constraint_violation: max |Φ| over constraint rows (N,), m or rad.
        velocity_violation: max |Φ̇| (N,), m/s or rad/s.
        clearance: per clearance joint its ``ClearanceOutputs`` over time (eccentricity, penetration,
            forces, slip, impact velocity, friction state); attribute or mapping access
            (``traj.clearance["B"].normal_force`` or ``traj.clearance["B"]["normal_force"]``).
        extremes: peaks, extremes and the input-torque RMS taken from the solver's steps over the
            statistics window (``Extremes``; independent of the output grid). Named statistics:
            ``jaxclear.analysis.statistics``. ``None`` if ``simulate`` ran with ``extremes=False``.
        num_steps, num_accepted_steps, num_rejected_steps: solver statistics (scalars).
        result: diffrax outcome (``diffrax.RESULTS``); success unless the solve failed.
        input_error: 0, or the code of a check of the inputs made inside the compiled solve
            (``jaxclear.InputCheck``: the mechanism could not be assembled, a mass or inertia is not
            positive, the initial state is not finite); ``simulate`` raises for it.
        t_final: time the solver reached, s (equals the end time on success).
        y_final: state at ``t_final``.
        mechanism: the simulated mechanism (names, parameters).
    """

    # `*batch`: empty for one run, the batch axes of a batched run (built by vmap of one run).
    t: Float[Array, "*batch N"]
    q: Float[Array, "*batch N n"]
    qd: Float[Array, "*batch N n"]
    qdd: Float[Array, "*batch N n"]
    internal_state: Float[Array, "*batch N S"]
    multipliers: Float[Array, "*batch N m"]
    input_torque: Float[Array, "*batch N"]
    reactions: dict
    constraint_violation: Float[Array, "*batch N"]
    velocity_violation: Float[Array, "*batch N"]
    clearance: dict
    extremes: Extremes | None
    num_steps: Int[Array, "*batch"]
    num_accepted_steps: Int[Array, "*batch"]
    num_rejected_steps: Int[Array, "*batch"]
    result: diffrax.RESULTS
    input_error: Int[Array, "*batch"]
    t_final: Float[Array, "*batch"]
    y_final: Float[Array, "*batch Y"]  # the full state (q, q̇, internal states): Y = 2n + S
    mechanism: Mechanism

    @property
    def succeeded(self):
        """Boolean (array for batched runs): did the solve reach the end time?"""
        return (self.result == diffrax.RESULTS.successful) & (self.input_error == 0)

    def coordinates(self, body: str) -> Float[Array, "*batch N 3"]:
        """(x, y, φ) of a body over time."""
        i = self.mechanism.body_index(body)
        return self.q[..., 3 * i : 3 * i + 3]

    def velocities(self, body: str) -> Float[Array, "*batch N 3"]:
        i = self.mechanism.body_index(body)
        return self.qd[..., 3 * i : 3 * i + 3]

    def accelerations(self, body: str) -> Float[Array, "*batch N 3"]:
        i = self.mechanism.body_index(body)
        return self.qdd[..., 3 * i : 3 * i + 3]

    def joint_force(self, joint: str) -> Float[Array, "*batch N 2"]:
        """Force (N) that body_j exerts on body_i at an ideal revolute joint, global components."""
        return -self.reactions[joint]

    def joint_force_magnitude(self, joint: str) -> Float[Array, "*batch N"]:
        return jnp.linalg.norm(self.reactions[joint], axis=-1)

    def member(self, index: int) -> "Trajectory":
        """Member ``index`` of a batched trajectory (``simulate_batch``, or ``jax.vmap`` of
        ``simulate``) as a single trajectory, its mechanism included: the analysis and plot
        functions that take one run (``contact_events``, ``plot_mode_timeline``, ...) accept it.

        Raises:
            ValueError: the trajectory is not batched (one leading batch axis).
            IndexError: ``index`` outside the batch.
        """
        shape = np.shape(self.t_final)
        if len(shape) != 1:
            raise ValueError(
                f"member() takes a trajectory with one batch axis; this one has shape {shape} "
                "(a single run has ())."
            )
        if not -shape[0] <= index < shape[0]:
            raise IndexError(f"index {index} is outside the batch of {shape[0]} members.")

        def take(x):
            return x[index] if np.ndim(x) > 0 else x

        return jax.tree_util.tree_map(take, self)

    def truncated(self) -> "Trajectory":
        """The saved instants the solver actually reached (t <= t_final), e.g. after a failure.

        Only for a single (unbatched) trajectory.
        """
        keep = int(np.sum(np.asarray(self.t) <= float(self.t_final)))
        changes = {
            name: jax.tree_util.tree_map(lambda x: x[:keep], getattr(self, name))
            for name in PER_INSTANT
        }
        return dataclasses.replace(self, **changes)

    def stats(self) -> dict:
        """Solver statistics as Python numbers."""
        return dict(
            num_steps=np.asarray(self.num_steps).tolist(),
            num_accepted_steps=np.asarray(self.num_accepted_steps).tolist(),
            num_rejected_steps=np.asarray(self.num_rejected_steps).tolist(),
            t_final=np.asarray(self.t_final).tolist(),
            succeeded=np.asarray(self.succeeded).tolist(),
        )


# Units and descriptions of the per-instant outputs of a clearance joint (Trajectory.clearance);
# keys not listed here are written with an empty unit.
CLEARANCE_OUTPUTS = {
    "ecc_x": ("m", "journal-centre eccentricity relative to the bearing centre, x component"),
    "ecc_y": ("m", "journal-centre eccentricity relative to the bearing centre, y component"),
    "penetration": ("m", "penetration depth (negative: free flight)"),
    "penetration_rate": ("m/s", "rate of the penetration depth"),
    "normal_force": ("N", "normal contact force"),
    "friction_force": ("N", "friction force"),
    "tangential_force": ("N", "tangential contact force"),
    "slip_velocity": ("m/s", "relative tangential (slip) velocity"),
    "impact_velocity": ("m/s", "impact-velocity memory m = δ̇ + u (latched at contact onset)"),
    "friction_state": ("m", "friction-law internal state (LuGre bristle deflection z)"),
    "film_force_x": (
        "N",
        "hydrodynamic film force on the journal, x component (lubricated joints)",
    ),
    "film_force_y": (
        "N",
        "hydrodynamic film force on the journal, y component (lubricated joints)",
    ),
}


BODY_OUTPUTS = (
    ("x", 0, "q", "m", "x of the centre of mass"),
    ("y", 1, "q", "m", "y of the centre of mass"),
    ("phi", 2, "q", "rad", "angle of the body frame to global x"),
    ("vx", 0, "qd", "m/s", "velocity of the centre of mass, x"),
    ("vy", 1, "qd", "m/s", "velocity of the centre of mass, y"),
    ("omega", 2, "qd", "rad/s", "angular velocity"),
    ("ax", 0, "qdd", "m/s^2", "acceleration of the centre of mass, x"),
    ("ay", 1, "qdd", "m/s^2", "acceleration of the centre of mass, y"),
    ("alpha", 2, "qdd", "rad/s^2", "angular acceleration"),
)
"""Per-body columns ``<body>_<name>`` of a general mechanism: (name, coordinate, array, unit, description)."""


def _select(traj, keep: np.ndarray):
    """The trajectory at the saved instants where ``keep`` (boolean, (N,)) is true."""
    index = np.flatnonzero(keep)
    changes = {
        name: jax.tree_util.tree_map(lambda x: x[index], getattr(traj, name))
        for name in PER_INSTANT
    }
    return dataclasses.replace(traj, **changes)


def window(traj, t_start: float):
    """The saved instants at or after ``t_start`` (s): the kept window after skipped revolutions.

    Args:
        traj: a single ``Trajectory``.
        t_start: first kept time, s; a hair of round-off (1e-9 of the horizon) is allowed so that
            the instant at exactly ``t_start`` stays.
    """
    t = np.asarray(traj.t)
    slack = 1e-9 * max(abs(float(t[-1])), 1e-300)
    return _select(traj, t >= t_start - slack)


def finite_rows(traj):
    """The saved instants whose coordinates, velocities, accelerations and multipliers are all finite
    (a failed solve leaves inf/nan after the time it reached)."""
    finite = np.ones(np.asarray(traj.t).shape, dtype=bool)
    for name in ("t", "q", "qd", "qdd", "multipliers", "input_torque"):
        values = np.asarray(getattr(traj, name))
        finite &= np.all(np.isfinite(values.reshape(values.shape[0], -1)), axis=1)
    return _select(traj, finite)


def join_trajectories(parts: "list[Trajectory]") -> "Trajectory":
    """Consecutive single solves, each started from the last one's final state at its end time
    (``jaxclear.simulate_revolutions``), as one ``Trajectory``: the saved instants in time order
    with each seam kept once, the extremes of all solves combined (``combine_extremes``), the
    solver counts summed; outcome, final time and state are the last solve's, or the first failed
    one's (the solves after a failure are left out).

    Raises:
        ValueError: no parts, or a batched one.
    """
    if not parts:
        raise ValueError("join_trajectories needs at least one trajectory.")
    if any(np.ndim(p.t_final) for p in parts):
        raise ValueError("join_trajectories takes single (unbatched) trajectories.")
    failed = [i for i, p in enumerate(parts) if not bool(p.succeeded)]
    parts = parts[: failed[0] + 1] if failed else parts
    changes = {}
    for name in PER_INSTANT:  # on the host: an eager jnp.concatenate compiles per new shape
        pieces = [
            jax.tree_util.tree_map(
                lambda x, i=i: np.asarray(x)[0 if i == 0 else 1 :], getattr(p, name)
            )
            for i, p in enumerate(parts)
        ]
        changes[name] = jax.tree_util.tree_map(
            lambda *x: jnp.asarray(np.concatenate(x, axis=0)), *pieces
        )
    extremes = None
    if all(p.extremes is not None for p in parts):
        extremes = combine_extremes([p.extremes for p in parts], [float(p.t[0]) for p in parts])
    total = lambda name: jnp.asarray(sum(int(getattr(p, name)) for p in parts))  # noqa: E731
    return dataclasses.replace(
        parts[-1],
        **changes,
        extremes=extremes,
        num_steps=total("num_steps"),
        num_accepted_steps=total("num_accepted_steps"),
        num_rejected_steps=total("num_rejected_steps"),
    )
