"""ISO 286 limits and fits: tolerance zones of holes and shafts, clearance ranges of fits.

Sources of the tables (all values in micrometres, sizes in millimetres):

- standard tolerance grades IT01 to IT18: ISO 286-1:2010 Table 1 (IT1 to IT18) and Table A.1
  (IT01, IT0);
- fundamental deviations of shafts: ISO 286-1:2010 Table 2 (a to h: upper deviation es;
  k to u: lower deviation ei);
- fundamental deviations of holes: ISO 286-1:2010 Table 3 (A to H: EI = -es; K, M, N and P to U:
  upper deviation ES, with the Δ values of its right-hand columns).

IT1 to IT18, Δ and the deviation rows were checked against two independent published
transcriptions of these tables (a DIN ISO 286-1 data set of an engineering calculator: IT1-IT18,
Δ, a-e, K, M, N, P, R, S; a table-verified ISO 286 package: IT5-IT11, c-h, k, m, n, p, s, u); the
tests compare with published limits (ISO 286-2 and the preferred metric fits of ANSI B4.2 as
printed in Machinery's Handbook), not with numbers computed here. IT01 and IT0 (Table A.1) had no
second source.

Conventions:

- Size ranges are "over A up to and including B": a nominal size equal to a range's upper bound
  belongs to that range (10 mm is in 6-10, not 10-18). The first range is 0 < D <= 3 mm; the last
  ends at 500 mm. Sizes are rounded to 1e-9 mm before the look-up, so 0.01 m is 10 mm exactly.
- Tolerance designations are a letter (or ``js``/``JS``) and an IT grade (``01``, ``0``, ``1`` to
  ``18``): ``"H7"``, ``"g6"``, ``"js6"``. Upper case is a hole (internal feature), lower case a
  shaft (external feature).
- Shafts a to h: ei = es - IT. Shafts k to u: es = ei + IT. js/JS: ±IT/2 exactly (some printings
  of the tables round odd IT values of js7 to js11 down to even micrometres; not done here).
- Holes A to H: EI = -es of the shaft letter, ES = EI + IT.
- Holes K, M, N up to grade 8 and P to U up to grade 7: ES = (tabulated value) + Δ, with
  Δ = IT(n) - IT(n-1) from Table 3 (grades 3 to 8 only, so these holes need grade >= 3). Above
  those grades ES is the tabulated value without Δ. EI = ES - IT. Special case of Table 3: M6 over
  250 up to 315 mm has ES = -9 µm (not -11).
- K above grade 8 is defined only up to 3 mm (ES = 0); N above grade 8 has ES = 0 over 3 mm.
- Not used by ISO 286-1 for sizes up to 1 mm (refused here): a, b, A, B; N above grade 8;
  grades IT14 to IT18.
- Functions take and return metres: ``tolerance_zone("H7", 0.02) == (0.0, 21e-6)``.
"""

import math
import numbers
import re
from collections.abc import Mapping
from typing import TypeVar

_Key = TypeVar("_Key")

# Main size ranges of Table 1 (upper bounds, mm): each is "over the previous bound up to and
# including this one", the first over 0.
_MAIN_UPPER_MM = (3, 6, 10, 18, 30, 50, 80, 120, 180, 250, 315, 400, 500)

# Intermediate ranges of Tables 2 and 3 (upper bounds, mm); the deviation rows below have one
# value per intermediate range (the standard prints one value over several where it does not
# split a main range; those values are repeated here).
_SUB_UPPER_MM = (3, 6, 10, 14, 18, 24, 30, 40, 50, 65, 80, 100, 120, 140, 160, 180, 200, 225,
                 250, 280, 315, 355, 400, 450, 500)  # fmt: skip

