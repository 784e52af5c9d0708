"""Output folders: each holds one command's results, complete, or the earlier ones untouched.

- ``run`` and ``fit`` write into a fresh staging folder beside ``--out`` (``.NAME.partial-<random>``)
  and move it into place at the end (``StagedOutput.publish``): an interrupted or failed write
  leaves the earlier folder as it was, never a mix of two runs.
- ``montecarlo`` and ``sweep`` write in place, each file replaced atomically after every chunk,
  so that a killed run resumes from what it finished (the engine's manifest ``ensemble.json``).
- A folder that holds another command's results, another configuration's (the settings, or the
  config file's per-joint or custom-mechanism tables), or result files whose manifest is gone, is
  refused before anything is solved; ``--force`` moves it aside first (``NAME.replaced-<UTC
  time>``, nothing is deleted).
"""

import json
import os
import shutil
import tempfile
from datetime import UTC, datetime
from pathlib import Path

from ..internal import MANIFEST, configuration_differences
from ._common import UsageError

MANIFESTS = {"run.json": "run", "fit.json": "fit", "sweep.json": "sweep"}
"""The file by which each command's folder is known (montecarlo: the engine's manifest with its
table samples.csv)."""
ENSEMBLE_TABLES = {"samples.csv": "montecarlo", "sweep.csv": "sweep"}


def folder_owner(path: Path) -> str | None:
    """Which command's results ``path`` holds: ``"run"``, ``"fit"``, ``"montecarlo"``,
    ``"sweep"``, ``"unknown"`` (files no command's manifest accounts for), or ``None`` (no folder,
    or an empty one)."""
    if not path.is_dir() or not any(path.iterdir()):
        return None
    for name, command in MANIFESTS.items():
        if (path / name).is_file():
            return command
    manifest = path / MANIFEST
    if manifest.is_file():
        try:
            table = json.loads(manifest.read_text(encoding="utf-8")).get("table")
        except (OSError, ValueError, AttributeError):
            return "unknown"
        return ENSEMBLE_TABLES.get(table, "unknown")
    return "unknown"


UNRELATED = (("solver", "compilation_cache"),)
"""Settings that do not change the results, so a folder may be run again with another value."""


MECHANISM_ENTRIES = {"clearance_per_joint": "clearance", "description": None}
"""The manifest entries besides ``config`` that hold the config file's other mechanism tables
(run.json has both, fit.json ``clearance_per_joint`` only), and where each goes in the compared
configuration: the per-joint tables ``[clearance.<joint>]`` inside ``clearance`` (so a change
reads ``clearance.B.lubrication.length``, its path in the file; a joint's name is never a shared
key of [clearance]), the custom mechanism's tables (``bodies``, ``joints``, ...) at the top."""


def _configuration(manifest: dict, recorded: set[str]) -> dict:
    """What must match for a folder to be run again: the configuration (every section but [output]
    and ``UNRELATED``), with the ``MECHANISM_ENTRIES`` of ``recorded`` merged in.

    Args:
        manifest: ``{"config": ..., "clearance_per_joint": ..., "description": ...}`` (a missing
            entry counts as empty).
        recorded: the ``MECHANISM_ENTRIES`` the earlier manifest holds; an entry it lacks is left
            out of both sides (what it held is not known).
    """
    plain = json.loads(json.dumps(manifest.get("config") or {}, default=str))
    plain.pop("output", None)
    for section, key in UNRELATED:
        plain.get(section, {}).pop(key, None)
    for entry, section in MECHANISM_ENTRIES.items():
        if entry not in recorded:
            continue
        tables = json.loads(json.dumps(manifest.get(entry) or {}, default=str))
        (plain if section is None else plain.setdefault(section, {})).update(tables)
    return plain


