"""Revolution by revolution: per-revolution statistics, the steady-state verdict, joined solves, and
statistics that do not depend on the output grid (issue: results that hold up)."""

import dataclasses
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxclear import cli
from jaxclear.mechanisms import slider_crank
from jaxclear.solve import combine_extremes, join_trajectories
from jaxclear.studies import compile_revolutions, simulate_revolutions, steady_state

MONTECARLO_EXAMPLE = Path(__file__).parents[1] / "examples" / "montecarlo_h7g6.toml"
IDEAL_TORQUE = (
    138.52  # N m: closed-form extremes of the ideal benchmark at 5000 rpm (test_statistics.py)
)
TORQUE_TOLERANCE = 0.5  # N m: the peak interpolation over Tsit5's steps is within 0.1 N m there


@pytest.fixture(scope="module")
def ideal_run():
    return simulate_revolutions(slider_crank(), 3, points_per_revolution=90, skip=0)


def test_ideal_mechanism_settles_period_one_with_closed_form_extremes(ideal_run):
    """The ideal slider–crank is periodic: the verdict says period-1 and every revolution has the
    closed-form torque extremes."""
    verdict = ideal_run.verdict
    assert verdict.settled and verdict.period == 1 and verdict.label == "period-1"
    assert verdict.distance <= verdict.tolerance
    table = ideal_run.revolution_statistics()
    assert table["crank_torque_min"].shape == (3,)
    np.testing.assert_allclose(table["crank_torque_min"], -IDEAL_TORQUE, atol=TORQUE_TOLERANCE)
    np.testing.assert_allclose(table["crank_torque_max"], IDEAL_TORQUE, atol=TORQUE_TOLERANCE)
    summary = ideal_run.summary()["crank_torque_max"]
    assert summary["min"] <= summary["median"] <= summary["max"]


def test_joined_trajectory_keeps_each_seam_once(ideal_run):
    traj, parts = ideal_run.trajectory, ideal_run.revolutions
    t = np.asarray(traj.t)
    assert t.size == 3 * 90 + 1 and np.all(np.diff(t) > 0)
    period = ideal_run.period
    np.testing.assert_allclose(t[[0, 90, 180, 270]], period * np.arange(4), rtol=1e-12, atol=1e-15)
    assert int(traj.num_steps) == sum(int(p.num_steps) for p in parts)
    # each revolution starts from the last one's final state, exactly
    for before, after in zip(parts, parts[1:]):
        np.testing.assert_array_equal(
            np.asarray(after.q[0]), np.asarray(before.y_final)[: after.q.shape[-1]]
        )
    # the joined extremes cover every revolution: its RMS is the RMS of the per-revolution ones
    rms = ideal_run.revolution_statistics()["crank_torque_rms"]
    x = traj.extremes
    np.testing.assert_allclose(float(x.input_torque_rms), np.sqrt(np.mean(rms**2)), rtol=1e-9)
    assert float(x.duration) == pytest.approx(3 * period, rel=1e-9)