# ISO 286-1:2010 Table 1 (IT1 to IT18) and Table A.1 (IT01, IT0): standard tolerances in µm, one
# value per main range (_MAIN_UPPER_MM).
_IT_UM: dict[str, tuple[float, ...]] = {
    "01": (0.3, 0.4, 0.4, 0.5, 0.6, 0.6, 0.8, 1, 1.2, 2, 2.5, 3, 4),
    "0": (0.5, 0.6, 0.6, 0.8, 1, 1, 1.2, 1.5, 2, 3, 4, 5, 6),
    "1": (0.8, 1, 1, 1.2, 1.5, 1.5, 2, 2.5, 3.5, 4.5, 6, 7, 8),
    "2": (1.2, 1.5, 1.5, 2, 2.5, 2.5, 3, 4, 5, 7, 8, 9, 10),
    "3": (2, 2.5, 2.5, 3, 4, 4, 5, 6, 8, 10, 12, 13, 15),
    "4": (3, 4, 4, 5, 6, 7, 8, 10, 12, 14, 16, 18, 20),
    "5": (4, 5, 6, 8, 9, 11, 13, 15, 18, 20, 23, 25, 27),
    "6": (6, 8, 9, 11, 13, 16, 19, 22, 25, 29, 32, 36, 40),
    "7": (10, 12, 15, 18, 21, 25, 30, 35, 40, 46, 52, 57, 63),
    "8": (14, 18, 22, 27, 33, 39, 46, 54, 63, 72, 81, 89, 97),
    "9": (25, 30, 36, 43, 52, 62, 74, 87, 100, 115, 130, 140, 155),
    "10": (40, 48, 58, 70, 84, 100, 120, 140, 160, 185, 210, 230, 250),
    "11": (60, 75, 90, 110, 130, 160, 190, 220, 250, 290, 320, 360, 400),
    "12": (100, 120, 150, 180, 210, 250, 300, 350, 400, 460, 520, 570, 630),
    "13": (140, 180, 220, 270, 330, 390, 460, 540, 630, 720, 810, 890, 970),
    "14": (250, 300, 360, 430, 520, 620, 740, 870, 1000, 1150, 1300, 1400, 1550),
    "15": (400, 480, 580, 700, 840, 1000, 1200, 1400, 1600, 1850, 2100, 2300, 2500),
    "16": (600, 750, 900, 1100, 1300, 1600, 1900, 2200, 2500, 2900, 3200, 3600, 4000),
    "17": (1000, 1200, 1500, 1800, 2100, 2500, 3000, 3500, 4000, 4600, 5200, 5700, 6300),
    "18": (1400, 1800, 2200, 2700, 3300, 3900, 4600, 5400, 6300, 7200, 8100, 8900, 9700),
}
_GRADES = tuple(_IT_UM)

# ISO 286-1:2010 Table 3, right-hand columns: Δ in µm for grades 3 to 8, one row per main range.
# (Δ = IT(n) - IT(n-1) of Table 1; the tests check this identity.)
_DELTA_UM: dict[int, tuple[float, ...]] = {
    3: (0, 1, 1, 1, 1.5, 1.5, 2, 2, 3, 3, 4, 4, 5),
    4: (0, 1.5, 1.5, 2, 2, 3, 3, 4, 4, 4, 4, 5, 5),
    5: (0, 1, 2, 3, 3, 4, 5, 5, 6, 6, 7, 7, 7),
    6: (0, 3, 3, 3, 4, 5, 6, 7, 7, 9, 9, 11, 13),
    7: (0, 4, 6, 7, 8, 9, 11, 13, 15, 17, 20, 21, 23),
    8: (0, 6, 7, 9, 12, 14, 16, 19, 23, 26, 29, 32, 34),
}