def claim_output(settings, command: str, say=print) -> Path:
    """Check that ``--out`` may take this command's results; move it aside under ``--force``.

    Allowed without ``--force``: no folder or an empty one; the same command's folder with the same
    configuration (``run``, ``fit``: replaced when the new results are complete); for
    ``montecarlo`` and ``sweep`` a folder with the engine's manifest, which resumes (the engine
    refuses another configuration, naming what changed).

    Returns:
        The output folder (not created here).

    Raises:
        UsageError: the folder holds other results (naming whose and how to proceed), or ``--out``
            is a file.
    """
    text = settings.config["output"]["directory"]
    source = settings.source("output", "directory")
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{source} {text!r} exists and is not a folder; choose another path")
    owner = folder_owner(out)
    if owner is None:
        return out
    current = {
        "config": settings.config,
        "clearance_per_joint": settings.joint_tables,
        "description": settings.description,
    }
    why = _conflict(out, owner, command, current)
    if why is None:
        return out
    if not settings.config["output"]["force"]:
        raise UsageError(
            f"{source} {text!r} holds {why}; choose another folder, or pass --force to move it "
            "aside and start afresh"
        )
    aside = out.with_name(f"{out.name}.replaced-{datetime.now(UTC):%Y%m%dT%H%M%S%fZ}")
    try:
        out.rename(aside)
    except OSError as e:
        raise UsageError(
            f"--force: cannot move {text!r} aside ({e.strerror or e}); choose another folder"
        ) from None
    say(f"note: {text} held {why}; moved aside to {aside}")
    return out


def _conflict(out: Path, owner: str, command: str, current: dict) -> str | None:
    """Why ``out`` (holding ``owner``'s results) cannot take ``command``'s, or ``None``.

    ``current``: this command's ``config``, ``clearance_per_joint`` and ``description``, compared
    with the same entries of the folder's manifest (``_configuration``)."""
    if owner == "unknown":
        return "files that no jaxclear manifest accounts for (results whose manifest is missing?)"
    if owner != command:
        return f"the results of 'jaxclear {owner}'"
    if command in ("montecarlo", "sweep"):
        return None  # the engine resumes it, or refuses another configuration
    try:
        old = json.loads((out / f"{command}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return f"a {command}.json that cannot be read"
    if not isinstance(old, dict) or not isinstance(old.get("config"), dict):
        return f"a {command}.json without its configuration"
    recorded = {entry for entry in MECHANISM_ENTRIES if isinstance(old.get(entry), dict)}
    changed = configuration_differences(
        _configuration(old, recorded), _configuration(current, recorded)
    )
    if changed:
        return f"a {command} of another configuration (changed: {', '.join(changed[:6])})"
    return None


class StagedOutput:
    """A fresh folder beside the output folder, moved into place by ``publish``.

    Args:
        out: the output folder (``claim_output``'s).
        source: how the user named it (for messages).

    Raises:
        UsageError: the parent folder cannot be created or written.
    """

    def __init__(self, out: Path, source: str):
        self.out = out
        parent = out.parent if str(out.parent) else Path(".")
        blocking = next(
            (p for p in (parent, *parent.parents) if p.exists() and not p.is_dir()), None
        )
        if blocking is not None:
            raise UsageError(
                f"{source} {str(out)!r} is not writable (Not a directory): {str(blocking)!r} is a "
                "file; choose a folder you can write to"
            )
        try:
            parent.mkdir(parents=True, exist_ok=True)
            self.stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=parent))
            fd, probe = tempfile.mkstemp(prefix=".jaxclear-write-test.", dir=self.stage)
            os.close(fd)
            os.unlink(probe)
        except OSError as e:
            if getattr(self, "stage", None) is not None:
                shutil.rmtree(self.stage, ignore_errors=True)
            raise UsageError(
                f"{source} {str(out)!r} is not writable ({e.strerror or e}); choose a folder you "
                "can write to"
            ) from None

    def publish(self) -> Path:
        """Move the staged results into place; an earlier folder there is removed only after."""
        old = None
        if self.out.exists():
            old = self.out.with_name(f".{self.out.name}.old-{os.getpid()}")
            self.out.rename(old)
        try:
            self.stage.rename(self.out)
        except OSError:
            if old is not None:
                old.rename(self.out)  # the earlier results back, untouched
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return self.out

    def discard(self) -> None:
        """Remove the staged results (the command failed before they were complete)."""
        shutil.rmtree(self.stage, ignore_errors=True)
