"""``jaxclear.Measurements``: measured data from CSV files and arrays, checked, with noise levels.

Every bad-data path raises ``DataError`` with a one-line message naming the file, where, and the
fix; the noise estimator is checked on synthetic data; a results.csv written by ``jaxclear run``'s
writer from a short simulation reads back as the same signals.
"""

import re

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import NUM_POINTS

import jaxclear
from jaxclear import DataError, Measurements
from jaxclear.io import result_columns, write_csv
from jaxclear.io._measurements import NOISE_FLOOR, estimate_noise
from jaxclear.mechanisms import slider_crank

KNOWN = ("slider_x", "slider_v", "slider_a", "B_normal_force")
NOISE_RTOL = 0.10
"""Estimated vs true σ on 600 samples: the estimator's spread there is 4.4 % (5.2 % with spikes;
measured over 2000 draws, ``estimate_noise``), so 10 % is over two standard deviations."""

CSV_RTOL = 1e-11
"""results.csv keeps 12 significant digits (``jaxclear.io.CSV_FORMAT``): relative round-off 5e-12."""


def _write(tmp_path, text: str | bytes, name="data.csv"):
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def _smooth_rows(n=20):
    t = np.linspace(0.0, 1e-2, n)
    return t, np.sin(300 * t), np.cos(300 * t)


def _csv(t, *columns, header="t,slider_x,slider_v"):
    rows = [",".join(repr(float(v)) for v in row) for row in zip(t, *columns, strict=True)]
    return header + "\n" + "\n".join(rows) + "\n"


def _raises(path, match, **options):
    """The DataError's message: one line, naming the file, matching ``match``."""
    with pytest.raises(DataError, match=match) as info:
        Measurements.from_csv(path, **options)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    return message


# --- reading ----------------------------------------------------------------------------------
def test_reads_columns_in_file_order_with_bom_spaces_and_blank_lines(tmp_path):
    t, x, v = _smooth_rows()
    text = _csv(t, v, x, header=" t , slider_v,slider_x").replace("\n", "\n\n", 3)
    path = _write(tmp_path, b"\xef\xbb\xbf" + text.replace(",", ", ").encode())
    data = Measurements.from_csv(path, known=KNOWN, noise={"slider_x": 1e-3})
    assert data.names == ("slider_v", "slider_x")
    assert data.source == str(path)
    assert data.t.dtype == np.float64 and data.t.shape == (20,)
    np.testing.assert_array_equal(data.t, t)
    np.testing.assert_array_equal(data.signals["slider_x"], x)
    assert data.noise["slider_x"] == 1e-3
    assert data.noise_estimated == {"slider_v": True, "slider_x": False}
    assert data.num_values == 40


def test_columns_selects_a_subset(tmp_path):
    t, x, v = _smooth_rows()
    path = _write(tmp_path, _csv(t, x, v, header="t,slider_x,junk"))
    data = Measurements.from_csv(path, known=KNOWN, columns=["slider_x"])
    assert data.names == ("slider_x",)


# --- errors: one per problem --------------------------------------------------------------------
def test_missing_and_unreadable_file(tmp_path):
    _raises(
        tmp_path / "nope.csv", r"cannot read the data file \(No such file or directory\); check"
    )
    _raises(tmp_path, r"cannot read the data file \(Is a directory\)")


def test_not_utf8_names_the_byte(tmp_path):
    path = _write(tmp_path, b"t,slider_x\n0,1\n1,\xe92\n")
    _raises(path, r"byte 17 \(line 3\) is not UTF-8 \(0xe9\); save the file as UTF-8")


def test_empty_file_and_header_only(tmp_path):
    _raises(_write(tmp_path, ""), "the file is empty; write a header row")
    _raises(_write(tmp_path, " \n\n", "blank.csv"), "the file is empty")
    _raises(_write(tmp_path, "t,slider_x\n", "header.csv"), r"no data rows after the header")


def test_ragged_row(tmp_path):
    path = _write(tmp_path, "t,slider_x,slider_v\n0,1,2\n1,2\n")
    _raises(path, r"line 3 has 2 cells but the header has 3 columns; give every row")
    path = _write(tmp_path, "t,slider_x\n0,1\n1,2,\n", "trailing.csv")
    _raises(path, r"line 3 has 3 cells but the header has 2 columns")


def test_non_numeric_and_empty_cells(tmp_path):
    path = _write(tmp_path, "t,slider_x\n0,1\n1,abc\n")
    _raises(path, r"line 3, column 'slider_x': 'abc' is not a number; write plain decimal")
    path = _write(tmp_path, "t,slider_x\n0,1\n,2\n", "empty_cell.csv")
    _raises(path, r"line 3, column 't': an empty cell is not a number")