# ISO 286-1:2010 Table 2: upper deviation es (µm) of shafts a to h, one value per intermediate
# range (_SUB_UPPER_MM: ≤3, 3-6, 6-10, 10-14, 14-18, 18-24, 24-30, 30-40, 40-50, 50-65, 65-80,
# 80-100, 100-120, 120-140, 140-160, 160-180, 180-200, 200-225, 225-250, 250-280, 280-315,
# 315-355, 355-400, 400-450, 450-500).
# fmt: off
_SHAFT_ES_UM: dict[str, tuple[float, ...]] = {
    "a": (-270, -270, -280, -290, -290, -300, -300, -310, -320, -340, -360, -380, -410, -460, -520,
          -580, -660, -740, -820, -920, -1050, -1200, -1350, -1500, -1650),
    "b": (-140, -140, -150, -150, -150, -160, -160, -170, -180, -190, -200, -220, -240, -260, -280,
          -310, -340, -380, -420, -480, -540, -600, -680, -760, -840),
    "c": (-60, -70, -80, -95, -95, -110, -110, -120, -130, -140, -150, -170, -180, -200, -210,
          -230, -240, -260, -280, -300, -330, -360, -400, -440, -480),
    "d": (-20, -30, -40, -50, -50, -65, -65, -80, -80, -100, -100, -120, -120, -145, -145,
          -145, -170, -170, -170, -190, -190, -210, -210, -230, -230),
    "e": (-14, -20, -25, -32, -32, -40, -40, -50, -50, -60, -60, -72, -72, -85, -85,
          -85, -100, -100, -100, -110, -110, -125, -125, -135, -135),
    "f": (-6, -10, -13, -16, -16, -20, -20, -25, -25, -30, -30, -36, -36, -43, -43,
          -43, -50, -50, -50, -56, -56, -62, -62, -68, -68),
    "g": (-2, -4, -5, -6, -6, -7, -7, -9, -9, -10, -10, -12, -12, -14, -14,
          -14, -15, -15, -15, -17, -17, -18, -18, -20, -20),
    "h": (0,) * 25,
}

# ISO 286-1:2010 Table 2: lower deviation ei (µm) of shafts k to u, per intermediate range. The k
# row is for grades 4 to 7; k of grades up to 3 and above 7 has ei = 0.
_SHAFT_EI_UM: dict[str, tuple[float, ...]] = {
    "k": (0, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 3, 3, 3, 3,
          3, 4, 4, 4, 4, 4, 4, 4, 5, 5),
    "m": (2, 4, 6, 7, 7, 8, 8, 9, 9, 11, 11, 13, 13, 15, 15,
          15, 17, 17, 17, 20, 20, 21, 21, 23, 23),
    "n": (4, 8, 10, 12, 12, 15, 15, 17, 17, 20, 20, 23, 23, 27, 27,
          27, 31, 31, 31, 34, 34, 37, 37, 40, 40),
    "p": (6, 12, 15, 18, 18, 22, 22, 26, 26, 32, 32, 37, 37, 43, 43,
          43, 50, 50, 50, 56, 56, 62, 62, 68, 68),
    "r": (10, 15, 19, 23, 23, 28, 28, 34, 34, 41, 43, 51, 54, 63, 65,
          68, 77, 80, 84, 94, 98, 108, 114, 126, 132),
    "s": (14, 19, 23, 28, 28, 35, 35, 43, 43, 53, 59, 71, 79, 92, 100,
          108, 122, 130, 140, 158, 170, 190, 208, 232, 252),
    "u": (18, 23, 28, 33, 33, 41, 48, 60, 70, 87, 102, 124, 144, 170, 190,
          210, 236, 258, 284, 315, 350, 390, 435, 490, 540),
}

# ISO 286-1:2010 Table 3: upper deviation ES (µm) of holes K, M, N before adding Δ (grades up to
# 8), per intermediate range. Above grade 8: K is defined only up to 3 mm (ES = 0), M has the
# same values without Δ, N has ES = -4 up to 3 mm and 0 above.
_HOLE_ES_UM: dict[str, tuple[float, ...]] = {
    "K": (0, -1, -1, -1, -1, -2, -2, -2, -2, -2, -2, -3, -3, -3, -3,
          -3, -4, -4, -4, -4, -4, -4, -4, -5, -5),
    "M": (-2, -4, -6, -7, -7, -8, -8, -9, -9, -11, -11, -13, -13, -15, -15,
          -15, -17, -17, -17, -20, -20, -21, -21, -23, -23),
    "N": (-4, -8, -10, -12, -12, -15, -15, -17, -17, -20, -20, -23, -23, -27, -27,
          -27, -31, -31, -31, -34, -34, -37, -37, -40, -40),
}
# fmt: on


