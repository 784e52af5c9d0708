"""Output columns of a run: a ``Trajectory`` as named, unit-tagged 1-D columns.

``result_columns`` turns a ``Trajectory`` into columns with one value per saved instant; the CSV,
the NPZ archive (``jaxclear.io.write_results``) and the plots (``jaxclear.plot``) all read these
columns, so a column added here appears everywhere.
"""

import dataclasses

import numpy as np

from ..analysis import MODE_NAMES, combination_shares, statistics, trajectory_modes
from ..analysis._modes import DEFAULT_CONTINUOUS_FRACTION, contact_modes, crank_period
from ..mechanisms import is_slider_crank
from ..model import RevoluteJoint, TranslationalJoint
from ..model._translational_clearance import CORNER_NAMES
from ..solve._trajectory import BODY_OUTPUTS, CLEARANCE_OUTPUTS

TRANSLATIONAL_OUTPUTS = {
    "offset": ("m", "lateral offset of the slider centre from the guide line (along the normal)"),
    "tilt": ("rad", "slider tilt to the guide"),
    "penetration": ("m", "largest corner penetration (negative: free flight)"),
    "normal_force": ("N", "largest corner normal force"),
    "corner_penetration": ("m", "corner penetration into its guide face (negative: gap)"),
    "corner_penetration_rate": ("m/s", "rate of the corner penetration"),
    "corner_normal_force": ("N", "corner normal contact force"),
    "corner_friction_force": ("N", "corner friction force along the guide"),
    "corner_slip_velocity": ("m/s", "corner slip velocity along the guide"),
    "corner_impact_velocity": ("m/s", "corner impact-velocity memory"),
    "corner_friction_state": ("m", "corner friction-law state (LuGre bristle deflection z)"),
}
"""Units and descriptions of a translational clearance joint's outputs. A per-corner output
``corner_<q>`` becomes the columns ``<joint>_<q>_<corner>`` (``CORNER_NAMES``: upper_front,
upper_rear, lower_rear, lower_front)."""


@dataclasses.dataclass(frozen=True)
class Column:
    """One output column: ``values`` has one entry per saved instant.

    Attributes:
        name: column name in results.csv / results.npz.
        unit: SI unit (``"deg"`` for angles given in degrees, ``""`` if dimensionless/unknown).
        description: one line for run.json and the README.
        values: float64 array of shape (N,).
    """

    name: str
    unit: str
    description: str
    values: np.ndarray


def driven_angle_deg(traj) -> np.ndarray:
    """Angle of the driven body in degrees, continuous (unwrapped) from its initial value, (N,).

    For the slider–crank this is the crank angle, 0 at outer dead centre.
    """
    mech = traj.mechanism
    if mech.driver is None:
        raise ValueError(
            "the mechanism has no driver, so it has no crank angle; plot against time instead."
        )
    phi = np.asarray(traj.coordinates(mech.driver.body))[:, 2]
    return np.degrees(np.unwrap(phi))


