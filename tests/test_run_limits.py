"""Values that once made ``jaxclear run`` hang: refused before anything is solved.

``--revolutions=1e9`` (an example of ``test_cli_fuzz.py::test_run_option_values``) passed every
check and sized the contact-event buffer of every revolution for the whole horizon (now per revolution): 1.28e11 events per joint, a 2 TB
allocation that XLA, running the program from jaxclear's compiled-program store, never reported:
the command waited in ``block_until_ready`` forever. The command line now bounds the horizon, the
saved instants and ``max_steps`` (exit 2), and ``simulate`` refuses output buffers larger than the
machine's memory before compiling (``ValueError``). Nothing here solves: the commands are stopped
at their first ``simulate`` call, and ``simulate`` refuses before compiling.
"""

from pathlib import Path

import pytest

import jaxclear
from jaxclear import cli, mechanisms


class Solved(BaseException):  # not an Exception: the command line catches those
    """The command accepted its input and got as far as solving."""


@pytest.fixture
def no_solve(monkeypatch):
    def stop(*args, **kwargs):
        raise Solved

    monkeypatch.setattr(jaxclear, "simulate", stop)


def refused(argv: list[str], out: Path, capsys) -> str:
    """Run ``argv``; assert exit 2 with one ``jaxclear: error:`` line and no output; return it."""
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("jaxclear: error: "), err
    assert not out.exists()
    return lines[0]


@pytest.mark.parametrize("value", ["1e9", "1001", "1e300"])
def test_horizon_beyond_the_bound_is_refused(value, tmp_path, capsys, no_solve):
    line = refused(["run", f"--revolutions={value}"], tmp_path / "out", capsys)
    assert "--revolutions" in line and "at most 1000" in line


def test_horizon_at_the_bound_goes_on_to_solve(tmp_path, no_solve):
    with pytest.raises(Solved):
        cli.main(["run", "--revolutions=1000", "--quiet", "--out", str(tmp_path / "out")])


def test_horizon_in_a_config_file_is_refused(tmp_path, capsys, no_solve):
    config = tmp_path / "long.toml"
    config.write_text("[simulation]\nrevolutions = 1e9\n", encoding="utf-8")
    line = refused(["run", str(config)], tmp_path / "out", capsys)
    assert "[simulation] revolutions" in line and "at most 1000" in line


@pytest.mark.parametrize(
    "argv",
    [
        ["--points-per-revolution=1000000000"],  # revolutions auto: at most 12
        ["--revolutions=1000", "--points-per-revolution=1001"],
    ],
)
def test_saved_instants_beyond_the_bound_are_refused(argv, tmp_path, capsys, no_solve):
    line = refused(["run", *argv], tmp_path / "out", capsys)
    assert "--points-per-revolution" in line and "1000000" in line


def test_max_steps_beyond_the_bound_is_refused(tmp_path, capsys, no_solve):
    # 1e20 does not even fit an int64: it failed inside the compiled call with an OverflowError
    line = refused(["run", "--max-steps=100000000000000000000"], tmp_path / "out", capsys)
    assert "--max-steps" in line and "at most 1000000000" in line


@pytest.mark.parametrize("value", ["1e-320", "0.005"])
def test_speed_below_the_bound_is_refused(value, tmp_path, capsys, no_solve):
    # a subnormal speed made the revolution's duration infinite: "t1 must be finite", exit 1
    line = refused(["run", f"--rpm={value}"], tmp_path / "out", capsys)
    assert "--rpm" in line and "at least 0.01" in line


def test_speed_at_the_bound_goes_on_to_solve(tmp_path, no_solve):
    with pytest.raises(Solved):
        cli.main(["run", "--rpm=0.01", "--quiet", "--out", str(tmp_path / "out")])


@pytest.mark.parametrize("value", ["65", "-1"])
def test_spread_outside_its_range_is_refused(value, tmp_path, capsys, no_solve):
    line = refused(["run", f"--spread={value}"], tmp_path / "out", capsys)
    assert "--spread" in line and "to 64" in line


@pytest.fixture(scope="module")
def three_joints():
    return mechanisms.slider_crank(clearance_joints=("O", "A", "B"))


def test_simulate_refuses_an_event_buffer_larger_than_memory(three_joints):
    # what run asked for with --revolutions=1e9: 128 events per revolution and joint
    with pytest.raises(ValueError, match=r"contact_events=128000000000 on 3 contact channels"):
        jaxclear.simulate(three_joints, 1e-4, num_points=2, contact_events=128 * 10**9)


def test_simulate_refuses_a_grid_larger_than_memory(three_joints):
    size = three_joints.state_size
    with pytest.raises(ValueError, match=rf"100000000000 saved instants of {size} values"):
        jaxclear.simulate(three_joints, 1e-4, num_points=10**11)