def _as_floats(table: Mapping[_Key, tuple[int | float, ...]]) -> dict[_Key, tuple[float, ...]]:
    """The same table with float entries (the literals above are mostly integers)."""
    return {key: tuple(float(value) for value in row) for key, row in table.items()}


_IT_UM = _as_floats(_IT_UM)
_DELTA_UM = _as_floats(_DELTA_UM)
_SHAFT_ES_UM = _as_floats(_SHAFT_ES_UM)
_SHAFT_EI_UM = _as_floats(_SHAFT_EI_UM)
_HOLE_ES_UM = _as_floats(_HOLE_ES_UM)

_SHAFT_LETTERS = (*_SHAFT_ES_UM, "js", *_SHAFT_EI_UM)
_HOLE_LETTERS = (
    *(letter.upper() for letter in _SHAFT_ES_UM),
    "JS",
    *_HOLE_ES_UM,
    *(letter.upper() for letter in _SHAFT_EI_UM if letter not in "kmn"),
)
_DESIGNATION = re.compile(r"^([A-Za-z]{1,2})(\d{1,2})$")
_SIZE_DIGITS = 9  # sizes in mm are rounded to 1e-9 mm before the range look-up
_MAX_DIAMETER = 0.5  # m: Tables 1 to 3 as used here end at 500 mm


def _size_mm(diameter: float) -> float:
    """Nominal size in mm from a diameter in metres, after checking it lies in (0, 0.5] m."""
    if isinstance(diameter, bool) or not isinstance(diameter, numbers.Real):
        raise ValueError(
            f"diameter must be a number in metres (e.g. 0.02 for 20 mm); got {diameter!r}"
        )
    diameter = float(diameter)
    if not (math.isfinite(diameter) and 0.0 < diameter <= _MAX_DIAMETER):
        hint = (
            f" (it looks like millimetres: give {diameter / 1000:g} for {diameter:g} mm)"
            if 1.0 < diameter <= 1000 * _MAX_DIAMETER
            else ""
        )
        raise ValueError(
            f"diameter must be in metres with 0 < diameter <= 0.5 (ISO 286 tables up to "
            f"500 mm; e.g. 0.02 for 20 mm); got {diameter!r}{hint}"
        )
    return round(diameter * 1e3, _SIZE_DIGITS)


def _range_index(size_mm: float, upper_bounds: tuple[int, ...]) -> int:
    """Index of the range "over previous bound up to and including upper bound" holding size."""
    for index, upper in enumerate(upper_bounds):
        if size_mm <= upper:
            return index
    raise AssertionError(f"size {size_mm} mm above the tables (checked by _size_mm)")


def _parse_designation(designation: str) -> tuple[str, str]:
    """Split ``"H7"`` into letter ``"H"`` and grade ``"7"``, checking both are supported."""
    if not isinstance(designation, str):
        raise ValueError(
            f"tolerance designation must be a string such as 'H7' or 'g6'; got {designation!r}"
        )
    match = _DESIGNATION.match(designation.strip())
    if match is None:
        raise ValueError(
            f"cannot read tolerance designation {designation!r}: expected a deviation letter and "
            f"an IT grade, e.g. 'H7' (hole) or 'g6' (shaft)"
        )
    letter, grade = match.groups()
    if letter not in _SHAFT_LETTERS and letter not in _HOLE_LETTERS:
        raise ValueError(
            f"unknown fundamental deviation letter {letter!r} in {designation!r}; supported: "
            f"holes {', '.join(_HOLE_LETTERS)} (upper case), shafts {', '.join(_SHAFT_LETTERS)} "
            f"(lower case)"
        )
    if grade not in _IT_UM:
        raise ValueError(
            f"unknown tolerance grade {grade!r} in {designation!r}; supported: IT grades "
            f"{', '.join(_GRADES)}"
        )
    return letter, grade


def _it_um(grade: str, size_mm: float) -> float:
    if int(grade) >= 14 and size_mm <= 1.0:  # int("01") == 1
        raise ValueError(
            f"ISO 286-1 does not use grades IT14 to IT18 for nominal sizes up to 1 mm; got IT{grade}"
            f" at {size_mm:g} mm"
        )
    return _IT_UM[grade][_range_index(size_mm, _MAIN_UPPER_MM)]


