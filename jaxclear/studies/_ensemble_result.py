"""An ensemble's per-member results and their files: the member table, the manifest, resuming.

``run_ensemble`` returns an ``EnsembleResult``. With ``EnsembleSettings.out`` given it keeps the
finished members in a folder after every chunk: the member table (``table_name``, one CSV row per
finished member, floats written with ``repr``) and the manifest ``ensemble.json`` (the run's
configuration, its fingerprint, counts), each replaced atomically. A later run with the same
configuration reads them back (``resume``) and solves only the members not on disk; a run with
another configuration, or a table whose drawn values differ, is refused.
"""

import csv
import dataclasses
import hashlib
import json
import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._core._errors import EnsembleError
from ..io import atomic_write, write_json
from ..model import Mechanism, get_parameter, parameter_names

MANIFEST = "ensemble.json"
"""The manifest's file name in the output folder."""
OK, FAILED = "ok", "failed"


@dataclasses.dataclass
class EnsembleResult:
    """Per-member results of ``run_ensemble``, in member order.

    Attributes:
        names: the drawn parameters' names (``B.clearance``, ``rod_mass``, ...).
        values: (N, len(names)) drawn values, SI units.
        statistics: {name: (N,) values}, NaN where the member failed. Names: those of
            ``jaxclear.analysis.statistics`` (``B_peak_normal_force``, ``crank_torque_rms``, ...),
            ``<signal>_deviation`` (RMS deviation from the ideal mechanism over the statistics
            window), ``torque_fluctuation`` (RMS of the input torque about its mean), and the
            contact modes over the statistics window from the contacts located from the solver's
            steps (``mode_statistic_names``: per joint ``<J>_free_share``, ``<J>_impact_share``,
            ``<J>_continuous_share``, ``<J>_impacts``, ``<J>_continuous_contacts``; per
            combination ``combination_C-I-F_share`` and so on).
        status: (N,) ``"ok"`` or ``"failed"``.
        messages: (N,) why a member failed (``""`` if it did not).
        num_steps: (N,) solver steps (0 for members not solved).
        wall_time_s: (N,) the wall time of the member's chunk divided by its members.
    """

    names: tuple[str, ...]
    values: np.ndarray
    statistics: dict[str, np.ndarray]
    status: np.ndarray
    messages: list[str]
    num_steps: np.ndarray
    wall_time_s: np.ndarray

    @property
    def succeeded(self) -> np.ndarray:
        return self.status == OK

    def __len__(self) -> int:
        return len(self.status)

    def rows(self) -> list[dict[str, Any]]:
        """One dict per member: ``index``, drawn values, statistics, steps, time, status, message."""
        rows = []
        for i in range(len(self)):
            row: dict[str, Any] = {"index": i}
            row.update({n: float(self.values[i, k]) for k, n in enumerate(self.names)})
            row.update({k: float(v[i]) for k, v in self.statistics.items()})
            row.update(
                num_steps=int(self.num_steps[i]),
                wall_time_s=float(self.wall_time_s[i]),
                status=str(self.status[i]),
                message=self.messages[i],
            )
            rows.append(row)
        return rows

    def summary(self) -> dict[str, Any]:
        """Over the members that succeeded: percentiles 5/50/95, mean and its standard error, min,
        max of each statistic; counts and the failures' messages."""
        ok = self.succeeded
        out: dict[str, Any] = {
            "members": len(self),
            "succeeded": int(ok.sum()),
            "failed": int((~ok).sum()),
            "failures": [
                {"index": int(i), "message": self.messages[i]} for i in np.flatnonzero(~ok)
            ],
            "statistics": {},
        }
        for name, v in self.statistics.items():
            x = v[ok]
            x = x[np.isfinite(x)]
            if x.size == 0:
                continue
            p5, p50, p95 = np.percentile(x, [5, 50, 95])
            out["statistics"][name] = {
                "mean": float(x.mean()),
                "standard_error": float(x.std(ddof=1) / math.sqrt(x.size)) if x.size > 1 else None,
                "p5": float(p5),
                "p50": float(p50),
                "p95": float(p95),
                "min": float(x.min()),
                "max": float(x.max()),
                "count": int(x.size),
            }
        return out


def fingerprint(description: Mapping[str, Any]) -> str:
    """A short hash of a JSON-able description of an ensemble (its configuration)."""
    text = json.dumps(description, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def configuration_differences(old: Mapping, new: Mapping, prefix="") -> list[str]:
    """Dotted keys whose values differ between two JSON-able configurations (nested mappings)."""
    keys = sorted(set(old) | set(new))
    out = []
    for k in keys:
        a, b = old.get(k), new.get(k)
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            out += configuration_differences(a, b, f"{prefix}{k}.")
        elif json.dumps(a, default=str) != json.dumps(b, default=str):
            out.append(f"{prefix}{k}")
    return out


def write_table(path: Path, result: EnsembleResult, finished: np.ndarray) -> None:
    """The finished members' rows (``EnsembleResult.rows``) as CSV, replaced atomically."""
    rows = [r for r, f in zip(result.rows(), finished) if f]
    fields = list(result.rows()[0]) if len(result) else ["index"]

    def write(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            for r in rows:
                w.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})

    atomic_write(path, write)


