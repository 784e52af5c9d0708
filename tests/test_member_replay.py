"""Replaying one ensemble member (``jaxclear montecarlo/sweep --member K``,
``jaxclear.studies.replay_member``): the member is solved again by the ensemble's own batched
program, so its statistics equal its row bitwise, and it is written as ``jaxclear run`` writes a run.

Every solve uses examples/montecarlo_h7g6.toml (clearance joint B) over a quarter revolution, four
members in one chunk on one device: the Monte Carlo and the sweep share the ensemble's compiled
chunk, and the replays share theirs.
"""

import csv
import json
from pathlib import Path

import pytest

import jaxclear
from jaxclear import cli
from jaxclear.studies import EnsembleError, EnsembleSettings, replay_member

EXAMPLE = Path(__file__).parents[1] / "examples" / "montecarlo_h7g6.toml"
SHORT = [
    "--revolutions", "0.25", "--skip-revolutions", "0.05", "--points-per-revolution", "120",
    "--chunk-size", "4", "--devices", "1", "--no-progress", "--quiet", "--no-plots",
]  # fmt: skip
SAMPLES = 4
MEMBER = 2
BOOKKEEPING = {"index", "num_steps", "wall_time_s", "status", "message"}


def _rows(path):
    with open(path, newline="", encoding="utf-8") as fh:
        return {int(r["index"]): r for r in csv.DictReader(fh)}


def _montecarlo(out, *extra):
    argv = ["montecarlo", str(EXAMPLE), *SHORT, "--samples", str(SAMPLES), "--seed", "1"]
    return cli.main([*argv, "--out", str(out), *extra])


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory):
    out = tmp_path_factory.mktemp("mc")
    assert _montecarlo(out) == 0
    return out, _rows(out / "samples.csv")


@pytest.fixture(scope="module")
def replayed(ensemble):
    out, _ = ensemble
    assert _montecarlo(out, "--member", str(MEMBER)) == 0
    return out / f"member-{MEMBER}"


def test_cli_replay_writes_a_run_equal_to_its_row(ensemble, replayed):
    _, rows = ensemble
    row = rows[MEMBER]
    run = json.loads((replayed / "run.json").read_text(encoding="utf-8"))
    assert run["status"] == "complete"
    for name in ("results.csv", "results.npz", "run.json", "modes.csv"):
        assert (replayed / name).is_file(), name
    # bitwise: the CSV holds repr(float), which reads back to the same double
    assert run["statistics"], "no statistics in run.json"
    for name, value in run["statistics"].items():
        assert repr(float(value)) == row[name], name
    member = run["member"]
    assert member["index"] == MEMBER and member["exact_chunk"] is True
    assert (member["engine"], member["lanes"]) == ("refill", 8)  # the ensemble's, as recorded
    assert member["num_steps"] == int(row["num_steps"])
    for name, value in member["ensemble_statistics"].items():
        assert repr(float(value)) == row[name], name
    assert member["values"]["B.clearance"] == float(row["B.clearance"])
    # the member's own clearance went into the solve that results.csv holds
    with open(replayed / "results.csv", newline="", encoding="utf-8") as fh:
        traj_rows = list(csv.DictReader(fh))
    assert len(traj_rows) == run["num_points"]
    assert max(float(r["B_penetration"]) for r in traj_rows) > 0.0  # it did hit the wall


def test_python_replay_equals_the_row(ensemble, replayed):
    out, rows = ensemble
    settings = jaxclear.cli._config.resolve_settings(
        jaxclear.cli._main.build_parser().parse_args(
            ["montecarlo", str(EXAMPLE), *SHORT, "--samples", "4", "--out", str(out)]
        )
    )
    from jaxclear.cli._mechanism_config import build_mechanism
    from jaxclear.cli._montecarlo import distributions
    from jaxclear.cli._prepare import grid, kept_start, solver_for

    mechanism = build_mechanism(settings)
    values = jaxclear.studies.draw(distributions(settings.montecarlo, mechanism, ""), SAMPLES, 1)
    t1, points = grid(settings)
    steps = [int(rows[i]["num_steps"]) for i in range(SAMPLES)]
    options = dict(
        statistics_start=kept_start(settings),
        num_points=points,
        solver=solver_for(settings, mechanism),
        settings=EnsembleSettings(chunk_size=4, devices=jaxclear.cli._ensemble_common.local_devices(1), progress=False),
    )  # fmt: skip
    for k in (0, MEMBER):
        got = replay_member(mechanism, values, t1, k, num_steps=steps, **options)
        assert got.chunk == sorted(got.chunk) or got.exact_chunk
        assert got.row["num_steps"] == steps[k]
        for name, value in got.statistics.items():
            assert repr(value) == rows[k][name], (k, name)
        assert set(got.statistics) | BOOKKEEPING | set(got.names) == set(rows[k])
        assert got.trajectory.t.shape == (points,)
    with pytest.raises(EnsembleError, match="outside the ensemble"):
        replay_member(mechanism, values, t1, SAMPLES, **options)


def test_cli_sweep_replay_and_bad_member(tmp_path, ensemble):
    values = ["--param", "B.clearance", "--values", "2e-5", "3e-5", "4e-5", "5e-5"]
    argv = ["sweep", str(EXAMPLE), *SHORT, *values, "--out", str(tmp_path)]
    assert cli.main(argv) == 0
    rows = _rows(tmp_path / "sweep.csv")
    assert cli.main([*argv, "--member", "1"]) == 0
    run = json.loads((tmp_path / "member-1" / "run.json").read_text(encoding="utf-8"))
    assert run["member"]["values"] == {"B.clearance": 3e-5}
    for name, value in run["statistics"].items():
        assert repr(float(value)) == rows[1][name], name
    with pytest.raises(SystemExit) as stop:
        cli.main([*argv, "--member", "4"])
    assert stop.value.code == 2
