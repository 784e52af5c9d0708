"""Identification from measured data: ``jaxclear.identify`` and ``jaxclear fit``.

The data are not made by jaxclear: tests/reference/identification_data.py simulated them with the
independent SciPy code (sharp contact events), with Gaussian noise of 1 µm on slider position and
2 % of the RMS on slider acceleration and crank torque. The quick case fits the clearance of
joint B (pin on the rod, gravity on, 5000 rpm, true 0.3 mm, start 0.5 mm) over the first 1.5 ms of
that record; the API test and the command-line test use the same shapes and settings, so they
share one compilation. The full records (6 ms at 5000 rpm, 0.3 s at 200 rpm, two joints) are
``slow`` tests.
"""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from reference.identification_data import load

import jaxclear
from jaxclear import cli
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb

QUICK_SPAN = 1.5e-3  # s of the 6 ms record: several impacts, seconds to fit
QUICK_SCAN = 8  # one vectorised chunk
QUICK_HORIZONS = (0.25, 0.5, 1.0)
TARGET = 0.02  # relative error of the clearance the issue asks for
START = {"B.clearance": (5e-4, 1e-4, 8e-4)}  # m: initial, lower, upper

CONFIG = Path(__file__).parents[1] / "examples" / "fit_clearance_B.toml"  # the docs' example


def mechanism(rpm=5000.0, joints=None):
    return jaxclear.mechanisms.slider_crank(
        rpm=rpm,
        gravity=True,
        clearance_joints=joints or {"B": {"clearance": 5e-4, "journal_body": "rod"}},
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )


