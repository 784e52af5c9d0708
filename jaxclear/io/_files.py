"""Result files of a run: ``results.csv``, ``results.npz``, ``run.json`` and ``modes.csv``.

Files are written to a temporary name in the output folder and renamed into place, so an
interrupted run never leaves a truncated file under a final name.
"""

import json
import os
import platform
import tempfile
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import MODE_NAMES
from ._columns import Column, column_summary, result_columns

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


def write_revolutions_csv(path: Path, rows: list[dict]) -> Path:
    """revolutions.csv: one row per revolution (``revolution_rows``): its index, start and end
    times, whether the summary keeps it, then its statistics and contact-mode shares; empty
    cells where a revolution has no value (left out of the statistics window)."""
    names = list(dict.fromkeys(k for row in rows for k in row))

    def cell(v):
        if v is None or (isinstance(v, float) and not np.isfinite(v)):
            return ""
        return repr(float(v)) if isinstance(v, float) else str(v)

    def write(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            f.write(",".join(names) + "\n")
            for row in rows:
                f.write(",".join(cell(row.get(k)) for k in names) + "\n")

    return atomic_write(path, write)


def write_modes_csv(path: Path, events: dict) -> Path:
    """modes.csv: one row per contact of each clearance joint (``analysis.contact_events``):
    joint, onset_s, end_s, duration_s, mode (impact or continuous), finished (0 for a contact
    still in progress at the end of the run), in time order."""
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