def test_bad_quoting(tmp_path):
    path = _write(tmp_path, 't,slider_x\n0,1\n1,"2\n')
    _raises(path, r"line 3 is not valid CSV \(.*\); close or remove the quote")


def test_header_problems(tmp_path):
    _raises(
        _write(tmp_path, "time,slider_x\n0,1\n1,2\n"),
        r"no 't' column \(columns: time, slider_x\); name the time column 't' \(seconds\)",
    )
    _raises(
        _write(tmp_path, "t;slider_x\n0;1\n1;2\n", "semicolon.csv"),
        "separate the columns with commas",
    )
    _raises(_write(tmp_path, "# t,slider_x\n0,1\n", "hash.csv"), "remove the '#'")
    _raises(
        _write(tmp_path, "t,slider_x,slider_x\n0,1,1\n", "dup.csv"),
        r"column name 'slider_x' appears twice \(columns 2 and 3\); give each column a unique",
    )
    _raises(_write(tmp_path, "t,,slider_x\n0,1,1\n", "noname.csv"), r"column 2 of the header")


def test_unknown_missing_and_no_usable_columns(tmp_path):
    t, x, v = _smooth_rows()
    path = _write(tmp_path, _csv(t, x, v, header="t,slider_x,slider_y"))
    message = _raises(
        path,
        r"column 'slider_y' is not a signal of the mechanism \(valid names: slider_x, slider_v, "
        r"slider_a, B_normal_force\); rename it .*\(columns=",
        known=KNOWN,
    )
    assert "slider_x" in message
    _raises(
        path,
        r"selected column 'slider_a' is not in the file \(columns: slider_x, slider_y\)",
        columns=["slider_a"],
    )
    only_t = _write(tmp_path, "t\n0\n1\n", "only_t.csv")
    _raises(
        only_t, r"no signal column besides 't' \(valid names: .*\); add at least one", known=KNOWN
    )


def test_non_finite_values(tmp_path):
    t, x, v = _smooth_rows()
    x[4], x[7] = np.nan, np.inf
    path = _write(tmp_path, _csv(t, x, v))
    _raises(path, r"column 'slider_x', line 6: value nan is not finite \(2 such rows\); remove the")
    t[2] = np.inf
    _raises(_write(tmp_path, _csv(t, x, v), "t.csv"), r"column 't', line 4: value inf")


def test_times_not_increasing(tmp_path):
    t, x, v = _smooth_rows()
    t[5] = t[4]
    message = _raises(
        _write(tmp_path, _csv(t, x, v)),
        r"time not strictly increasing: line 7 has t = .* s, which repeats t = .* s on line 6; "
        r"sort the rows by t",
    )
    assert repr(float(t[4])) in message
    t[5] = t[4] - 1e-4
    _raises(_write(tmp_path, _csv(t, x, v), "back.csv"), r"line 7 has t = .* which goes back from")


def test_too_few_rows(tmp_path):
    _raises(_write(tmp_path, "t,slider_x\n0,1\n"), r"1 data row; a fit needs at least 2 instants")
    path = _write(tmp_path, "t,slider_x\n0,1\n1,2\n2,3\n", "three.csv")
    _raises(path, r"column 'slider_x': 3 rows are too few to estimate its noise .*\(noise=")
    assert Measurements.from_csv(path, noise={"slider_x": 0.1}).num_points == 3


def test_bad_noise_levels(tmp_path):
    t, x, v = _smooth_rows()
    path = _write(tmp_path, _csv(t, x, v))
    _raises(path, r"noise level of 'slider_x' is -1.0; give a finite", noise={"slider_x": -1.0})
    _raises(path, r"noise level of 'slider_x' is nan", noise={"slider_x": float("nan")})
    _raises(path, r"noise level is given for 'slider_a', which is not", noise={"slider_a": 1.0})
    zero = _write(tmp_path, _csv(t, 0 * x, v), "zero.csv")
    _raises(zero, r"column 'slider_x' is zero at every instant .*; give its noise level")
    assert Measurements.from_csv(zero, noise={"slider_x": 0.5}).noise["slider_x"] == 0.5


def test_from_arrays_checks(tmp_path):
    t, x, _ = _smooth_rows()
    with pytest.raises(DataError, match=r"array: signal 'slider_x' has shape \(19,\) but t has"):
        Measurements.from_arrays(t, {"slider_x": x[:-1]})
    with pytest.raises(DataError, match=r"array: column 'slider_q' is not a signal"):
        Measurements.from_arrays(t, {"slider_q": x}, known=KNOWN)
    x[3] = np.nan
    with pytest.raises(DataError, match=r"synthetic: column 'slider_x', index 3: value nan"):
        Measurements.from_arrays(t, {"slider_x": x}, source="synthetic")
    with pytest.raises(
        DataError, match=r"index 1 has t = 0.0 s, which repeats t = 0.0 s on index 0"
    ):
        Measurements.from_arrays([0.0, 0.0], {"slider_x": [1.0, 2.0]}, noise={"slider_x": 1.0})


