"""ISO 286 tolerance zones and fits against published tables.

Expected values are copied from published tables, not computed:

- [MH-hole] Machinery's Handbook, "American National Standard Preferred Hole Basis Metric
  Clearance Fits" and "... Transition and Interference Fits" (ANSI B4.2-1978, which
  reproduces the ISO 286-2 limits): hole and shaft limits in mm, and the fit (max, min)
  diametral clearance in mm, negative for interference.
- [MH-shaft] Machinery's Handbook, "American National Standard Preferred Shaft Basis Metric ...
  Fits" (ANSI B4.2-1978): limits of K7, N7, P7, S7, U7 holes with h6 shafts (the Δ rule).
- [ISO 286-2] ISO 286-2:2010 tables of limit deviations (µm) for single classes: M (Table 14),
  K (Table 13), N (Table 15), js/JS (Tables 9 and 19).
- [ISO 286-1] ISO 286-1:2010 Table 1 (standard tolerance grades, µm).
"""

import pytest

from jaxclear.studies._iso286 import (
    _DELTA_UM,
    _IT_UM,
    fit_clearance,
    fit_zones,
    standard_tolerance,
    tolerance_zone,
)

LIMIT_ATOL = 1e-10
"""m. Published limits are given to 1 µm (0.5 µm for js/JS); 0.1 nm absorbs the round-off of
converting printed mm limits to metre deviations while any wrong table entry (>= 0.5 µm) fails."""

# [MH-hole] (nominal mm, fit, hole (max, min) mm, shaft (max, min) mm, fit (max, min) mm)
HOLE_BASIS_FITS = [
    (20, "H11/c11", (20.130, 20.000), (19.890, 19.760), (0.370, 0.110)),
    (20, "H9/d9", (20.052, 20.000), (19.935, 19.883), (0.169, 0.065)),
    (20, "H8/f7", (20.033, 20.000), (19.980, 19.959), (0.074, 0.020)),
    (20, "H7/g6", (20.021, 20.000), (19.993, 19.980), (0.041, 0.007)),
    (20, "H7/h6", (20.021, 20.000), (20.000, 19.987), (0.034, 0.000)),
    (20, "H7/k6", (20.021, 20.000), (20.015, 20.002), (0.019, -0.015)),
    (20, "H7/n6", (20.021, 20.000), (20.028, 20.015), (0.006, -0.028)),
    (20, "H7/p6", (20.021, 20.000), (20.035, 20.022), (-0.001, -0.035)),
    (20, "H7/s6", (20.021, 20.000), (20.048, 20.035), (-0.014, -0.048)),
    (20, "H7/u6", (20.021, 20.000), (20.054, 20.041), (-0.020, -0.054)),
    (50, "H11/c11", (50.160, 50.000), (49.870, 49.710), (0.450, 0.130)),
    (50, "H8/f7", (50.039, 50.000), (49.975, 49.950), (0.089, 0.025)),
    (50, "H7/g6", (50.025, 50.000), (49.991, 49.975), (0.050, 0.009)),
    (100, "H9/d9", (100.087, 100.000), (99.880, 99.793), (0.294, 0.120)),
    (100, "H8/f7", (100.054, 100.000), (99.964, 99.929), (0.125, 0.036)),
    (100, "H7/k6", (100.035, 100.000), (100.025, 100.003), (0.032, -0.025)),
    (100, "H7/n6", (100.035, 100.000), (100.045, 100.023), (0.012, -0.045)),
    (100, "H7/p6", (100.035, 100.000), (100.059, 100.037), (-0.002, -0.059)),
    (100, "H7/s6", (100.035, 100.000), (100.093, 100.071), (-0.036, -0.093)),
    (100, "H7/u6", (100.035, 100.000), (100.146, 100.124), (-0.089, -0.146)),
    # 10 mm is the upper bound of 6-10 mm and uses that range
    (10, "H11/c11", (10.090, 10.000), (9.920, 9.830), (0.260, 0.080)),
    (10, "H7/g6", (10.015, 10.000), (9.995, 9.986), (0.029, 0.005)),
    (10, "H7/s6", (10.015, 10.000), (10.032, 10.023), (-0.008, -0.032)),
    (250, "H11/c11", (250.290, 250.000), (249.720, 249.430), (0.860, 0.280)),
    (250, "H7/g6", (250.046, 250.000), (249.985, 249.956), (0.090, 0.015)),
    (250, "H7/s6", (250.046, 250.000), (250.169, 250.140), (-0.094, -0.169)),
    (250, "H7/u6", (250.046, 250.000), (250.313, 250.284), (-0.238, -0.313)),
    (400, "H7/g6", (400.057, 400.000), (399.982, 399.946), (0.111, 0.018)),
    (400, "H7/s6", (400.057, 400.000), (400.244, 400.208), (-0.151, -0.244)),
    (400, "H7/u6", (400.057, 400.000), (400.471, 400.435), (-0.378, -0.471)),
    (500, "H11/c11", (500.400, 500.000), (499.520, 499.120), (1.280, 0.480)),
    (500, "H7/u6", (500.063, 500.000), (500.580, 500.540), (-0.477, -0.580)),
]