def write_csv(path, columns):
    names = list(columns)
    table = np.column_stack([columns[n] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.12g")
    return path


@pytest.fixture(scope="module")
def config():
    return str(CONFIG)


@pytest.fixture(scope="module")
def quick_data(tmp_path_factory):
    columns, meta = load("ident_5000rpm_B")
    keep = columns["t"] <= QUICK_SPAN + 1e-12
    columns = {n: v[keep] for n, v in columns.items()}
    path = write_csv(tmp_path_factory.mktemp("data") / "quick.csv", columns)
    return path, meta


@pytest.fixture(scope="module")
def quick_fit(quick_data):
    path, meta = quick_data
    mech = mechanism()
    data = jaxclear.Measurements.from_csv(path, known=jaxclear.signal_names(mech))
    result = jaxclear.identify(mech, data, START, scan_points=QUICK_SCAN, horizons=QUICK_HORIZONS)
    return result, meta


def test_quick_fit_recovers_clearance(quick_fit):
    result, meta = quick_fit
    truth = meta["true_parameters"]["clearance"]["B"]
    estimate = result.parameters["B.clearance"]
    assert abs(estimate.value - truth) <= TARGET * truth
    assert abs(estimate.value - truth) <= 2 * estimate.std, "2σ interval must contain the truth"
    assert estimate.initial == 5e-4 and (estimate.lower, estimate.upper) == (1e-4, 8e-4)
    assert result.loss < 2.0  # ≈ 1: the model follows the data to their noise level
    assert set(result.noise) == {"slider_x", "slider_a", "crank_torque"}
    assert all(result.noise_estimated.values())
    # the scan covered the bounds and started from the initial point
    assert result.scan["values"].shape == (QUICK_SCAN, 1)
    assert result.scan["values"][0, 0] == 5e-4
    assert result.history[0]["stage"] == "scan"
    # fitted signals are the model's: their residual is about the noise level
    residual = result.fitted["slider_x"] - result.measured["slider_x"]
    assert np.sqrt(np.mean(residual**2)) < 3 * result.noise["slider_x"]


def test_fit_command_writes_results(quick_data, quick_fit, config, tmp_path):
    path, meta = quick_data
    out = tmp_path / "fit"
    argv = [
        "fit",
        str(path),
        config,
        "--fit",
        "B.clearance=5e-4:1e-4:8e-4",
        "--scan-points",
        str(QUICK_SCAN),
        "--horizons",
        ",".join(str(h) for h in QUICK_HORIZONS),
        "--out",
        str(out),
        "--quiet",
    ]
    assert cli.main(argv) == 0
    info = json.loads((out / "fit.json").read_text())
    fitted = info["parameters"]["B.clearance"]
    api = quick_fit[0].parameters["B.clearance"]
    assert fitted["value"] == pytest.approx(api.value, rel=1e-9)  # the same fit as the API's
    assert fitted["std"] > 0 and set(fitted) >= {"value", "std", "initial", "lower", "upper"}
    assert info["converged"] in (True, False) and info["iterations"] >= 1
    assert info["history"] and info["time_s"] > 0
    header = (out / "fit.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["t", "slider_x_measured", "slider_x_fitted", "slider_x_residual"]
    for png in ("fit.png", "loss.png"):
        assert (out / png).stat().st_size > 1000


# --- bad input: one line, exit 2, nothing written ------------------------------------------------


def _fails(argv, tmp_path, capsys, match):
    out = tmp_path / "never"
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--out", str(out), "--quiet"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("jaxclear: error:")
    assert re.search(match, err), err
    assert not out.exists()


@pytest.mark.parametrize(
    "text, match",
    [
        ("time,slider_x\n0,0.17\n1e-5,0.17\n", "no 't' column"),
        ("t\n0\n1e-5\n", "no signal column"),
        ("t,slider_y\n0,0.17\n1e-5,0.17\n", "'slider_y' is not a signal"),
        ("t,slider_x\n0,0.17\n1e-5,nan\n", "not finite"),
        ("t,slider_x\n0,0.17\n1e-5,0.17\n1e-5,0.17\n", "not strictly increasing"),
        ("t,slider_x\n0,0.17\n2e-5,0.17\n1e-5,0.17\n", "not strictly increasing"),
        ("t,slider_x\n0,0.17\n1e-5\n", "has 1 cells but the header has 2"),
        ("t,slider_x\n0,0.17\n1e-5,abc\n", "is not a number"),
        ("t,slider_x\n0,0.17\n0.5,0.17\n", "past the simulated span"),
        ("t,slider_x\n-1e-3,0.17\n1e-5,0.17\n", "outside the simulated span"),
    ],
)
def test_bad_data(text, match, config, tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    argv = ["fit", str(path), config, "--fit", "B.clearance", "--noise", "slider_x=1e-6"]
    _fails(argv, tmp_path, capsys, match)


def test_non_utf8_data(config, tmp_path, capsys):
    path = tmp_path / "latin1.csv"
    path.write_bytes("t,slider_x\n0,0.17\n1e-5,0.17 \xe9\n".encode("latin-1"))
    argv = ["fit", str(path), config, "--fit", "B.clearance"]
    _fails(argv, tmp_path, capsys, "not UTF-8")


def test_fewer_points_than_parameters(config, tmp_path, capsys):
    path = tmp_path / "two.csv"
    path.write_text("t,slider_x\n0,0.17\n1e-5,0.17\n")
    argv = [
        "fit",
        str(path),
        config,
        "--fit",
        "B.clearance,B.restitution,rod_mass",
        "--noise",
        "slider_x=1e-6",
    ]
    _fails(argv, tmp_path, capsys, "for 3 fitted parameters")


@pytest.mark.parametrize(
    "spec, match",
    [
        ("B.clearence", "unknown parameter 'B.clearence'; did you mean 'B.clearance'"),
        ("A.clearance", "unknown parameter 'A.clearance'"),
        ("B.clearance=abc", "is not INITIAL or INITIAL:LOWER:UPPER"),
        ("B.clearance=5e-4:1e-4", "got 2 numbers"),
        ("B.clearance=9e-4:1e-4:8e-4", "not strictly inside its bounds"),
    ],
)
def test_bad_parameters(spec, match, config, tmp_path, capsys):
    path = tmp_path / "ok.csv"
    t = np.linspace(0, 1e-3, 50)
    write_csv(path, {"t": t, "slider_x": 0.17 + 0 * t})
    argv = ["fit", str(path), config, "--fit", spec, "--noise", "slider_x=1e-6"]
    _fails(argv, tmp_path, capsys, match)


# --- full cases of the issue (slow) ---------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, rpm, fitted",
    [
        ("ident_5000rpm_B", 5000.0, {"B.clearance": (5e-4, 1e-4, 8e-4)}),
        ("ident_200rpm_B", 200.0, {"B.clearance": (5e-4, 1e-4, 8e-4)}),
        (
            "ident_5000rpm_AB",
            5000.0,
            {"B.clearance": (5e-4, 1e-4, 8e-4), "A.clearance": (5e-4, 1e-4, 8e-4)},
        ),
    ],
)
def test_full_records(name, rpm, fitted):
    columns, meta = load(name)
    joints = {"B": {"clearance": 5e-4, "journal_body": "rod"}}
    if "A.clearance" in fitted:
        joints["A"] = {"clearance": 5e-4}
    mech = mechanism(rpm, joints)
    t = columns.pop("t")
    data = jaxclear.Measurements.from_arrays(t, columns, known=jaxclear.signal_names(mech))
    result = jaxclear.identify(mech, data, fitted)
    print(f"{name}: {result.values} in {result.time:.1f} s, fitted up to {result.window_end:g} s")
    for key, estimate in result.parameters.items():
        truth = meta["true_parameters"]["clearance"][key.split(".")[0]]
        assert abs(estimate.value - truth) <= TARGET * truth, (key, estimate)
        assert abs(estimate.value - truth) <= 2 * estimate.std, (key, estimate)