def test_verdict_on_constructed_returns():
    """Period-2 returns settle with k = 2 (not 1); scattered ones are irregular; two revolutions
    are undecided."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=4), rng.normal(size=4)
    transient = [rng.normal(size=4) * 5 for _ in range(3)]
    period_two = np.array(transient + [a, b] * 4) + 1e-6 * rng.normal(size=(11, 4))
    verdict = steady_state(period_two)
    assert verdict.settled and verdict.period == 2 and verdict.settled_from == 3
    chaotic = steady_state(rng.normal(size=(13, 4)))
    assert (
        not chaotic.settled
        and chaotic.label == "irregular"
        and chaotic.distance > chaotic.tolerance
    )
    assert steady_state(rng.normal(size=(3, 4))).label == "undecided"


def test_contact_across_a_seam_is_joined(ideal_run):
    """``combine_extremes`` joins a contact in progress at the end of one solve with the one the
    next solve starts at its first instant."""
    x = ideal_run.revolutions[0].extremes

    def part(onset_open, events, count):
        return dataclasses.replace(
            x,
            contact_onset={"B": jnp.asarray(onset_open)},
            events={"B": jnp.asarray(events, dtype=float)},
            event_count={"B": jnp.asarray(count, dtype=jnp.int32)},
        )

    first = part(0.7, [[0.1, 0.2], [np.nan, np.nan]], 1)  # a contact from 0.7 still going at 1.0
    second = part(np.nan, [[1.0, 1.3], [1.5, 1.6]], 2)  # the next solve starts it at 1.0
    joined = combine_extremes([first, second], [0.0, 1.0])
    expected = [[0.1, 0.2], [0.7, 1.3], [1.5, 1.6]]
    np.testing.assert_array_equal(np.asarray(joined.events["B"]), expected)
    assert int(joined.event_count["B"]) == 3
    assert np.isnan(float(joined.contact_onset["B"]))
    # a buffer that overflowed leaves more contacts than stored, so contact_events refuses
    full = part(np.nan, [[1.0, 1.1], [1.2, 1.3]], 5)
    assert int(combine_extremes([full], [1.0]).event_count["B"]) == 5


def test_statistics_do_not_depend_on_the_output_grid(tmp_path):
    """run.json's statistics, summary and per-revolution rows are bitwise the same for 90 and 2500
    points per revolution (XLA's default CPU code generator; docs/outputs.md)."""
    base = [
        "run",
        "--clearance-joints", "B", "--contact", "lankarani-nikravesh", "--friction", "none",
        "--revolutions", "1", "--skip-revolutions", "0", "--no-plots", "--quiet", "--no-progress",
    ]  # fmt: skip
    infos = []
    for points in (90, 2500):
        out = tmp_path / f"p{points}"
        assert cli.main([*base, "--points-per-revolution", str(points), "--out", str(out)]) == 0
        infos.append(json.loads((out / "run.json").read_text()))
    a, b = infos
    assert a["stats"]["num_steps"] == b["stats"]["num_steps"]
    assert a["statistics"] == b["statistics"]
    assert a["summary"] == b["summary"] and a["revolutions"] == b["revolutions"]
    assert a["steady_state"]["verdict"] == "undecided"


def test_bad_arguments_name_the_parameter():
    with pytest.raises(ValueError, match="revolutions"):
        simulate_revolutions(slider_crank(), 0)
    with pytest.raises(ValueError, match="skip"):
        simulate_revolutions(slider_crank(), 2, skip=2)
    with pytest.raises(ValueError, match="points_per_revolution"):
        simulate_revolutions(slider_crank(), 2, points_per_revolution=1)


def test_join_refuses_nothing():
    with pytest.raises(ValueError, match="at least one"):
        join_trajectories([])


def test_companions_perturbed_at_rounding_level_leave_a_periodic_run_steady():
    """``companions``: K solves in one batch from the initial state perturbed by ~1e-12 relative;
    the ideal (periodic) mechanism's medians do not move, so nothing is marked sensitive.
    ``compile_revolutions`` compiles both solves beforehand: the run then compiles no solve again
    (only kernels of a few ms for joining and statistics; a solve takes seconds)."""
    compile_revolutions(slider_crank(), points_per_revolution=90, companions=2)
    compiles = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            compiles.append(duration)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        run = simulate_revolutions(
            slider_crank(), 2, points_per_revolution=90, skip=0, companions=2
        )
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert not [d for d in compiles if d > 0.5], compiles
    batch = run.companion_revolutions
    assert len(batch) == 2 and np.asarray(batch[0].t_final).shape == (2,)
    start = np.asarray(batch[0].q[:, 0])  # (K, n): the companions' first saved instants
    nominal = np.asarray(run.revolutions[0].q[0])
    relative = np.abs(start - nominal) / np.maximum(np.abs(nominal), 1e-300)
    assert 1e-14 < relative.max() < 1e-10  # perturbed, at the rounding level
    spread = run.spread()
    assert spread and not any(v["sensitive"] for v in spread.values())
    assert spread["crank_torque_max"]["relative_spread"] < 1e-6
    assert len(spread["crank_torque_max"]["companions"]) == 2


def test_negative_spread_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", "--spread", "-1", "--out", str(tmp_path / "o"), "--quiet"])
    assert exc.value.code == 2
    assert "--spread" in capsys.readouterr().err


def test_revolutions_auto_stops_when_settled(tmp_path):
    """``jaxclear run --revolutions auto`` solves until the verdict settles (the ideal mechanism:
    period-1 after two revolutions) and keeps the settled revolutions."""
    out = tmp_path / "auto"
    argv = [
        "run",
        "--clearance-joints",
        "none",
        "--revolutions",
        "auto",
        "--points-per-revolution",
        "90",
    ]
    assert cli.main([*argv, "--no-plots", "--quiet", "--out", str(out)]) == 0
    info = json.loads((out / "run.json").read_text())
    assert info["steady_state"]["verdict"] == "period-1"
    assert info["steady_state"]["revolutions"] == 2 < 12
    assert info["t_end_s"] == pytest.approx(2 * 60 / 5000, rel=1e-9) and info["num_points"] == 181
    assert info["kept_window_s"][0] == pytest.approx(0.0, abs=1e-12)  # settled from revolution 0


def test_revolutions_auto_is_refused_where_a_horizon_is_needed(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(
            ["montecarlo", str(MONTECARLO_EXAMPLE), "--samples", "2", "--revolutions", "auto"]
            + ["--devices", "1", "--out", str(tmp_path / "m"), "--quiet"]
        )
    assert exc.value.code == 2
    assert "auto is for jaxclear run only" in capsys.readouterr().err
