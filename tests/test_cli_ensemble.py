"""The ``jaxclear montecarlo`` and ``jaxclear sweep`` commands: outputs, resume, refusals, bad input.

Every solving call uses examples/montecarlo_h7g6.toml (clearance joint B, Lankarani-Nikravesh
contact, modified Coulomb friction) with the same short horizon, chunk size and one device, and
draws or sweeps B.clearance only: one compilation of the engine's chunk serves them all (about
20 s on one core); each later call traces once (about a second) and solves in a fraction of one.
"""

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_transforms import COMPILE_EVENT, count_compilations

import jaxclear.cli._ensemble_common
from jaxclear import cli
from jaxclear.analysis import DEFAULT_CONTINUOUS_FRACTION
from jaxclear.cli._common import NOT_APPLIED
from jaxclear.cli._config import resolve_settings
from jaxclear.cli._ensemble_common import DEVICE_COUNT_FLAG, apply_device_count
from jaxclear.cli._main import build_parser
from jaxclear.studies import fit_clearance

EXAMPLE = Path(__file__).parents[1] / "examples" / "montecarlo_h7g6.toml"
SHORT = [
    "--revolutions",
    "0.25",
    "--skip-revolutions",
    "0.05",
    "--points-per-revolution",
    "120",
    "--chunk-size",
    "4",
    "--devices",
    "1",
    "--no-progress",
]
SAMPLES = 6
FIT, DIAMETER = "H7/g6", 0.02  # the example's B.clearance
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(autouse=True)
def _keep_xla_flags(monkeypatch):
    """The commands add flags to XLA_FLAGS (read once, at JAX's start): undo that after each test,
    so later tests in this process see the variable as it was."""
    if "XLA_FLAGS" in os.environ:
        monkeypatch.setenv("XLA_FLAGS", os.environ["XLA_FLAGS"])
    else:
        monkeypatch.delenv("XLA_FLAGS", raising=False)


def montecarlo_argv(out, *extra, seed="1", samples=str(SAMPLES)):
    return [
        "montecarlo",
        str(EXAMPLE),
        *SHORT,
        "--samples",
        samples,
        "--seed",
        seed,
        "--out",
        str(out),
        *extra,
    ]


def sweep_argv(out, *extra):
    return ["sweep", str(EXAMPLE), *SHORT, "--param", "B.clearance", "--out", str(out), *extra]


def read_rows(path):
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def montecarlo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("mc")
    assert cli.main(montecarlo_argv(out, "--quiet")) == 0
    return out


def test_montecarlo_writes_outputs(montecarlo_run):
    out = montecarlo_run
    for name in ("samples.csv", "summary.json", "histograms.png", "scatter.png", "ensemble.json"):
        assert (out / name).exists(), name
    for name in ("histograms.png", "scatter.png"):
        assert (out / name).read_bytes().startswith(PNG_SIGNATURE)
    rows = read_rows(out / "samples.csv")
    assert sorted(int(r["index"]) for r in rows) == list(range(SAMPLES))
    assert all(r["status"] == "ok" for r in rows), [r["message"] for r in rows]
    low, high = fit_clearance(FIT, DIAMETER)
    drawn = np.array([float(r["B.clearance"]) for r in rows])
    assert np.all((drawn >= low) & (drawn <= high)), drawn
    assert np.unique(drawn).size == SAMPLES
    force = np.array([float(r["B_peak_normal_force"]) for r in rows])
    assert np.all(np.isfinite(force) & (force > 0))

    info = json.loads((out / "summary.json").read_text())
    assert info["kind"] == "montecarlo"
    assert (info["samples"], info["seed"], info["members"]) == (SAMPLES, 1, SAMPLES)
    assert (info["succeeded"], info["failed"], info["failures"]) == (SAMPLES, 0, [])
    assert info["distributions"] == {
        "B.clearance": {"fit": FIT, "diameter": DIAMETER, "within": "uniform"}
    }
    assert (info["devices"], info["chunk_size"]) == (1, 4)
    assert (info["engine"], info["lanes"]) == ("refill", 8)  # the defaults
    assert info["continuous_fraction"] == DEFAULT_CONTINUOUS_FRACTION  # not set in the file
    assert info["config"]["clearance"]["joints"] == "B"
    assert info["wall_time_s"] > 0 and info["versions"]["jaxclear"]
    stats = info["statistics"]["B_peak_normal_force"]
    assert stats["min"] <= stats["p5"] <= stats["p50"] <= stats["p95"] <= stats["max"]
    np.testing.assert_allclose(stats["p50"], np.median(force), rtol=1e-12)
    assert set(info["files"]) == {"samples.csv", "summary.json", "histograms.png", "scatter.png"}