def result_columns(traj, continuous_fraction: float | None = None) -> list[Column]:
    """Named output columns of a single (unbatched) trajectory, in file order.

    Columns: ``t``; for a driven mechanism ``<body>_angle`` (deg) and ``<body>_torque`` (N m) of the
    driven body (``crank_angle``, ``crank_torque`` for the slider–crank); for the benchmark
    slider–crank (``is_slider_crank``) ``slider_x``, ``slider_v``, ``slider_a``, for any other
    mechanism every body's ``body_columns``; for every ideal revolute joint the force
    that its body_j exerts on its body_i, ``<joint>_Fx``, ``<joint>_Fy`` (N); for every ideal
    translational joint the moment and normal force the guide exerts on the slider,
    ``<joint>_moment`` (N m) and ``<joint>_normal`` (N); per clearance joint, in the mechanism's
    order, its outputs as ``<joint>_<output>`` (``CLEARANCE_OUTPUTS`` order) and its contact mode
    ``<joint>_mode``; per translational clearance joint its ``translational_columns`` (offset,
    tilt, per-corner penetrations and forces, modes); then ``constraint_violation`` and
    ``velocity_violation``.

    Raises:
        ValueError: ``traj`` is batched.
    """
    t = np.asarray(traj.t, dtype=float)
    if t.ndim != 1:
        raise ValueError(
            f"result_columns needs one trajectory, got a batch (t has shape {t.shape}); index it first."
        )
    mech = traj.mechanism
    benchmark = is_slider_crank(mech)
    cols = [Column("t", "s", "time", t)]
    if mech.driver is not None:
        body = mech.driver.body
        cols.append(
            Column(
                f"{body}_angle",
                "deg",
                f"angle of the driven body {body!r}, unwrapped from its initial value",
                driven_angle_deg(traj),
            )
        )
    if not benchmark:
        cols += body_columns(traj)
    if benchmark:
        cols += [
            Column(
                "slider_x",
                "m",
                "slider position along the guide (x)",
                np.asarray(traj.coordinates("slider"))[:, 0],
            ),
            Column(
                "slider_v",
                "m/s",
                "slider velocity (x)",
                np.asarray(traj.velocities("slider"))[:, 0],
            ),
            Column(
                "slider_a",
                "m/s^2",
                "slider acceleration (x)",
                np.asarray(traj.accelerations("slider"))[:, 0],
            ),
        ]
    if mech.driver is not None:
        body = mech.driver.body
        cols.append(
            Column(
                f"{body}_torque",
                "N m",
                f"input torque the driver applies to {body!r} (positive counter-clockwise; torque x speed > 0: motor does work)",
                np.asarray(traj.input_torque),
            )
        )
    for joint in mech.joints:
        lam = np.asarray(traj.reactions[joint.name])
        if isinstance(joint, RevoluteJoint):
            force = np.asarray(traj.joint_force(joint.name))
            for k, axis in enumerate("xy"):
                cols.append(
                    Column(
                        f"{joint.name}_F{axis}",
                        "N",
                        f"force {joint.body_j!r} exerts on {joint.body_i!r} at revolute joint {joint.name!r}, {axis} component",
                        force[:, k],
                    )
                )
        elif isinstance(joint, TranslationalJoint):
            # Constraint rows (relative angle, normal offset); generalised constraint force on
            # body_i is -Phi_q^T lambda (docs/model.md §1), so the guide acts on the slider with -lambda.
            cols += [
                Column(
                    f"{joint.name}_moment",
                    "N m",
                    f"moment {joint.body_j!r} exerts on {joint.body_i!r} at translational joint {joint.name!r}",
                    -lam[:, 0],
                ),
                Column(
                    f"{joint.name}_normal",
                    "N",
                    f"force {joint.body_j!r} exerts on {joint.body_i!r} normal to the guide of {joint.name!r} "
                    "(along the axis turned +90 deg)",
                    -lam[:, 1],
                ),
            ]
        else:
            for k in range(lam.shape[1]):
                cols.append(
                    Column(
                        f"{joint.name}_lambda{k}",
                        "",
                        f"Lagrange multiplier {k} of joint {joint.name!r}",
                        lam[:, k],
                    )
                )
    if traj.clearance:
        legend = ", ".join(f"{k} {v}" for k, v in MODE_NAMES.items())
        fraction = (
            DEFAULT_CONTINUOUS_FRACTION if continuous_fraction is None else continuous_fraction
        )
        modes = trajectory_modes(traj, fraction)
        # traj.clearance comes back from JAX with its keys sorted; write the joints in the
        # mechanism's order and each joint's outputs in CLEARANCE_OUTPUTS order, then its mode.
        for name in clearance_joint_names(traj):
            outputs = traj.clearance[name]
            keys = [k for k in CLEARANCE_OUTPUTS if k in outputs] + sorted(
                k for k in outputs if k not in CLEARANCE_OUTPUTS
            )
            for key in keys:
                value = np.asarray(outputs[key], dtype=float) + 0.0  # + 0.0: no '-0' in the CSV
                unit, description = CLEARANCE_OUTPUTS.get(key, ("", key.replace("_", " ")))
                if value.ndim == 1:
                    cols.append(
                        Column(
                            f"{name}_{key}",
                            unit,
                            f"{description} at clearance joint {name!r}",
                            value,
                        )
                    )
                else:
                    flat = value.reshape(value.shape[0], -1)
                    for k in range(flat.shape[1]):
                        cols.append(
                            Column(
                                f"{name}_{key}_{k}",
                                unit,
                                f"{description} [{k}] at clearance joint {name!r}",
                                flat[:, k],
                            )
                        )
            cols.append(
                Column(
                    f"{name}_mode",
                    "",
                    f"contact mode at clearance joint {name!r} ({legend})",
                    modes[name].astype(float),
                )
            )
    cols += translational_columns(traj, continuous_fraction)
    cols += [
        Column(
            "constraint_violation",
            "m",
            "max |Phi| over constraint rows (m or rad)",
            np.asarray(traj.constraint_violation),
        ),
        Column(
            "velocity_violation",
            "m/s",
            "max |dPhi/dt| over constraint rows (m/s or rad/s)",
            np.asarray(traj.velocity_violation),
        ),
    ]
    names = [c.name for c in cols]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"output column names collide: {dupes}; rename the joints or bodies.")
    return cols


