"""What the commands derive from the settings table (``_setting_table.SETTINGS``): lookups, the
checks of TOML values, the command-line options and the references printed by ``--help`` and
written into docs/cli.md."""

import argparse
import math
from collections.abc import Mapping

from ..solve import PRESETS
from ._common import UsageError
from ._setting_table import (
    MAX_HORIZON_REVOLUTIONS,
    MAX_RPM,
    MAX_STEPS,
    MIN_RPM,
    SETTINGS,
    Setting,
)

SECTIONS = tuple(dict.fromkeys(s.section for s in SETTINGS))
BY_LABEL = {(s.section, s.key): s for s in SETTINGS}
PER_JOINT = tuple(s for s in SETTINGS if s.per_joint)


def format_default(s: Setting, command: str | None = None) -> str:
    """The default of ``s`` as shown in ``--help`` of ``command`` and, without one, docs/cli.md
    (where a command's own default follows in parentheses)."""
    own = dict(s.command_defaults)
    if command is not None and command in own:
        return _format_value(own[command])
    if s.default is None and s.section == "solver":
        by_value: dict[str, list[str]] = {}
        for name, preset in PRESETS.items():
            by_value.setdefault(f"{getattr(preset, s.key):g}", []).append(name)
        return "preset's: " + ", ".join(
            f"{'/'.join(names)} {value}" for value, names in by_value.items()
        )
    if s.default is None and s.kind is dict:
        return "none"
    if s.default is None:
        return "see description"
    if isinstance(s.default, Mapping):
        text = ", ".join(f"{name} {_format_value(value)}" for name, value in s.default.items())
    else:
        text = _format_value(s.default)
    if s.command_defaults and command is None:  # e.g. "2 (run: auto)"
        text += " (" + ", ".join(f"{c}: {_format_value(v)}" for c, v in s.command_defaults) + ")"
    return text


def _format_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.10g}"
    return str(value)


def config_reference() -> str:
    """Text listing every key of the settings sections (``--help``; docs/cli.md holds the same)."""
    lines = []
    for section in SECTIONS:
        lines.append(f"  [{section}]")
        for s in SETTINGS:
            if s.section != section:
                continue
            unit = f" [{s.unit}]" if s.unit else ""
            flag = f" ({s.flag})" if s.flag else ""
            where = f" ({', '.join(s.mechanisms)} only)" if s.mechanisms else ""
            scope = (
                " (per-joint table only)"
                if not s.shared
                else (" (also per joint)" if s.per_joint else "")
            )
            lines.append(f"    {s.key}{unit} = {format_default(s)}{flag}{where}{scope}: {s.help}")
    return "\n".join(lines)


AUTO = "auto"
"""``revolutions = "auto"``: ``jaxclear run`` solves until the response settles (``simulate_revolutions``)."""


# --- checks -----------------------------------------------------------------------------------------


def type_ok(s: Setting, value) -> bool:
    """Whether a TOML value has the type ``s`` needs (bools are not numbers)."""
    if s.kind is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if s.kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if s.kind == "gravity":
        return isinstance(value, int | float)
    if s.kind == "revolutions":
        return value == AUTO or (isinstance(value, int | float) and not isinstance(value, bool))
    return isinstance(value, s.kind)


def type_name(s: Setting) -> str:
    return {
        float: "a number",
        int: "an integer",
        str: "a string",
        bool: "true or false",
        "gravity": "true, false or a number",
        "revolutions": 'a number or "auto"',
        dict: "an inline table { key = value, ... }",
    }[s.kind]


def check_value(s: Setting, value, source: str) -> None:
    """Raise ``UsageError`` naming ``source`` if ``value`` fails the setting's check or choices."""
    if value is None:
        return
    if s.choices is not None and value not in s.choices:
        raise UsageError(f"{source} must be one of {', '.join(s.choices)}, got {value!r}")
    if s.kind is str:
        if not value.strip():
            raise UsageError(f"{source} is empty; {_empty_hint(s)}")
        return
    if s.check is None or isinstance(value, bool) or value == AUTO:
        return
    if not math.isfinite(value):
        raise UsageError(f"{source} must be finite, got {value!r}")
    if s.check in ("positive", "rpm", "revolutions", "steps") and not value > 0:
        raise UsageError(f"{source} must be positive, got {value!r}")
    if s.check == "revolutions" and value > MAX_HORIZON_REVOLUTIONS:
        raise UsageError(
            f"{source} = {value:g} is more revolutions than one run holds (at most {MAX_HORIZON_REVOLUTIONS}: "
            "every revolution is a solve of about 0.1 s, and the run keeps every revolution's "
            'results in memory); give at most that, or "auto" for jaxclear run'
        )
    if s.check == "steps" and value > MAX_STEPS:
        raise UsageError(
            f"{source} = {value} is more steps than a solve can take (at most {MAX_STEPS}: about "
            "15 hours at the default run's pace); loosen rtol/atol or shorten the horizon instead"
        )
    if s.check == "rpm" and value > MAX_RPM:
        raise UsageError(
            f"{source} = {value:g} rev/min is implausible (at most {MAX_RPM:g}; linkages run at 200-6000 rpm); "
            "give the speed in revolutions per minute"
        )
    if s.check == "rpm" and value < MIN_RPM:
        raise UsageError(
            f"{source} = {value:g} rev/min is too slow to simulate (at least {MIN_RPM:g}: each "
            "revolution's steps follow the contacts' millisecond time scales); give the speed in "
            "revolutions per minute"
        )
    if s.check == "nonnegative" and not value >= 0:
        raise UsageError(f"{source} must be zero or positive, got {value!r}")
    if s.check == "fraction" and not 0 < value < 1:
        raise UsageError(
            f"{source} must be in (0, 1), got {value!r}; it is a fraction of a crank period"
        )