def test_resume_solves_nothing(montecarlo_run, capsys):
    before = read_rows(montecarlo_run / "samples.csv")
    assert cli.main(montecarlo_argv(montecarlo_run)) == 0
    out = capsys.readouterr().out
    assert f"{SAMPLES} of {SAMPLES} members were already finished, 0 left to solve" in out
    assert f"{SAMPLES} of {SAMPLES} members succeeded, 0 failed" in out
    assert "B peak normal force: median" in out
    # every row as it was, wall_time_s included: a member solved again would have a new one
    assert read_rows(montecarlo_run / "samples.csv") == before


@pytest.mark.parametrize(
    "change, changed",
    [({"seed": "2"}, "description.seed"), ({"samples": "5"}, "description.samples")],
)
def test_changed_configuration_is_refused(montecarlo_run, capsys, change, changed):
    before = (montecarlo_run / "samples.csv").read_bytes()
    with pytest.raises(SystemExit) as exc:
        cli.main(montecarlo_argv(montecarlo_run, "--quiet", **change))
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "another configuration" in err and changed in err, err
    assert len(err.splitlines()) == 1
    assert (montecarlo_run / "samples.csv").read_bytes() == before


def test_sweep_range(tmp_path, capsys):
    """A sweep with its optional stages: Poincaré sections (bifurcation diagram) and Lyapunov
    exponents over one revolution from the start (--skip-revolutions 0 keeps them short)."""
    out = tmp_path / "sweep"
    stages = ["--skip-revolutions", "0", "--sections", "2", "--lyapunov", "1"]
    assert cli.main(sweep_argv(out, "--range", "1e-4", "4e-4", "4", *stages)) == 0
    printed = capsys.readouterr().out
    assert "B peak normal force: " in printed
    assert "largest Lyapunov exponent" in printed
    rows = read_rows(out / "sweep.csv")
    expected = np.linspace(1e-4, 4e-4, 4)
    np.testing.assert_array_equal([float(r["B.clearance"]) for r in rows], expected)
    assert [int(r["index"]) for r in rows] == [0, 1, 2, 3]
    assert all(r["status"] == "ok" for r in rows)
    info = json.loads((out / "sweep.json").read_text())
    assert (info["kind"], info["parameter"], info["unit"]) == ("sweep", "B.clearance", "m")
    np.testing.assert_array_equal(info["values"], expected)
    for png in ("sweep.png", "sweep_modes.png", "bifurcation.png", "lyapunov.png"):
        assert (out / png).read_bytes().startswith(PNG_SIGNATURE), png
        assert png in info["files"], png
    # contact modes per value: the combinations that occur, their shares summing to 1
    combinations = info["contact_mode_combinations"]
    assert len(combinations) == 4
    for shares, row in zip(combinations, rows, strict=True):
        assert set(shares) <= {"F", "I", "C"} and sum(shares.values()) == pytest.approx(1.0)
        for label, share in shares.items():
            assert float(row[f"combination_{label}_share"]) == pytest.approx(share)
    # two Poincaré points per value and signal: the start (no revolution skipped) and one
    # revolution later
    points = read_rows(out / "bifurcation.csv")
    assert [int(r["index"]) for r in points] == [0, 0, 1, 1, 2, 2, 3, 3]
    period = 60.0 / 5000.0
    times = [float(r["time_s"]) for r in points]
    np.testing.assert_allclose(times, [0.0, period] * 4, atol=1e-15)
    assert all(np.isfinite(float(r["B_ecc_x"])) for r in points)
    assert all(float(r["B_ecc_x"]) == 0.0 for r in points[::2])  # journals start centred
    assert info["bifurcation"]["distinct_points"]["B_ecc_x"]["counts"] == [2, 2, 2, 2]
    exponents = read_rows(out / "lyapunov.csv")
    assert [int(r["succeeded"]) for r in exponents] == [1, 1, 1, 1]
    assert all(np.isfinite(float(r["exponent_per_s"])) for r in exponents)
    assert info["lyapunov"]["solver"]["rtol"] == pytest.approx(1e-9)


