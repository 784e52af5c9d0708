"""What the commands share to prepare a solve from their settings: the solver, the output grid,
the kept window and a writable output folder."""

import os
import tempfile
from pathlib import Path

from ..solve import recommended_solver, solver_config
from ._common import UsageError
from ._config import Settings
from ._setting_table import solver_help, solver_names
from ._settings import AUTO


def solver_for(settings: Settings, mechanism=None):
    """The run's ``SolverConfig``; ``auto`` is decided from ``mechanism`` (``recommended_solver``)."""
    section = settings.config["solver"]
    name = section["method"]
    if name not in solver_names():
        raise UsageError(
            f"{settings.source('solver', 'method')}: solver {name!r} is unknown; choose {solver_help()}"
        )
    if name == "auto":
        name = recommended_solver(mechanism).method if mechanism is not None else "fast"
    solver = solver_config(name)
    changes = {k: section[k] for k in ("rtol", "atol", "max_steps") if section[k] is not None}
    changes = {k: float(v) if k != "max_steps" else v for k, v in changes.items()}
    return solver.replace(**changes) if changes else solver


def grid(settings: Settings, revolutions: float | int | None = None) -> tuple[float, int]:
    """(end time in s, number of saved instants) of the configured revolutions, or of
    ``revolutions`` if given.

    Raises:
        UsageError: ``revolutions = "auto"`` in a command that needs a fixed horizon (ensembles,
            fits): only ``jaxclear run`` decides its horizon as it goes.
    """
    rpm = settings.config["mechanism"]["rpm"]
    if revolutions is None:
        revolutions = settings.config["simulation"]["revolutions"]
    if revolutions == AUTO:
        raise UsageError(
            f"{settings.source('simulation', 'revolutions')} auto is for jaxclear run only (it "
            "solves until the response settles); give a number of revolutions here"
        )
    intervals = max(1, round(revolutions * settings.config["simulation"]["points_per_revolution"]))
    return 60.0 * revolutions / rpm, intervals + 1


def kept_start(settings: Settings) -> float:
    """Start of the kept window (after ``skip_revolutions``), s."""
    return (
        60.0
        * settings.config["simulation"]["skip_revolutions"]
        / settings.config["mechanism"]["rpm"]
    )


def prepare_output(settings: Settings) -> Path:
    """Create the output folder and prove it writable (a temporary file), before any solve.

    Raises:
        UsageError: the path is a file, or the folder cannot be created or written.
    """
    text = settings.config["output"]["directory"]
    source = settings.source("output", "directory")
    out_dir = Path(text)
    if out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"{source} {text!r} exists and is not a folder; choose another path")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".jaxclear-write-test.", dir=out_dir)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise UsageError(
            f"{source} {text!r} is not writable ({e.strerror or e}); choose a folder you can write to"
        ) from None
    return out_dir
