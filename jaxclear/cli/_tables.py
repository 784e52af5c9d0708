"""Checked TOML tables of the command line: the key schema (``Field``), one-line errors naming the
key, and the per-joint ``lubrication = {...}`` table. Below both ``_config`` (which checks the
lubrication table when it reads a file) and ``_mechanism_config`` (which builds from it)."""

import dataclasses
import math
from typing import Any

import jaxclear

from ..contact import LUBRICATION_THEORIES, Lubrication
from ._common import UsageError, one_line


@dataclasses.dataclass(frozen=True)
class Field:
    """One key of a description table.

    Attributes:
        key: TOML key. kind: ``"number"``, ``"vector2"``, ``"vector3"``, ``"string"``, ``"points"``
            (table of name -> 2-vector), ``"pair"`` (two point references).
        unit: SI unit. help: description. required: must be given. default: shown in the reference.
    """

    key: str
    kind: str
    unit: str
    help: str
    required: bool = True
    default: Any = None


def fail(where: str, message: str):
    raise UsageError(f"{where}: {message}")


def number(where: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        fail(where, f"must be a finite number, got {value!r}")
    return float(value)


def check_keys(where: str, table, allowed, required) -> None:
    if not isinstance(table, dict):
        fail(where, f"must be a table, got {table!r}")
    for key in table:
        if key not in allowed:
            fail(where, f"unknown key {key!r}; known keys: {', '.join(allowed)}")
    for key in required:
        if key not in table:
            fail(where, f"missing key {key!r}")


LUBRICATION_KEYS: tuple[Field, ...] = (
    Field("viscosity", "number", "Pa s", "dynamic viscosity of the lubricant (> 0)"),
    Field("length", "number", "m", "bearing length L (> 0)"),
    Field("theory", "string", "", "short (Ocvirk) or long (Sommerfeld) bearing", False, "short"),
    Field(
        "transition_eccentricity",
        "number",
        "",
        "eccentricity ratio ε₀ in (0, 1) where the film starts to hand over to dry contact",
        False,
        "0.9",
    ),
    Field(
        "transition_width",
        "number",
        "",
        "width Δ of the film-to-dry blend (ε₀ + Δ <= 1)",
        False,
        "0.1",
    ),
    Field("petroff", "bool", "", "add the Petroff shear torque", False, "false"),
)
"""Keys of a per-joint ``lubrication = {...}`` table (``[clearance.<joint>]``; docs/model.md §3b)."""


def lubrication_from_table(where: str, table) -> Lubrication:
    """The ``Lubrication`` of a ``lubrication = { viscosity = ..., length = ..., ... }`` table.

    Raises:
        UsageError: not a table, an unknown or missing key, a value of the wrong type or out of
            range (one line, naming ``where`` and the key).
    """
    allowed = tuple(f.key for f in LUBRICATION_KEYS)
    required = tuple(f.key for f in LUBRICATION_KEYS if f.required)
    check_keys(where, table, allowed, required)
    values: dict[str, Any] = {}
    for key, value in table.items():
        if key == "theory":
            if value not in LUBRICATION_THEORIES:
                fail(
                    f"{where} theory",
                    f"must be one of {', '.join(map(repr, LUBRICATION_THEORIES))}, got {value!r}",
                )
            values[key] = value
        elif key == "petroff":
            if not isinstance(value, bool):
                fail(f"{where} petroff", f"must be true or false, got {value!r}")
            values[key] = value
        else:
            values[key] = number(f"{where} {key}", value)
    for key in ("viscosity", "length", "transition_width"):
        if key in values and not values[key] > 0:
            fail(f"{where} {key}", f"must be positive, got {values[key]}")
    e0 = values.get("transition_eccentricity")
    if e0 is not None and not 0 < e0 < 1:
        fail(
            f"{where} transition_eccentricity",
            f"must be in (0, 1), got {e0}; the film acts below it and the wall is at 1",
        )
    try:
        return Lubrication(**values)
    except (jaxclear.ModelError, ValueError, TypeError) as e:
        raise UsageError(f"{where}: {one_line(e)}") from None