def test_span_and_enough_checks():
    t = np.linspace(0.0, 0.01, 50)
    data = Measurements.from_arrays(t, {"slider_x": np.sin(300 * t)})
    data.check_span(0.0, 0.01)
    with pytest.raises(DataError, match=r"reach outside the simulated span .* the first at t = "):
        data.check_span(0.0, 0.005)
    data.check_enough(50)
    with pytest.raises(DataError, match=r"50 measured values \(50 instants × 1 signals\) for 51"):
        data.check_enough(51)


# --- noise --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_estimate_on_sinusoid_with_spikes(seed):
    """600 samples of two periods of a sinusoid, Gaussian noise σ = 1e-2, five spikes of 5–100 σ."""
    rng = np.random.default_rng(seed)
    sigma = 1e-2
    t = np.linspace(0.0, 1.0, 600)
    y = np.sin(2 * np.pi * 2 * t) + sigma * rng.standard_normal(t.size)
    spikes = rng.choice(t.size, 5, replace=False)
    y[spikes] += rng.choice([-1.0, 1.0], 5) * rng.uniform(5.0, 100.0, 5) * sigma
    assert estimate_noise(y) == pytest.approx(sigma, rel=NOISE_RTOL)
    data = Measurements.from_arrays(t, {"slider_x": y})
    assert data.noise["slider_x"] == estimate_noise(y)
    assert data.noise_estimated["slider_x"] and not data.noise_floored["slider_x"]


def test_noise_free_data_get_the_floor():
    t = np.linspace(0.0, 1.0, 100)
    y = 3.0 + 2.0 * t - t**2  # a quadratic: third differences zero up to round-off
    data = Measurements.from_arrays(
        t, {"slider_x": y, "slider_v": np.sin(t)}, noise={"slider_v": 0}
    )
    for name, values in data.signals.items():
        assert data.noise[name] == NOISE_FLOOR * np.sqrt(np.mean(values**2))
        assert data.noise_floored[name]


# --- a results.csv of a run reads back --------------------------------------------------------
@pytest.fixture(scope="module")
def run():
    """The ideal slider–crank, two revolutions at 5000 rpm (the configuration of the transform
    and constraint tests: a worker that ran them reuses the compiled solve)."""
    return jaxclear.simulate(
        slider_crank(rpm=5000.0), 2 * 60 / 5000, num_points=NUM_POINTS, solver="fast"
    )


def test_results_csv_round_trip(run, tmp_path):
    path = write_csv(tmp_path / "results.csv", result_columns(run))
    names = jaxclear.signal_names(run.mechanism)
    # The guide's moment on the slider is exactly zero (slider on the guide's axis): no scale.
    with pytest.raises(DataError, match=r"column 'slider_guide_moment' is zero at every instant"):
        Measurements.from_csv(path, known=names, columns=names)
    data = Measurements.from_csv(path, known=names, columns=names, noise={"slider_guide_moment": 1})
    assert data.names == names
    np.testing.assert_allclose(data.t, np.asarray(run.t), rtol=CSV_RTOL, atol=0)
    for name, values in jaxclear.signals(run, names).items():
        values = np.asarray(values)
        scale = np.abs(values).max()
        assert np.abs(data.signals[name] - values).max() <= CSV_RTOL * scale, name
        if name != "slider_guide_moment":
            # simulated data: what is left is the CSV's rounding, far below the floor
            assert data.noise_estimated[name] and data.noise_floored[name], name
    message = re.escape("column 'crank_angle' is not a signal of the mechanism")
    with pytest.raises(DataError, match=message):
        Measurements.from_csv(path, known=names)


def test_passes_through_filter_jit():
    """A Measurements is a pytree: its arrays are traced inputs of a jitted function."""
    t = np.linspace(0.0, 0.01, 30)
    data = Measurements.from_arrays(t, {"slider_x": np.sin(300 * t)}, noise={"slider_x": 0.5})

    @eqx.filter_jit
    def weighted_sum(measurements):
        return sum(jnp.sum(v) / measurements.noise[k] for k, v in measurements.signals.items())

    assert float(weighted_sum(data)) == pytest.approx(np.sum(np.sin(300 * t)) / 0.5, rel=1e-12)