def _delta_um(letter: str, grade: str, size_mm: float) -> float:
    """Δ of ISO 286-1 Table 3 for the holes that take it (K, M, N to grade 8; P..U to grade 7)."""
    if grade in ("01", "0") or int(grade) < 3:
        raise ValueError(
            f"ISO 286-1 gives Δ, and so hole {letter}, only from grade 3; got {letter}{grade}"
        )
    return _DELTA_UM[int(grade)][_range_index(size_mm, _MAIN_UPPER_MM)]


def _zone_um(letter: str, grade: str, size_mm: float) -> tuple[float, float]:
    """(lower, upper) deviation in µm of tolerance class letter+grade at size_mm."""
    it = _it_um(grade, size_mm)
    sub = _range_index(size_mm, _SUB_UPPER_MM)
    number = -1 if grade in ("01", "0") else int(grade)
    if letter in ("a", "b", "A", "B") and size_mm <= 1.0:
        raise ValueError(
            f"ISO 286-1 does not use deviation {letter} for nominal sizes up to 1 mm; got "
            f"{size_mm:g} mm"
        )
    if letter in ("js", "JS"):
        return -it / 2, it / 2
    if letter in _SHAFT_ES_UM:
        es = _SHAFT_ES_UM[letter][sub]
        return es - it, es
    if letter in _SHAFT_EI_UM:
        ei = _SHAFT_EI_UM[letter][sub]
        if letter == "k" and not 4 <= number <= 7:
            ei = 0.0
        return ei, ei + it
    if letter.lower() in _SHAFT_ES_UM:  # holes A to H
        ei_hole = -_SHAFT_ES_UM[letter.lower()][sub]
        return ei_hole, ei_hole + it
    if letter in _HOLE_ES_UM:  # K, M, N
        if number <= 8:
            es = _HOLE_ES_UM[letter][sub] + _delta_um(letter, grade, size_mm)
            if letter == "M" and grade == "6" and 250 < size_mm <= 315:
                es = -9.0  # ISO 286-1:2010 Table 3, special case (instead of -11)
        elif letter == "K":
            if size_mm > 3:
                raise ValueError(
                    f"ISO 286-1 defines hole K above grade 8 only up to 3 mm; got K{grade} at "
                    f"{size_mm:g} mm (use K8 or finer, or another letter)"
                )
            es = 0.0
        elif letter == "N":
            if size_mm <= 1.0:
                raise ValueError(
                    f"ISO 286-1 does not use hole N above grade 8 for sizes up to 1 mm; got "
                    f"N{grade} at {size_mm:g} mm"
                )
            es = -4.0 if size_mm <= 3 else 0.0
        else:
            es = _HOLE_ES_UM[letter][sub]
        return es - it, es
    # holes P to U: ES = -ei of the shaft letter, + Δ up to grade 7
    es = -_SHAFT_EI_UM[letter.lower()][sub]
    if number <= 7:
        es += _delta_um(letter, grade, size_mm)
    return es - it, es


def standard_tolerance(grade: str | int, diameter: float) -> float:
    """Standard tolerance ITn of ISO 286-1 Table 1 for a nominal diameter.

    Args:
        grade: ``"IT7"``, ``"7"`` or ``7``; ``"01"`` and ``"0"`` (or ``"IT01"``) for the finest.
        diameter: nominal diameter in metres, 0 < diameter <= 0.5 (0.02 for 20 mm).

    Returns:
        The tolerance (width of the zone) in metres, e.g. 21e-6 for IT7 at 20 mm.

    Raises:
        ValueError: unknown grade or diameter outside (0, 0.5] m.
    """
    text = str(grade).strip()
    text = text[2:] if text.upper().startswith("IT") else text
    if isinstance(grade, bool) or text not in _IT_UM:
        raise ValueError(
            f"unknown tolerance grade {grade!r}; supported: IT grades {', '.join(_GRADES)} "
            f"(as 'IT7', '7' or 7)"
        )
    return _it_um(text, _size_mm(diameter)) / 1e6


