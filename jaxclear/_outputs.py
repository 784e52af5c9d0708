"""Result files of a run: ``results.csv``, ``results.npz`` and ``run.json``.

``result_columns`` turns a ``Trajectory`` into named, unit-tagged 1-D columns (one value per saved
instant); the CSV, the NPZ archive and the plots (``jaxclear.plot``) all read these columns, so a
column added here appears everywhere. Files are written to a temporary name in the output folder
and renamed into place, so an interrupted run never leaves a truncated file under a final name.
"""

import dataclasses
import json
import os
import platform
import tempfile
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from ._trajectory import PER_INSTANT
from .model import RevoluteJoint, TranslationalJoint

CSV_NAME = "results.csv"
NPZ_NAME = "results.npz"
RUN_JSON_NAME = "run.json"
RUN_FORMAT = 1
"""Version of the run.json layout; bump when keys change meaning."""

CSV_FORMAT = "%.12g"
"""12 significant digits in the CSV (results.npz keeps full float64 precision)."""

VERSIONED_PACKAGES = (
    "jaxclear",
    "jax",
    "jaxlib",
    "diffrax",
    "equinox",
    "lineax",
    "optimistix",
    "numpy",
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
}


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
    ``<joint>_mode``; then ``constraint_violation`` and ``velocity_violation``.

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
        from .analysis import MODE_NAMES, trajectory_modes
        from .analysis._modes import DEFAULT_CONTINUOUS_FRACTION

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


def is_slider_crank(mechanism) -> bool:
    """Whether ``mechanism`` is the benchmark slider–crank (bodies ``crank``, ``rod``, ``slider``),
    whose results keep their established columns ``slider_x``, ``slider_v``, ``slider_a``."""
    return tuple(mechanism.body_names) == ("crank", "rod", "slider")


def body_columns(traj) -> list[Column]:
    """Position, velocity and acceleration of every body's centre of mass and frame (``BODY_OUTPUTS``)."""
    cols = []
    for body in traj.mechanism.body_names:
        i = traj.mechanism.index(body)
        for name, k, array, unit, description in BODY_OUTPUTS:
            values = np.asarray(getattr(traj, array))[:, 3 * i + k]
            cols.append(Column(f"{body}_{name}", unit, f"{description} of body {body!r}", values))
    return cols


def _select(traj, keep: np.ndarray):
    """The trajectory at the saved instants where ``keep`` (boolean, (N,)) is true."""
    import jax

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


def mode_shares(traj, continuous_fraction: float, reference_period: float | None = None) -> dict:
    """Time share of each combination of contact modes over the saved instants (docs/model.md §7)."""
    from .analysis import combination_shares, trajectory_modes

    modes = trajectory_modes(traj, continuous_fraction, reference_period)
    return combination_shares({name: modes[name] for name in clearance_joint_names(traj)})


def run_statistics(traj) -> dict[str, float]:
    """The run's ``statistics`` object for run.json: ``jaxclear.analysis.statistics`` as numbers.

    The values come from the solver's steps over the window that ``simulate``'s
    ``statistics_start`` opened (``jaxclear run`` passes the start of the kept revolutions).
    """
    from .analysis import statistics

    return {name: float(value) for name, value in statistics(traj).items()}


def clearance_joint_names(traj) -> list[str]:
    """Names of the trajectory's clearance joints in the mechanism's order (O, A, B for the slider–crank)."""
    order = [j.name for j in getattr(traj.mechanism, "clearance_joints", ())]
    return [n for n in order if n in traj.clearance] + sorted(
        n for n in traj.clearance if n not in order
    )


def column_map(traj) -> dict[str, Column]:
    """``result_columns`` keyed by name."""
    return {c.name: c for c in result_columns(traj)}


# --- writing ------------------------------------------------------------------------------------


def atomic_write(path: Path, write: Callable[[str], None]) -> Path:
    """Call ``write(tmp_path)`` then rename the temporary file to ``path`` (same folder)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_csv(path: Path, columns: list[Column]) -> Path:
    """Header of column names, then one row per instant (``CSV_FORMAT``)."""
    data = np.column_stack([c.values for c in columns])
    header = ",".join(c.name for c in columns)

    def write(tmp):
        with open(tmp, "w", newline="") as f:
            np.savetxt(f, data, delimiter=",", fmt=CSV_FORMAT, header=header, comments="")

    return atomic_write(path, write)


def write_modes_csv(path: Path, events: dict) -> Path:
    """modes.csv: one row per contact of each clearance joint (``analysis.contact_events``):
    joint, onset_s, end_s, duration_s, mode (impact or continuous), finished (0 for a contact
    still in progress at the end of the run), in time order."""
    from .analysis import MODE_NAMES

    rows = []
    for joint, e in events.items():
        for k in range(len(e["onset"])):
            rows.append(
                (
                    float(e["onset"][k]),
                    joint,
                    float(e["end"][k]),
                    float(e["duration"][k]),
                    MODE_NAMES[int(e["mode"][k])],
                    int(bool(e["finished"][k])),
                )
            )
    rows.sort()

    def write(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            f.write("joint,onset_s,end_s,duration_s,mode,finished\n")
            for onset, joint, end, duration, mode, finished in rows:
                f.write(f"{joint},{onset!r},{end!r},{duration!r},{mode},{finished}\n")

    return atomic_write(path, write)


def write_npz(path: Path, columns: list[Column]) -> Path:
    """One float64 array per column, same names as the CSV."""

    def write(tmp):
        with open(tmp, "wb") as f:
            arrays: dict[str, Any] = {c.name: c.values for c in columns}
            np.savez(f, **arrays)

    return atomic_write(path, write)


def write_json(path: Path, data: dict) -> Path:
    def write(tmp):
        with open(tmp, "w") as f:
            json.dump(_jsonable(data), f, indent=2, allow_nan=False)
            f.write("\n")

    return atomic_write(path, write)


def _jsonable(x):
    """Plain JSON types; non-finite floats become strings ("nan", "inf") to keep the file valid."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray | np.generic):
        return _jsonable(x.tolist())
    if isinstance(x, float) and not np.isfinite(x):
        return str(x)
    if isinstance(x, Path):
        return str(x)
    return x


def package_versions() -> dict[str, str | None]:
    """Installed versions of jaxclear and its numerical dependencies."""
    versions = {}
    for name in VERSIONED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    versions["python"] = platform.python_version()
    return versions


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


def write_results(
    out_dir: Path, traj, run_info: dict, continuous_fraction: float | None = None
) -> dict[str, Path]:
    """Write results.npz, results.csv and (last) run.json into ``out_dir``.

    Args:
        out_dir: output folder (created if missing).
        traj: a successful single ``Trajectory``.
        run_info: configuration, timings, ... merged into run.json.
        continuous_fraction: contact-mode threshold (fraction of a crank period) for ``<J>_mode``.

    Returns:
        ``{"csv": path, "npz": path, "run_json": path}``.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    columns = result_columns(traj, continuous_fraction)
    paths = {
        "npz": write_npz(out_dir / NPZ_NAME, columns),
        "csv": write_csv(out_dir / CSV_NAME, columns),
    }
    info = dict(run_info)
    info["columns"] = column_summary(columns)
    info.setdefault("files", [])
    info["files"] = sorted({*info["files"], CSV_NAME, NPZ_NAME, RUN_JSON_NAME})
    paths["run_json"] = write_json(out_dir / RUN_JSON_NAME, info)
    return paths