class ResumeWarning(UserWarning):
    """Something in an output folder was set right while resuming (a torn last row dropped)."""


def read_table(path: Path, names: Sequence[str]) -> list[dict[str, str]]:
    """The rows of a member table as strings (none if absent, or without the drawn ``names``).

    The table is always replaced whole and ends with a newline, so a last row without one (or with
    fewer fields than the header) was torn by a crash while the file system wrote it: it is dropped
    with a ``ResumeWarning`` and its member is solved again.
    """
    if not path.exists():
        return []
    text = path.read_text(encoding="utf-8")
    rows = list(csv.DictReader(text.splitlines()))
    if rows and (not text.endswith("\n") or None in rows[-1].values()):
        warnings.warn(
            ResumeWarning(
                f"{path}: the last row was cut short (a write interrupted by a crash); dropped, "
                "its member is solved again"
            ),
            stacklevel=2,
        )
        rows = rows[:-1]
    if rows and not set(names) <= set(rows[0]):
        return []
    return rows


def mechanism_values(mechanism: Mechanism) -> dict[str, Any]:
    """The base mechanism as JSON-able values: its parameters by name and its structure."""
    out: dict[str, Any] = {}
    for name in parameter_names(mechanism):
        try:
            out[name] = float(np.asarray(get_parameter(mechanism, name)))
        except (TypeError, ValueError):  # a non-scalar parameter: its repr decides
            out[name] = repr(np.asarray(get_parameter(mechanism, name)).tolist())
    out["laws"] = {
        j.name: [type(j.contact_law).__name__, type(j.friction_law).__name__]
        for j in mechanism.clearance_joints
    }
    out["bodies"] = list(mechanism.body_names)
    return out


def save(
    out_dir: Path,
    table_name: str,
    configuration: Mapping[str, Any],
    result: EnsembleResult,
    finished: np.ndarray,
) -> None:
    """Write the finished members' table and the manifest (``configuration`` under
    ``"settings"``, its fingerprint, counts), each replaced atomically."""
    write_table(out_dir / table_name, result, finished)
    write_json(
        out_dir / MANIFEST,
        {
            "settings": configuration,
            "fingerprint": fingerprint(configuration),
            "finished": int(finished.sum()),
            "failed": int((finished & (result.status != OK)).sum()),
            "table": table_name,
        },
    )


def resume(
    out_dir: Path,
    table_name: str,
    configuration: Mapping[str, Any],
    result: EnsembleResult,
    finished: np.ndarray,
) -> None:
    """Read back the members a run with this ``configuration`` left in ``out_dir``: their rows go
    into ``result`` and ``finished`` (both changed in place). Nothing happens without a manifest.

    Raises:
        EnsembleError: the manifest cannot be read, holds another configuration (naming what
            changed), or a member on disk has other drawn values than ``result``.
    """
    manifest = out_dir / MANIFEST
    if not manifest.exists():
        return
    try:
        old = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        raise EnsembleError(
            f"{manifest} cannot be read ({e}); remove it or choose another output folder."
        ) from None
    if old.get("fingerprint") != fingerprint(configuration):
        changed = configuration_differences(
            old.get("settings", {}), json.loads(json.dumps(configuration, default=str))
        )
        raise EnsembleError(
            f"{out_dir} holds an ensemble with another configuration (changed: "
            f"{', '.join(changed[:6]) or 'format'}); resume with the same settings, or choose "
            "another output folder."
        )
    for line, row in enumerate(read_table(out_dir / table_name, result.names), start=2):
        try:
            i = int(row["index"])
            drawn = np.asarray([float(row[nm]) for nm in result.names])
            stats = {k: float(row[k]) for k in result.statistics if k in row and row[k] != ""}
            steps = int(row.get("num_steps", 0) or 0)
            wall = float(row.get("wall_time_s", 0.0) or 0.0)
        except (KeyError, TypeError, ValueError) as e:
            raise EnsembleError(
                f"{out_dir / table_name}, line {line}: not a member row ({type(e).__name__}: {e}); "
                "the table was changed by hand or by another program: restore it, or choose another "
                "output folder."
            ) from None
        if not (0 <= i < len(result)):
            continue
        if not np.array_equal(drawn, result.values[i]):
            raise EnsembleError(
                f"{out_dir / table_name}: member {i} has other drawn values than this run "
                "would draw; resume with the same settings and seed, or choose another folder."
            )
        for k, v in stats.items():
            result.statistics[k][i] = v
        result.status[i] = row.get("status", FAILED)
        result.messages[i] = row.get("message", "")
        result.num_steps[i] = steps
        result.wall_time_s[i] = wall
        finished[i] = True