# [MH-shaft] (nominal mm, fit, hole (max, min) mm, fit (max, min) mm); shaft h6 as in MH-hole
SHAFT_BASIS_FITS = [
    (20, "C11/h11", (20.240, 20.110), (0.370, 0.110)),
    (20, "D9/h9", (20.117, 20.065), (0.169, 0.065)),
    (20, "F8/h7", (20.053, 20.020), (0.074, 0.020)),
    (20, "G7/h6", (20.028, 20.007), (0.041, 0.007)),
    (20, "K7/h6", (20.006, 19.985), (0.019, -0.015)),
    (20, "N7/h6", (19.993, 19.972), (0.006, -0.028)),
    (20, "P7/h6", (19.986, 19.965), (-0.001, -0.035)),
    (20, "S7/h6", (19.973, 19.952), (-0.014, -0.048)),
    (20, "U7/h6", (19.967, 19.946), (-0.020, -0.054)),
    (100, "K7/h6", (100.010, 99.975), (0.032, -0.025)),
    (100, "N7/h6", (99.990, 99.955), (0.012, -0.045)),
    (100, "P7/h6", (99.976, 99.941), (-0.002, -0.059)),
    (100, "S7/h6", (99.942, 99.907), (-0.036, -0.093)),
    (100, "U7/h6", (99.889, 99.854), (-0.089, -0.146)),
]

# [ISO 286-2] single classes: (class, nominal mm, (lower, upper) deviation µm)
SINGLE_CLASSES = [
    ("K6", 20, (-11, 2)),  # K: -2 + Δ(6) = -2 + 4
    ("K8", 5, (-13, 5)),  # K: -1 + Δ(8) = -1 + 6
    ("M6", 20, (-17, -4)),
    ("M7", 50, (-25, 0)),  # 50 mm: upper bound of 40-50
    ("M8", 20, (-29, 4)),
    ("M6", 300, (-41, -9)),  # special case of ISO 286-1 Table 3 (not -11)
    ("M6", 200, (-37, -8)),
    ("M6", 400, (-46, -10)),
    ("N6", 20, (-24, -11)),
    ("N9", 20, (-52, 0)),  # N above grade 8: ES = 0
    ("js6", 20, (-6.5, 6.5)),
    ("JS7", 20, (-10.5, 10.5)),
    ("r6", 65, (41, 60)),  # 65 mm: upper bound of 50-65 ...
    ("r6", 66, (43, 62)),  # ... 66 mm in 65-80
    ("u6", 24, (41, 54)),  # 24 mm: upper bound of 18-24 ...
    ("u6", 25, (48, 61)),  # ... 25 mm in 24-30
    ("a11", 45, (-480, -320)),  # 40-50
    ("b11", 35, (-330, -170)),  # 30-40
    ("k6", 2, (0, 6)),  # up to 3 mm
    ("k8", 20, (0, 33)),  # k above grade 7: ei = 0
    ("H7", 450, (0, 63)),  # 400-500
    ("g6", 10.5, (-17, -6)),  # just over 10 mm: 10-14
]