def _empty_hint(s: Setting) -> str:
    if s.key == "joints":
        return "use 'none' for ideal joints, or list joints like 'O,A,B'"
    if s.key == "directory":
        return "give the path of an output folder"
    if s.choices:
        return f"choose one of {', '.join(s.choices)}"
    return "give a value"


# --- command-line options ---------------------------------------------------------------------------


def _number(kind):
    def convert(text: str):
        if kind == "revolutions" and text == AUTO:
            return AUTO
        try:
            return float(text) if kind == "revolutions" else kind(text)
        except ValueError:
            what = {int: "an integer", "revolutions": 'a number or "auto"'}.get(kind, "a number")
            raise argparse.ArgumentTypeError(f"needs {what}, got {text!r}") from None

    return convert


METAVARS = {
    "directory": "DIR",
    "joints": "LIST",
    "contact": "LAW",
    "friction": "LAW",
    "name": "NAME",
    "start": "HOW",
    "method": "NAME",
}


def add_setting_arguments(
    parser: argparse.ArgumentParser, command: str, sections: tuple[str, ...] = SECTIONS
) -> None:
    """Add a flag for every ``Setting`` of ``sections`` that has one (the shared run options),
    with ``command``'s defaults in the help.

    Values land in ``args.<section>__<key>`` (``None`` when not given), read by
    ``_config.resolve_settings``.
    """
    for s in SETTINGS:
        if s.flag is None or s.section not in sections:
            continue
        unit = f" [{s.unit}]" if s.unit else ""
        default = (
            ""
            if s.default is None and s.section != "solver"
            else f" (default: {format_default(s, command)})"
        )
        if s.kind is bool or s.kind == "gravity":
            text = s.flag_help or s.help
            parser.add_argument(
                s.flag,
                dest=s.dest,
                action=argparse.BooleanOptionalAction,
                default=None,
                help=f"{text}{default}",
            )
        elif s.kind is str:
            parser.add_argument(
                s.flag,
                dest=s.dest,
                default=None,
                metavar=METAVARS.get(s.key, "NAME"),
                help=f"{s.help}{default}",
            )
        else:
            metavar = "N" if s.kind is int else "X"
            parser.add_argument(
                s.flag,
                dest=s.dest,
                type=_number(s.kind),
                default=None,
                metavar=metavar,
                help=f"{s.help}{unit}{default}",
            )


def all_flags() -> list[str]:
    """Every settings flag (with the ``--no-`` forms of switches), for 'did you mean' hints."""
    flags = []
    for s in SETTINGS:
        if s.flag:
            flags.append(s.flag)
            if s.kind is bool or s.kind == "gravity":
                flags.append("--no-" + s.flag[2:])
    return flags


def markdown_reference() -> str:
    """The settings reference as Markdown tables, one per section (docs/cli.md embeds it verbatim;
    ``tests/test_cli.py`` checks that it is current)."""
    out = []
    for section in SECTIONS:
        out += [
            f"### `[{section}]`",
            "",
            "| key | unit | default | flag | description |",
            "| --- | --- | --- | --- | --- |",
        ]
        for s in SETTINGS:
            if s.section != section:
                continue
            notes = []
            if s.mechanisms:
                notes.append(f"{' and '.join(s.mechanisms)} only")
            if not s.shared:
                notes.append(f"per-joint table `[{section}.<joint>]` only")
            elif s.per_joint:
                notes.append(f"also in `[{section}.<joint>]`")
            note = f" ({'; '.join(notes)})" if notes else ""
            flag = f"`{s.flag}`" if s.flag else ""
            text = s.help.replace("|", "\\|")
            out.append(f"| `{s.key}` | {s.unit} | {format_default(s)} | {flag} | {text}{note} |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"
