"""Reading and validating the TOML config file, and layering defaults < file < options.

Everything here runs before any solve; every problem is a ``UsageError`` (exit 2) naming the file,
the table and the key, and saying how to fix it.
"""

import argparse
import dataclasses
import tomllib
from pathlib import Path
from typing import Any

from ..studies._revolutions import MAX_REVOLUTIONS
from ._common import UsageError
from ._setting_table import MAX_SAVED_INSTANTS, SETTINGS
from ._settings import (
    AUTO,
    BY_LABEL,
    PER_JOINT,
    SECTIONS,
    check_value,
    type_name,
    type_ok,
)
from ._tables import lubrication_from_table

DESCRIPTION_TABLES = ("ground", "bodies", "joints", "driver", "springs", "loads")
"""Top-level tables that describe a custom mechanism (schema in ``_mechanism_config.py``)."""
ENSEMBLE_TABLES = ("montecarlo",)
"""Top-level tables read by one subcommand only and ignored by the others: ``[montecarlo]`` holds
the distributions of ``jaxclear montecarlo`` (checked there, against the mechanism)."""


@dataclasses.dataclass(frozen=True)
class ConfigFile:
    """What a config file holds, checked for types and known keys.

    Attributes:
        path: the file as given.
        values: settings by (section, key).
        joint_tables: per-joint clearance tables, ``{joint name: {key: value}}``
            (``[clearance.<joint>]``).
        description: the custom-mechanism tables (``DESCRIPTION_TABLES``) as parsed.
        montecarlo: the ``[montecarlo]`` table as parsed (distributions by parameter name, or
            per-joint subtables ``[montecarlo.<joint>]``); empty if absent.
    """

    path: str
    values: dict[tuple[str, str], Any]
    joint_tables: dict[str, dict[str, Any]]
    description: dict[str, Any]
    montecarlo: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Settings:
    """The resolved settings of a run.

    Attributes:
        config: ``{section: {key: value}}`` after defaults < file < options (as written to run.json).
        sources: where each value came from: ``"default"``, ``"[section] key in 'file'"`` or a flag.
        joint_tables: per-joint clearance overrides, ``{joint: {key: value}}``.
        description: custom-mechanism tables (empty for the benchmarks).
        config_file: path of the config file, or ``None``.
        montecarlo: the file's ``[montecarlo]`` table (``jaxclear montecarlo``; others ignore it).
    """

    config: dict[str, dict[str, Any]]
    sources: dict[tuple[str, str], str]
    joint_tables: dict[str, dict[str, Any]]
    description: dict[str, Any]
    config_file: str | None
    montecarlo: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def mechanism(self) -> str:
        return self.config["mechanism"]["name"]

    def source(self, section: str, key: str) -> str:
        return self.sources[(section, key)]


def _decode(path: str) -> str:
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise UsageError(f"config file {path!r} not found; give the path of a TOML file") from None
    except IsADirectoryError:
        raise UsageError(
            f"config file {path!r} is a directory; give the path of a TOML file"
        ) from None
    except OSError as e:
        raise UsageError(f"cannot read config file {path!r}: {e.strerror or e}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise UsageError(
            f"config file {path!r} is not UTF-8 text (byte 0x{data[e.start]:02x} on line {line}); "
            "save it with UTF-8 encoding (TOML files must be UTF-8)"
        ) from None


def read_config(path: str) -> ConfigFile:
    """Parse and check a TOML config file; raises ``UsageError`` on any problem."""
    try:
        data = tomllib.loads(_decode(path))
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"config file {path!r} is not valid TOML: {e}") from None
    values: dict[tuple[str, str], Any] = {}
    joint_tables: dict[str, dict[str, Any]] = {}
    description = {}
    montecarlo: dict[str, Any] = {}
    known_sections = ", ".join(f"[{s}]" for s in (*SECTIONS, *DESCRIPTION_TABLES, *ENSEMBLE_TABLES))
    for section, table in data.items():
        if section in ENSEMBLE_TABLES:
            if not isinstance(table, dict):
                raise UsageError(
                    f"{section!r} in {path!r} must be a table [{section}] of distributions; "
                    "see docs/ensembles.md"
                )
            montecarlo = table
            continue
        if section in DESCRIPTION_TABLES:
            if not isinstance(table, dict):
                raise UsageError(
                    f"{section!r} in {path!r} must be a table [{section}...]; see docs/cli.md"
                )
            description[section] = table
            continue
        if not isinstance(table, dict):
            where = next((f"[{x.section}]" for x in SETTINGS if x.key == section), None)
            hint = (
                f"put it under {where}"
                if where
                else f"keys belong in the sections {known_sections}"
            )
            raise UsageError(f"top-level key {section!r} in {path!r} is not in a section; {hint}")
        if section not in SECTIONS:
            raise UsageError(
                f"unknown section [{section}] in {path!r}; known sections: {known_sections}"
            )
        for key, value in table.items():
            s = BY_LABEL.get((section, key))
            if (
                section == "clearance"
                and isinstance(value, dict)
                and (s is None or not (s.shared or s.kind is dict))
            ):
                joint_tables[key] = _joint_table(path, key, value)
                continue
            if s is None or not s.shared:
                known = ", ".join(x.key for x in SETTINGS if x.section == section and x.shared)
                extra = (
                    "; per-joint tables [clearance.<joint>] hold per-joint keys"
                    if section == "clearance"
                    else ""
                )
                hint = (
                    " (it belongs in a per-joint table [clearance.<joint>])"
                    if s is not None
                    else ""
                )
                raise UsageError(
                    f"unknown key {key!r} in [{section}] of {path!r}{hint}; known keys: {known}{extra}"
                )
            if not type_ok(s, value):
                raise UsageError(f"{s.label} in {path!r} must be {type_name(s)}, got {value!r}")
            values[(section, key)] = value
    return ConfigFile(path, values, joint_tables, description, montecarlo)