# [ISO 286-1] Table 1 (grade, nominal mm, IT µm)
IT_VALUES = [
    ("7", 20, 21),
    ("6", 20, 13),
    ("5", 10, 6),
    ("11", 100, 220),
    ("16", 300, 3200),
    ("18", 500, 9700),
    ("1", 150, 3.5),
    ("01", 450, 4),
    ("0", 3, 0.5),
    ("9", 3.5, 30),
]


def _deviations(limits_mm, nominal_mm):
    """Published (max, min) limits in mm -> (lower, upper) deviation in m."""
    high, low = limits_mm
    return ((low - nominal_mm) / 1e3, (high - nominal_mm) / 1e3)


@pytest.mark.parametrize("nominal, fit, hole, shaft, clearance", HOLE_BASIS_FITS)
def test_hole_basis_fits_match_published_limits(nominal, fit, hole, shaft, clearance):
    hole_zone, shaft_zone = fit_zones(fit, nominal / 1e3)
    assert hole_zone == pytest.approx(_deviations(hole, nominal), abs=LIMIT_ATOL)
    assert shaft_zone == pytest.approx(_deviations(shaft, nominal), abs=LIMIT_ATOL)
    assert fit_clearance(fit, nominal / 1e3) == pytest.approx(
        (clearance[1] / 2e3, clearance[0] / 2e3), abs=LIMIT_ATOL
    )


@pytest.mark.parametrize("nominal, fit, hole, clearance", SHAFT_BASIS_FITS)
def test_shaft_basis_fits_match_published_limits(nominal, fit, hole, clearance):
    hole_zone, _ = fit_zones(fit, nominal / 1e3)
    assert hole_zone == pytest.approx(_deviations(hole, nominal), abs=LIMIT_ATOL)
    assert fit_clearance(fit, nominal / 1e3) == pytest.approx(
        (clearance[1] / 2e3, clearance[0] / 2e3), abs=LIMIT_ATOL
    )


@pytest.mark.parametrize("designation, nominal, deviations_um", SINGLE_CLASSES)
def test_single_classes_match_iso_286_2(designation, nominal, deviations_um):
    expected = (deviations_um[0] * 1e-6, deviations_um[1] * 1e-6)
    assert tolerance_zone(designation, nominal / 1e3) == pytest.approx(expected, abs=LIMIT_ATOL)


@pytest.mark.parametrize("grade, nominal, it_um", IT_VALUES)
def test_standard_tolerance_matches_table_1(grade, nominal, it_um):
    assert standard_tolerance(grade, nominal / 1e3) == pytest.approx(it_um * 1e-6, abs=1e-13)
    assert standard_tolerance("IT" + grade, nominal / 1e3) == standard_tolerance(
        grade, nominal / 1e3
    )


def test_examples_of_the_docstrings_are_exact():
    assert tolerance_zone("H7", 0.02) == (0.0, 21e-6)
    assert tolerance_zone("g6", 0.02) == (-20e-6, -7e-6)
    assert fit_clearance("H7/g6", 0.02) == (3.5e-6, 20.5e-6)
    assert standard_tolerance(7, 0.02) == 21e-6


def test_delta_is_the_difference_of_consecutive_grades():
    """ISO 286-1 Table 3: Δ = IT(n) − IT(n−1) over 3 mm and Δ = 0 up to 3 mm; the two transcribed
    tables must agree."""
    for grade, row in _DELTA_UM.items():
        assert row[0] == 0.0
        for k, delta in enumerate(row[1:], start=1):
            assert delta == pytest.approx(_IT_UM[str(grade)][k] - _IT_UM[str(grade - 1)][k])