def test_sweep_values_in_order(tmp_path):
    out = tmp_path / "sweep"
    values = [3e-4, 1e-4, 2e-4, 1.5e-4]  # a whole chunk (SHORT): test_sweep_range's program
    argv = sweep_argv(out, "--quiet", "--values=" + ",".join(map(str, values)))
    assert cli.main(argv) == 0
    rows = read_rows(out / "sweep.csv")
    assert [float(r["B.clearance"]) for r in rows] == values
    assert [r["status"] for r in rows] == ["ok"] * len(values)


def test_sweep_all_failed_exits_1(tmp_path, capsys):
    # a step budget far too small for the horizon: every member fails in the solver
    with pytest.raises(SystemExit) as exc:
        cli.main(
            sweep_argv(tmp_path / "sweep", "--quiet", "--values=2e-4,3e-4", "--max-steps", "5")
        )
    assert exc.value.code == 1
    assert "all 2 members failed" in capsys.readouterr().err
    info = json.loads((tmp_path / "sweep" / "sweep.json").read_text())
    assert info["succeeded"] == 0 and len(info["failures"]) == 2


# --- bad input: exit 2 before any solve, no output folder -----------------------------------------

CONFIG = """\
[clearance]
joints = "B"
contact = "lankarani-nikravesh"
friction = "modified-coulomb"
"""
BAD_MONTECARLO = {
    "misspelt distribution": (
        '[montecarlo.B]\nclearance = { distribution = "uniformm", low = 3e-4, high = 6e-4 }\n',
        [],
        "B.clearance: unknown distribution 'uniformm'",
    ),
    "missing key": (
        '[montecarlo]\n"B.clearance" = { distribution = "uniform", low = 3e-4 }\n',
        [],
        "B.clearance: missing key(s) 'high'",
    ),
    "unknown fit": (
        '[montecarlo.B]\nclearance = { fit = "H7/zz6", diameter = 0.02 }\n',
        [],
        "B.clearance",
    ),
    "unknown parameter": (
        "[montecarlo]\nrodmass = 0.2\n",
        [],
        "unknown parameter 'rodmass'; did you mean 'rod_mass'",
    ),
    "unknown joint": (
        "[montecarlo.C]\nclearance = 3e-4\n",
        [],
        "unknown parameter 'C.clearance'",
    ),
    "joint without clearance": (
        "[montecarlo.A]\nclearance = 3e-4\n",
        [],
        "joint 'A' is an ideal revolute joint and has no clearance",
    ),
    "given twice": (
        '[montecarlo]\n"B.clearance" = 3e-4\n[montecarlo.B]\nclearance = 4e-4\n',
        [],
        "B.clearance is given twice",
    ),
    "no distributions": ("", [], "no distributions"),
    "wall start": (
        "[montecarlo.B]\nclearance = 3e-4\n",
        ["--start", "wall"],
        "'wall' is not supported by montecarlo",
    ),
    "no samples": ("[montecarlo.B]\nclearance = 3e-4\n", ["--samples", "0"], "--samples 0"),
    "zero chunk": ("[montecarlo.B]\nclearance = 3e-4\n", ["--chunk-size", "0"], "--chunk-size"),
    "zero lanes": ("[montecarlo.B]\nclearance = 3e-4\n", ["--lanes", "0"], "--lanes 0"),
    "more devices than cores": (
        "[montecarlo.B]\nclearance = 3e-4\n",
        ["--devices", "100000"],
        "--devices 100000 is more than the",
    ),
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


@pytest.mark.parametrize("case", list(BAD_MONTECARLO))
def test_bad_montecarlo_input(case, tmp_path, capsys):
    table, extra, match = BAD_MONTECARLO[case]
    config = tmp_path / "mc.toml"
    config.write_text(CONFIG + table)
    out = tmp_path / "out"
    argv = ["montecarlo", str(config), "--samples", "4", "--out", str(out), *extra]
    assert_usage_error(capsys, argv, match)
    assert not out.exists(), "bad input must be found before the output folder is made"


BAD_SWEEP = {
    "values and range": (["--values", "1e-4", "--range", "1e-4", "2e-4", "2"], "not allowed with"),
    "neither": ([], "one of the arguments --values --range is required"),
    "unknown parameter": (["--param", "B.clearence", "--values", "1e-4"], "did you mean"),
    "range count": (["--range", "1e-4", "2e-4", "2.5"], "N must be an integer"),
    "not a number": (["--values", "1e-4", "big"], "give numbers"),
    "negative sections": (["--values", "1e-4", "--sections", "-1"], "--sections -1"),
    "empty item": (["--values", "1e-4,,2e-4"], "an empty item between commas"),
    "joint without clearance": (
        ["--param", "A.clearance", "--values", "1e-4"],
        "joint 'A' is an ideal revolute joint and has no clearance",
    ),
    "range of one value": (["--range", "1e-4", "2e-4", "1"], "N = 1 gives START alone"),
    "negative clearance": (
        ["--values=3e-4,-1e-5"],
        "B.clearance = -1e-05 is outside its admissible",
    ),
    "rpm zero": (
        ["--param", "rpm", "--values", "0", "1000"],
        "--param rpm: a value must be positive",
    ),
    "rpm implausible": (["--param", "rpm", "--values", "1e9"], "is implausible"),
}


@pytest.mark.parametrize("case", list(BAD_SWEEP))
def test_bad_sweep_input(case, tmp_path, capsys):
    extra, match = BAD_SWEEP[case]
    out = tmp_path / "out"
    param = [] if "--param" in extra else ["--param", "B.clearance"]
    argv = ["sweep", "--clearance-joints", "B", *param, "--out", str(out), *extra]
    assert_usage_error(capsys, argv, match)
    assert not out.exists()


def test_run_ignores_the_montecarlo_table():
    args = build_parser().parse_args(["run", str(EXAMPLE)])
    settings = resolve_settings(args)
    assert settings.montecarlo == {"B": {"clearance": {"fit": FIT, "diameter": DIAMETER}}}
    assert settings.config["clearance"]["joints"] == "B"


def test_help(capsys):
    for command, words in (
        ("montecarlo", ("--samples", "--seed", "[montecarlo]", "--chunk-size", "--devices")),
        ("sweep", ("--param", "--values", "--range", "--chunk-size")),
    ):
        with pytest.raises(SystemExit) as exc:
            cli.main([command, "--help"])
        assert exc.value.code == 0
        text = capsys.readouterr().out
        for word in words:
            assert word in text, (command, word)


def test_device_count_flag(monkeypatch):
    """Before JAX starts the flag is added to XLA_FLAGS; after (this test process), the variable is
    left alone: it would not change the running backend, only JAX's cache keys."""
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=false")
    assert apply_device_count(5) == NOT_APPLIED
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=false"
    monkeypatch.setattr(jaxclear.cli._ensemble_common, "backend_started", lambda: False)
    monkeypatch.setenv("XLA_FLAGS", f"{DEVICE_COUNT_FLAG}=3")
    assert apply_device_count(8) == "set by XLA_FLAGS"  # the user's own flag wins
    assert os.environ["XLA_FLAGS"] == f"{DEVICE_COUNT_FLAG}=3"
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=false")
    assert apply_device_count(5) == f"{DEVICE_COUNT_FLAG}=5"
    assert os.environ["XLA_FLAGS"].split() == [
        "--xla_cpu_use_fusion_emitters=false",
        f"{DEVICE_COUNT_FLAG}=5",
    ]
    monkeypatch.delenv("XLA_FLAGS")
    assert apply_device_count(None) == f"{DEVICE_COUNT_FLAG}={len(os.sched_getaffinity(0))}"


@pytest.mark.slow
def test_two_cpu_devices_in_a_fresh_process(tmp_path):
    """A fresh process gets --devices 2 as two CPU devices and splits the chunk over them; its
    compiled solves go to the persistent compilation cache (they make no host callbacks, which
    JAX would refuse to store)."""
    env = {
        k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_COMPILATION_CACHE_DIR")
    }
    env["JAXCLEAR_CACHE_DIR"] = str(tmp_path / "cache")
    out = tmp_path / "mc"
    argv = montecarlo_argv(out, "--quiet", samples="4")
    argv[argv.index("--devices") + 1] = "2"
    code = f"import sys; from jaxclear import cli; sys.exit(cli.main({argv!r}))"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600
    )
    assert result.returncode == 0, result.stderr
    info = json.loads((out / "summary.json").read_text())
    assert (info["devices"], info["succeeded"]) == (2, 4)
    assert info["device_flag"] == f"{DEVICE_COUNT_FLAG}=2"
    assert info["compilation_cache"] == env["JAXCLEAR_CACHE_DIR"]
    stored = [p.name for p in (tmp_path / "cache").iterdir()]
    assert any(name.startswith("jit__refill_solve") for name in stored), stored


