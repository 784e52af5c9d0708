"""The ``jaxclear run`` command: outputs, config-file layering and every bad-input path."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

import jaxclear
import jaxclear._simulate
from jaxclear import cli

# Short horizon, shared by every simulating test here and in test_plot.py: the same number of output
# points and solver settings compile once per process.
SHORT = ["--revolutions", "0.25", "--points-per-revolution", "36", "--no-progress", "--quiet"]
NUM_POINTS = 10  # 0.25 rev x 36 points/rev = 9 intervals
CRANK, ROD = 0.05, 0.12  # m, slider_crank defaults
POSITION_TOLERANCE = 1e-6  # m: the 'fast' preset (rtol 1e-6) and Baumgarte drift stay well below
EXPECTED_COLUMNS = [
    "t",
    "crank_angle",
    "slider_x",
    "slider_v",
    "slider_a",
    "crank_torque",
    "O_Fx",
    "O_Fy",
    "A_Fx",
    "A_Fy",
    "B_Fx",
    "B_Fy",
    "slider_guide_moment",
    "slider_guide_normal",
    "constraint_violation",
    "velocity_violation",
]


def closed_form_slider_x(angle_rad):
    """x_B = r cos θ + sqrt(l² − r² sin² θ) for the slider on the axis through the crank pivot."""
    return CRANK * np.cos(angle_rad) + np.sqrt(ROD**2 - (CRANK * np.sin(angle_rad)) ** 2)


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    assert cli.main(["run", *SHORT, "--out", str(out)]) == 0
    return out


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], dtype=float)
    return header, {name: body[:, k] for k, name in enumerate(header)}


def test_run_writes_files(default_run):
    for name in ("results.csv", "results.npz", "run.json", "slider_acceleration.png", "constraint_violation.png"):
        assert (default_run / name).stat().st_size > 0, name
    assert not list(default_run.glob(".*tmp*")), "temporary files left behind"


def test_csv_columns_and_values(default_run):
    header, cols = read_csv(default_run / "results.csv")
    assert header == EXPECTED_COLUMNS
    assert cols["t"].shape == (NUM_POINTS,)
    rpm = 5000.0
    assert cols["t"][-1] == pytest.approx(0.25 * 60 / rpm)
    np.testing.assert_allclose(cols["crank_angle"], np.linspace(0.0, 90.0, NUM_POINTS), atol=1e-6)
    expected = closed_form_slider_x(np.radians(cols["crank_angle"]))
    np.testing.assert_allclose(cols["slider_x"], expected, atol=POSITION_TOLERANCE)
    assert cols["slider_x"][0] == pytest.approx(CRANK + ROD)
    # Outer dead centre: slider at rest, acceleration −rω²(1 + r/l) (MODEL.md §6: −19 419 m/s²).
    omega = rpm * 2 * math.pi / 60
    assert cols["slider_v"][0] == pytest.approx(0.0, abs=1e-6)
    assert cols["slider_a"][0] == pytest.approx(-CRANK * omega**2 * (1 + CRANK / ROD), rel=1e-4)
    assert np.all(cols["constraint_violation"] < POSITION_TOLERANCE)


def test_npz_matches_csv(default_run):
    header, cols = read_csv(default_run / "results.csv")
    with np.load(default_run / "results.npz") as npz:
        assert sorted(npz.files) == sorted(header)
        for name in header:
            np.testing.assert_allclose(npz[name], cols[name], rtol=1e-11, atol=1e-300)


def test_run_json(default_run):
    info = json.loads((default_run / "run.json").read_text())
    assert info["status"] == "complete"
    assert info["config"]["mechanism"]["rpm"] == 5000.0
    assert info["config"]["solver"]["method"] == "fast"
    assert info["solver"]["method"] == "tsit5"
    assert info["stats"]["succeeded"] is True and info["stats"]["num_steps"] > 0
    assert info["compile_time_s"] > 0 and info["run_time_s"] > 0
    for package in ("jaxclear", "jax", "jaxlib", "diffrax", "equinox", "numpy"):
        assert info["versions"][package], package
    assert info["columns"]["slider_a"]["unit"] == "m/s^2"
    assert set(info["files"]) >= {"results.csv", "results.npz", "run.json", "slider_position.png"}


def test_config_file_and_override(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text(
        '[mechanism]\nrpm = 3000\ninitial_angle = 0.5\n[simulation]\nrevolutions = 1\n[output]\nplots = false\n'
    )
    out = tmp_path / "out"
    # Options win over the file: 4000 rpm and a quarter revolution.
    assert cli.main(["run", str(config), *SHORT, "--rpm", "4000", "--out", str(out)]) == 0
    info = json.loads((out / "run.json").read_text())
    assert info["config"]["mechanism"]["rpm"] == 4000.0
    assert info["config"]["mechanism"]["initial_angle"] == 0.5
    assert info["sources"]["mechanism.rpm"] == "--rpm"
    assert info["config"]["simulation"]["revolutions"] == 0.25
    assert not (out / "slider_position.png").exists()
    _, cols = read_csv(out / "results.csv")
    assert cols["t"][-1] == pytest.approx(0.25 * 60 / 4000)
    assert cols["crank_angle"][0] == pytest.approx(math.degrees(0.5))
    np.testing.assert_allclose(cols["slider_x"], closed_form_slider_x(np.radians(cols["crank_angle"])), atol=POSITION_TOLERANCE)


def test_help_lists_options_and_keys(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for setting in cli.SETTINGS:
        assert setting.key in text, setting.key
        if setting.flag:
            assert setting.flag in text, setting.flag
    for flag in ("--no-progress", "--quiet", "--no-gravity", "rev/min"):
        assert flag in text


def test_top_level_help(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--help"])
    assert exc.value.code == 0
    assert "run" in capsys.readouterr().out


def test_readme_documents_every_setting():
    readme = (Path(__file__).parents[1] / "README.md").read_text()
    for setting in cli.SETTINGS:
        assert f"`{setting.key}`" in readme, setting.key
        if setting.flag:
            assert f"`{setting.flag}" in readme, setting.flag


BAD_CONFIGS = {
    "malformed": ("[mechanism]\nrpm = \n", "not valid TOML"),
    "unknown key": ("[mechanism]\nspeed = 3000\n", "unknown key 'speed'"),
    "unknown section": ("[mech]\nrpm = 3000\n", "unknown section"),
    "wrong type": ('[mechanism]\nrpm = "fast"\n', "must be a number"),
    "bool for number": ("[simulation]\nrevolutions = true\n", "must be a number"),
    "float for integer": ("[simulation]\npoints_per_revolution = 3.5\n", "must be an integer"),
    "not in a section": ("rpm = 3000\n", "put it under [mechanism]"),
    "negative in file": ("[mechanism]\nrod_mass = -1.0\n", "must be positive"),
    "unknown solver": ('[solver]\nmethod = "euler"\n', "solver 'euler' is unknown"),
    "rod too short": ("[mechanism]\nrod_length = 0.04\n", "rod_length > crank_length"),
}
BAD_OPTIONS = {
    "unknown option": (["--bogus"], "unrecognized arguments: --bogus"),
    "misspelt option": (["--rmp", "3"], "did you mean --rpm"),
    "abbreviated option": (["--revolution", "1"], "unrecognized arguments"),
    "negative rpm": (["--rpm", "-5"], "--rpm must be positive"),
    "zero revolutions": (["--revolutions", "0"], "--revolutions must be positive"),
    "not a number": (["--rpm", "abc"], "needs a number"),
    "nan": (["--rtol", "nan"], "must be finite"),
    "non-integer points": (["--points-per-revolution", "2.5"], "needs an integer"),
    "zero max steps": (["--max-steps", "0"], "must be positive"),
    "unknown solver": (["--solver", "euler"], "solver 'euler' is unknown"),
    "missing config": (["does-not-exist.toml"], "not found"),
}


def assert_usage_error(capsys, argv, match):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("jaxclear: error: "), err
    assert match in lines[0], err
    assert "Traceback" not in err


@pytest.mark.parametrize("case", list(BAD_CONFIGS))
def test_bad_config_file(case, tmp_path, capsys):
    text, match = BAD_CONFIGS[case]
    config = tmp_path / "bad.toml"
    config.write_text(text)
    assert_usage_error(capsys, ["run", str(config), *SHORT, "--out", str(tmp_path / "out")], match)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", list(BAD_OPTIONS))
def test_bad_option(case, tmp_path, capsys):
    args, match = BAD_OPTIONS[case]
    assert_usage_error(capsys, ["run", *args, "--out", str(tmp_path / "out")], match)


def test_no_command(capsys):
    assert_usage_error(capsys, [], "required")


def test_out_is_a_file(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert_usage_error(capsys, ["run", *SHORT, "--out", str(target)], "is not a folder")


def test_simulation_failure_exits_1(tmp_path, capsys, monkeypatch):
    # A failing solve is simulated (a real one needs new solver settings, i.e. another compilation).
    def failing(*args, **kwargs):
        raise jaxclear.SimulationError("simulation failed at t = 0.001 s after 3 steps.\nSuggested fix: raise max_steps.")

    monkeypatch.setattr(jaxclear._simulate, "simulate", failing)
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", *SHORT, "--out", str(tmp_path / "out")])
    assert exc.value.code == 1
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("jaxclear: error: simulation failed"), lines
    assert "max_steps" in lines[0]
    assert not (tmp_path / "out" / "results.csv").exists()


def test_unexpected_error_is_one_line(tmp_path, capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("something\nunexpected")

    monkeypatch.setattr(jaxclear._simulate, "simulate", broken)
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", *SHORT, "--out", str(tmp_path / "out")])
    assert exc.value.code == 1
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["jaxclear: error: RuntimeError: something unexpected (set JAXCLEAR_TRACEBACK=1 for the traceback)"]