def translational_columns(traj, continuous_fraction: float | None = None) -> list[Column]:
    """Columns of each translational clearance joint J (docs/model.md §2c): ``J_offset``,
    ``J_tilt``, ``J_penetration`` and ``J_normal_force`` (largest over the corners), per corner
    ``J_<quantity>_<corner>`` (``TRANSLATIONAL_OUTPUTS``), the joint's contact mode ``J_mode``
    (from its largest corner penetration) and the modes of its two corner pairs, ``J_mode_upper``
    and ``J_mode_lower`` (the slider against the upper or the lower guide face)."""
    names = translational_clearance_joint_names(traj)
    if not names:
        return []
    fraction = DEFAULT_CONTINUOUS_FRACTION if continuous_fraction is None else continuous_fraction
    t = np.asarray(traj.t, dtype=float)
    period = crank_period(traj.mechanism) or float(t[-1] - t[0])
    legend = ", ".join(f"{k} {v}" for k, v in MODE_NAMES.items())
    cols = []
    for name in names:
        outputs = traj.clearance[name]
        for key in outputs.keys():
            value = np.asarray(outputs[key], dtype=float) + 0.0  # + 0.0: no '-0' in the CSV
            unit, description = TRANSLATIONAL_OUTPUTS.get(key, ("", key.replace("_", " ")))
            where = f"at translational clearance joint {name!r}"
            if value.ndim == 1:
                cols.append(Column(f"{name}_{key}", unit, f"{description} {where}", value))
                continue
            quantity = key.removeprefix("corner_")
            for k, corner in enumerate(CORNER_NAMES):
                cols.append(
                    Column(
                        f"{name}_{quantity}_{corner}",
                        unit,
                        f"{description}, {corner.replace('_', ' ')} corner, {where}",
                        value[:, k],
                    )
                )
        pen = np.asarray(outputs["corner_penetration"], dtype=float)
        for suffix, what, depth in (
            ("", "", pen.max(axis=1)),
            ("_upper", " of the upper corner pair", pen[:, :2].max(axis=1)),
            ("_lower", " of the lower corner pair", pen[:, 2:].max(axis=1)),
        ):
            cols.append(
                Column(
                    f"{name}_mode{suffix}",
                    "",
                    f"contact mode{what} at translational clearance joint {name!r} ({legend})",
                    contact_modes(t, depth, fraction * period).astype(float),
                )
            )
    return cols


def body_columns(traj) -> list[Column]:
    """Position, velocity and acceleration of every body's centre of mass and frame (``BODY_OUTPUTS``)."""
    cols = []
    for body in traj.mechanism.body_names:
        i = traj.mechanism.index(body)
        for name, k, array, unit, description in BODY_OUTPUTS:
            values = np.asarray(getattr(traj, array))[:, 3 * i + k]
            cols.append(Column(f"{body}_{name}", unit, f"{description} of body {body!r}", values))
    return cols


def mode_shares(traj, continuous_fraction: float, reference_period: float | None = None) -> dict:
    """Time share of each combination of contact modes over the saved instants (docs/model.md §7)."""
    modes = trajectory_modes(traj, continuous_fraction, reference_period)
    names = clearance_joint_names(traj) + translational_clearance_joint_names(traj)
    return combination_shares({name: modes[name] for name in names})


def run_statistics(traj) -> dict[str, float]:
    """The run's ``statistics`` object for run.json: ``jaxclear.analysis.statistics`` as numbers.

    The values come from the solver's steps over the window that ``simulate``'s
    ``statistics_start`` opened (``jaxclear run`` passes the start of the kept revolutions).
    """
    return {name: float(value) for name, value in statistics(traj).items()}


def clearance_joint_names(traj) -> list[str]:
    """Names of the trajectory's revolute clearance joints in the mechanism's order (O, A, B for
    the slider–crank); translational clearance joints: ``translational_clearance_joint_names``."""
    order = [j.name for j in getattr(traj.mechanism, "clearance_joints", ())]
    sliders = set(translational_clearance_joint_names(traj))
    return [n for n in order if n in traj.clearance] + sorted(
        n for n in traj.clearance if n not in order and n not in sliders
    )


def translational_clearance_joint_names(traj) -> list[str]:
    """Names of the trajectory's translational clearance joints, in the mechanism's order."""
    order = [j.name for j in getattr(traj.mechanism, "translational_clearance_joints", ())]
    return [n for n in order if n in traj.clearance]


def column_map(traj) -> dict[str, Column]:
    """``result_columns`` keyed by name."""
    return {c.name: c for c in result_columns(traj)}


def column_summary(columns: list[Column]) -> dict:
    """Units, descriptions and min/max of every column (for run.json)."""
    out = {}
    for c in columns:
        finite = c.values[np.isfinite(c.values)]
        out[c.name] = dict(
            unit=c.unit,
            description=c.description,
            min=float(finite.min()) if finite.size else None,
            max=float(finite.max()) if finite.size else None,
        )
    return out