def test_resume_drops_a_torn_last_row(montecarlo_run, tmp_path, capsys):
    """A crash while the file system wrote samples.csv leaves its last row cut short: resume drops
    it, says so, and solves that member again; the other rows stay as they were."""
    out = tmp_path / "torn"
    shutil.copytree(montecarlo_run, out)
    table = out / "samples.csv"
    text = table.read_text()
    rows = read_rows(table)
    table.write_text(text[: len(text) - len(text.splitlines()[-1]) // 2 - 1])  # mid last row
    with count_compilations() as counts:
        assert cli.main(montecarlo_argv(out)) == 0
    # the member left is solved in the run's chunk shape, by the program the run compiled (with
    # a chunk of its own it compiled one more: 23.7 s against 2.0 s for this test)
    assert counts[COMPILE_EVENT] == 0
    printed = capsys.readouterr().out
    assert "note: " in printed and "last row was cut short" in printed
    assert f"{SAMPLES - 1} of {SAMPLES} members were already finished, 1 left to solve" in printed
    again = read_rows(table)
    assert len(again) == SAMPLES
    assert again[:-1] == rows[:-1]
    assert again[-1]["index"] == rows[-1]["index"] and again[-1]["status"] == "ok"


def test_resume_refuses_a_row_changed_by_hand(montecarlo_run, tmp_path, capsys):
    out = tmp_path / "edited"
    shutil.copytree(montecarlo_run, out)
    table = out / "samples.csv"
    lines = table.read_text().splitlines(keepends=True)
    lines[2] = "x" + lines[2]  # the second member's index is no longer a number
    table.write_text("".join(lines))
    assert_usage_error(capsys, montecarlo_argv(out), "line 3: not a member row")


def test_replay_takes_the_recorded_engine_unless_given(tmp_path):
    """``--member K`` replays with the engine and lanes the ensemble's JSON summary records (the
    same program, so its statistics can equal the row bitwise); options given win; without a
    summary (or one written before the options existed) the defaults."""
    from jaxclear.cli._ensemble_common import _recorded_engine

    def args(engine=None, lanes=None):
        return argparse.Namespace(engine=engine, lanes=lanes)

    assert _recorded_engine(args(), tmp_path, "montecarlo") == {"engine": "refill", "lanes": 8}
    (tmp_path / "summary.json").write_text(json.dumps({"engine": "lockstep", "lanes": 4}))
    (tmp_path / "sweep.json").write_text(json.dumps({"chunk_size": 4}))  # no engine recorded
    assert _recorded_engine(args(), tmp_path, "montecarlo") == {"engine": "lockstep", "lanes": 4}
    assert _recorded_engine(args("refill", 16), tmp_path, "montecarlo") == {
        "engine": "refill",
        "lanes": 16,
    }
    assert _recorded_engine(args(), tmp_path, "sweep") == {"engine": "refill", "lanes": 8}