def tolerance_zone(designation: str, diameter: float) -> tuple[float, float]:
    """Limit deviations of an ISO 286 tolerance class at a nominal diameter.

    Args:
        designation: deviation letter and grade, ``"H7"`` (hole: upper case) or ``"g6"`` (shaft:
            lower case). Holes A-H, JS, K, M, N, P, R, S, U; shafts a-h, js, k, m, n, p, r, s, u;
            grades 01, 0, 1 to 18 (K, M, N, P-U holes from grade 3).
        diameter: nominal diameter in metres, 0 < diameter <= 0.5 (0.02 for 20 mm). A size on a
            range boundary belongs to the range it ends (ranges are "over A up to and including
            B").

    Returns:
        (lower, upper) deviation from the nominal size in metres: for a hole (EI, ES), for a shaft
        (ei, es). ``tolerance_zone("H7", 0.02) == (0.0, 21e-6)``,
        ``tolerance_zone("g6", 0.02) == (-20e-6, -7e-6)``.

    Raises:
        ValueError: unreadable designation, unknown letter or grade (the message lists what is
            supported), a class ISO 286-1 does not define at that size, or a diameter outside
            (0, 0.5] m.
    """
    letter, grade = _parse_designation(designation)
    lower, upper = _zone_um(letter, grade, _size_mm(diameter))
    return lower / 1e6, upper / 1e6


def _split_fit(fit: str) -> tuple[str, str]:
    """``"H7/g6"`` -> (``"H7"``, ``"g6"``), checking hole first (upper case), shaft second."""
    if not isinstance(fit, str) or fit.count("/") != 1:
        raise ValueError(
            f'cannot read fit {fit!r}: expected hole/shaft such as "H7/g6" (hole class in upper'
            f" case first, shaft class in lower case second)"
        )
    hole, shaft = (part.strip() for part in fit.split("/"))
    if not hole[:1].isupper() or not shaft[:1].islower():
        raise ValueError(
            f'cannot read fit {fit!r}: expected hole/shaft such as "H7/g6" (hole class in upper'
            f" case first, shaft class in lower case second)"
        )
    return hole, shaft


def fit_zones(fit: str, diameter: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """Tolerance zones of the hole and of the shaft of a fit.

    Args:
        fit: ``"hole/shaft"``, e.g. ``"H7/g6"`` (hole basis) or ``"G7/h6"`` (shaft basis).
        diameter: nominal diameter in metres, 0 < diameter <= 0.5.

    Returns:
        ((EI, ES), (ei, es)): lower and upper deviations of the hole, then of the shaft, in metres
        (see `tolerance_zone`).

    Raises:
        ValueError: malformed fit string, or as `tolerance_zone`.
    """
    hole, shaft = _split_fit(fit)
    return tolerance_zone(hole, diameter), tolerance_zone(shaft, diameter)


def fit_clearance(fit: str, diameter: float) -> tuple[float, float]:
    """Radial clearance range of an ISO 286 fit.

    The radial clearance is half the diametral one: c = (D_hole - d_shaft) / 2, so its limits are
    c_min = (EI - es) / 2 and c_max = (ES - ei) / 2.

    Args:
        fit: ``"hole/shaft"``, e.g. ``"H7/g6"``.
        diameter: nominal diameter in metres, 0 < diameter <= 0.5 (0.02 for 20 mm).

    Returns:
        (min, max) radial clearance in metres; negative values are interference (transition and
        interference fits). ``fit_clearance("H7/g6", 0.02) == (3.5e-6, 20.5e-6)``.

    Raises:
        ValueError: malformed fit string, or as `tolerance_zone`.
    """
    hole, shaft = _split_fit(fit)
    size_mm = _size_mm(diameter)
    hole_lower, hole_upper = _zone_um(*_parse_designation(hole), size_mm)
    shaft_lower, shaft_upper = _zone_um(*_parse_designation(shaft), size_mm)
    return (hole_lower - shaft_upper) / 2e6, (hole_upper - shaft_lower) / 2e6