def _joint_table(path: str, joint: str, table: dict) -> dict:
    known = {s.key: s for s in PER_JOINT}
    for key, value in table.items():
        s = known.get(key)
        if s is None:
            raise UsageError(
                f"unknown key {key!r} in [clearance.{joint}] of {path!r}; per-joint keys: {', '.join(known)}"
            )
        if not type_ok(s, value):
            raise UsageError(
                f"[clearance.{joint}] {key} in {path!r} must be {type_name(s)}, got {value!r}"
            )
        check_value(s, value, f"[clearance.{joint}] {key} in {path!r}")
        if key == "lubrication":
            # its own keys and ranges, checked here so that a table of a joint the run leaves
            # ideal (--clearance-joints) is checked too
            lubrication_from_table(f"[clearance.{joint}] lubrication", value)
    return dict(table)


def _mechanism_name(args: argparse.Namespace, file: ConfigFile | None) -> tuple[str, str]:
    """(name, source): the flag, else the file's key, else custom if the file describes bodies."""
    flag = getattr(args, "mechanism__name", None)
    if flag is not None:
        name, source = flag, "--mechanism"
    elif file is not None and ("mechanism", "name") in file.values:
        name, source = file.values[("mechanism", "name")], f"[mechanism] name in {file.path!r}"
    elif file is not None and "bodies" in file.description:
        return "custom", "default"
    else:
        return "slider_crank", "default"
    check_value(BY_LABEL[("mechanism", "name")], name, source)
    return name, source


def resolve_settings(args: argparse.Namespace) -> Settings:
    """Defaults < config file < options, checked.

    Args:
        args: parsed command line; ``args.config`` is the config file path or ``None``; the setting
            flags are in ``args.<section>__<key>``.

    Returns:
        The ``Settings`` of the run.

    Raises:
        UsageError: any bad value, key, type or file.
    """
    file = read_config(args.config) if args.config else None
    name, name_source = _mechanism_name(args, file)
    config: dict[str, dict[str, Any]] = {section: {} for section in SECTIONS}
    sources: dict[tuple[str, str], str] = {}
    for s in SETTINGS:
        if not s.shared:
            continue
        if (s.section, s.key) == ("mechanism", "name"):
            config["mechanism"]["name"], sources[("mechanism", "name")] = name, name_source
            continue
        value, source = s.default_for(name, getattr(args, "command", None)), "default"
        if file is not None and (s.section, s.key) in file.values:
            value, source = file.values[(s.section, s.key)], f"{s.label} in {file.path!r}"
        flag = getattr(args, s.dest, None) if s.flag else None
        if flag is not None:
            value, source = flag, s.flag
        if source != "default" and s.mechanisms is not None and name not in s.mechanisms:
            raise UsageError(
                f"{source} applies to {' and '.join(s.mechanisms)} only, and this run's mechanism is "
                f"{name}; remove it or set [mechanism] name"
            )
        if s.mechanisms is not None and name not in s.mechanisms:
            continue  # not a setting of this mechanism: left out of run.json
        config[s.section][s.key] = value
        sources[(s.section, s.key)] = str(source)
    for s in SETTINGS:
        if (s.section, s.key) in sources:
            check_value(s, config[s.section][s.key], sources[(s.section, s.key)])
    if name == "custom" and config["mechanism"]["rpm"] is None:
        raise UsageError(
            "[mechanism] rpm is required for a custom mechanism (speed of the [driver] body, rev/min)"
        )
    description = file.description if file is not None else {}
    if file is not None and description and name != "custom":
        tables = ", ".join(f"[{t}]" for t in description)
        raise UsageError(
            f"{tables} in {file.path!r} describe a custom mechanism, but {sources[('mechanism', 'name')]} "
            f'gives {name}; set [mechanism] name = "custom" or remove those tables'
        )
    if name == "custom" and "bodies" not in description:
        raise UsageError(
            "a custom mechanism needs [bodies.<name>] tables (and [joints], [driver]); see docs/cli.md"
        )
    simulation = config["simulation"]
    horizon = MAX_REVOLUTIONS if simulation["revolutions"] == AUTO else simulation["revolutions"]
    if simulation["skip_revolutions"] >= horizon:
        raise UsageError(
            f"{sources[('simulation', 'skip_revolutions')]}: skip_revolutions ({simulation['skip_revolutions']:g}) must be "
            f"smaller than revolutions ({horizon:g}) so that something is left to plot; "
            "lower --skip-revolutions or raise --revolutions"
        )
    instants = horizon * simulation["points_per_revolution"]
    if instants > MAX_SAVED_INSTANTS:
        raise UsageError(
            f"{sources[('simulation', 'points_per_revolution')]} = {simulation['points_per_revolution']} "
            f"over {horizon:g} revolutions{' (auto: at most that)' if simulation['revolutions'] == AUTO else ''} "
            f"saves {instants:.3g} instants, more than "
            f"{MAX_SAVED_INSTANTS} (each holds about 0.6 kB in memory and a row of results.csv; "
            "peaks and statistics come from the solver's steps, not from these instants); "
            "lower --points-per-revolution or --revolutions"
        )
    return Settings(
        config=config,
        sources=sources,
        joint_tables=file.joint_tables if file is not None else {},
        description=description,
        config_file=args.config,
        montecarlo=file.montecarlo if file is not None else {},
    )