def test_tables_are_monotonic_in_grade():
    grades = list(_IT_UM)
    for finer, coarser in zip(grades, grades[1:], strict=False):
        assert all(a < b for a, b in zip(_IT_UM[finer], _IT_UM[coarser], strict=True))


def test_range_boundaries_belong_to_the_lower_range():
    assert tolerance_zone("g6", 0.003) == tolerance_zone("g6", 0.002)  # 3 mm in 0-3
    assert tolerance_zone("g6", 0.0031) != tolerance_zone("g6", 0.003)
    assert tolerance_zone("s6", 0.05) == tolerance_zone("s6", 0.045)  # 50 mm in 40-50 (30-50)
    assert tolerance_zone("s6", 0.0501) == pytest.approx((53e-6, 72e-6), abs=LIMIT_ATOL)  # 50-65
    assert tolerance_zone("H7", 0.5) == tolerance_zone("H7", 0.45)


def test_sizes_up_to_3_mm_are_accepted():
    assert tolerance_zone("H7", 0.001) == (0.0, 10e-6)
    assert fit_clearance("H7/g6", 0.002) == pytest.approx((1e-6, 9e-6), abs=LIMIT_ATOL)


def test_whitespace_around_fit_parts_is_accepted():
    assert fit_clearance(" H7 / g6 ", 0.02) == fit_clearance("H7/g6", 0.02)


@pytest.mark.parametrize(
    "designation, match",
    [
        ("x7", r"unknown fundamental deviation letter 'x'.*supported: holes A, B.*shafts a, b"),
        ("Js7", r"unknown fundamental deviation letter 'Js'"),
        ("H19", r"unknown tolerance grade '19'.*supported: IT grades 01, 0, 1"),
        ("7H", r"cannot read tolerance designation '7H'.*e\.g\. 'H7'"),
        ("", r"cannot read tolerance designation"),
        ("K9", r"hole K above grade 8 only up to 3 mm"),
        ("M2", r"only from grade 3"),
        ("P01", r"only from grade 3"),
    ],
)
def test_bad_designation_raises(designation, match):
    with pytest.raises(ValueError, match=match):
        tolerance_zone(designation, 0.02)


@pytest.mark.parametrize("diameter", [20.0, 0.0, -0.01, 0.6, float("nan"), float("inf")])
def test_diameter_outside_the_tables_raises(diameter):
    with pytest.raises(ValueError, match=r"diameter must be in metres.*0\.02 for 20 mm"):
        tolerance_zone("H7", diameter)


def test_diameter_in_millimetres_gets_a_hint():
    with pytest.raises(ValueError, match=r"looks like millimetres: give 0\.02 for 20 mm"):
        fit_clearance("H7/g6", 20.0)


def test_classes_not_used_up_to_1_mm_raise():
    with pytest.raises(ValueError, match=r"deviation a for nominal sizes up to 1 mm"):
        tolerance_zone("a11", 0.001)
    with pytest.raises(ValueError, match=r"IT14 to IT18 for nominal sizes up to 1 mm"):
        tolerance_zone("h14", 0.0005)
    with pytest.raises(ValueError, match=r"hole N above grade 8 for sizes up to 1 mm"):
        tolerance_zone("N9", 0.001)


@pytest.mark.parametrize("fit", ["H7g6", "g6/H7", "H7/g6/h5", "H7/", "/g6", "h7/g6", "H7/G6"])
def test_malformed_fit_raises(fit):
    with pytest.raises(ValueError, match=r"expected hole/shaft such as \"H7/g6\""):
        fit_clearance(fit, 0.02)


def test_bad_grade_of_standard_tolerance_raises():
    with pytest.raises(ValueError, match=r"unknown tolerance grade 'IT19'.*'IT7', '7' or 7"):
        standard_tolerance("IT19", 0.02)
