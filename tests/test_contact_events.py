"""Contact modes from located events (``simulate(contact_events=K)``,
``jaxclear.analysis.contact_events`` / ``event_mode_shares``): independent of the output grid."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear.analysis import CONTINUOUS, IMPACT, contact_events, event_mode_shares
from jaxclear.analysis._modes import contact_modes
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
from jaxclear.mechanisms import slider_crank
from jaxclear.solve._extremes import Observation, Tracker


def _observation(delta):
    zero = jnp.zeros(())
    return Observation(
        accelerations=jnp.zeros(1),
        body_accelerations=jnp.zeros(1),
        input_torque=zero,
        normal_force={"B": zero},
        penetration={"B": jnp.asarray(delta, dtype=float)},
        constraint_violation=zero,
    )


def test_onsets_and_ends_are_located_between_samples():
    """δ(t) = sin(2π t) − 0.5 is positive on (1/12, 5/12) + k: contacts of 1/3 s. Sampled at
    irregular instants (as solver steps are) the located crossings are within the linear
    interpolation error of the samples' spacing."""
    rng = np.random.default_rng(0)
    t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 2.0, 400)), [2.0]])
    delta = np.sin(2 * np.pi * t) - 0.5
    x = Tracker.first(0.0, t[0], _observation(delta[0]), max_events=8)
    for ti, di in zip(t[1:], delta[1:]):
        x = x.update(ti, _observation(di))
    x = x.extremes()
    assert int(x.event_count["B"]) == 2
    events = np.asarray(x.events["B"])[:2]
    exact = np.array([[1 / 12, 5 / 12], [13 / 12, 17 / 12]])
    spacing = np.max(np.diff(t))
    # linear interpolation of a smooth crossing: error ≤ h² max|δ''| / (8 |δ'|) at the crossing
    bound = spacing**2 * (2 * np.pi) ** 2 / (8 * 2 * np.pi * np.cos(np.pi / 6))
    np.testing.assert_allclose(events, exact, atol=bound)
    assert np.isnan(float(x.contact_onset["B"]))  # t = 2: free flight
    assert np.all(np.isnan(np.asarray(x.events["B"])[2:]))


def test_overflowing_buffer_is_counted_not_stored():
    x = Tracker.first(0.0, 0.0, _observation(-1.0), max_events=1)
    for k, d in enumerate([1.0, -1.0, 1.0, -1.0, 1.0]):
        x = x.update(float(k + 1), _observation(d))
    x = x.extremes()
    assert int(x.event_count["B"]) == 2
    np.testing.assert_allclose(np.asarray(x.events["B"]), [[0.5, 1.5]])
    assert float(x.contact_onset["B"]) == pytest.approx(4.5)


T1 = 1.5e-3  # s: free flight from the centred start, the first impacts, sliding
FINE = 3001  # output points: 0.5 µs apart
COARSE = 300  # every 300th of them: 150 µs apart, longer than an impact


@pytest.fixture(scope="module")
def first_contacts():
    mech = slider_crank(
        rpm=5000.0,
        clearance_joints="B",
        clearance=4e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(0.01),
        gravity=False,
    )
    return jaxclear.simulate(mech, T1, num_points=FINE, contact_events=64)


def test_events_see_contacts_shorter_than_the_output_interval(first_contacts):
    tr = first_contacts
    period = 60.0 / 5000.0
    e = contact_events(tr)["B"]
    assert np.sum(e["mode"] == IMPACT) >= 2
    assert np.all(e["duration"][e["mode"] == IMPACT] < 0.02 * period)
    t = np.asarray(tr.t)
    delta = np.asarray(tr.clearance["B"]["penetration"])
    # the fine grid resolves every contact: same count, onsets within its spacing
    runs = np.flatnonzero(np.diff((delta > 0).astype(int)) == 1)
    assert len(runs) == len(e["onset"]) - (1 if delta[0] > 0 else 0)
    np.testing.assert_allclose(t[runs + 1], e["onset"][-len(runs) :], atol=t[1] - t[0])
    # the coarse grid misses some of them
    coarse = contact_modes(t[::COARSE], delta[::COARSE], 0.02 * period)
    seen = np.sum(np.diff((coarse > 0).astype(int)) == 1)
    assert seen < len(e["onset"])


def test_event_shares_equal_the_fine_grid(first_contacts):
    tr = first_contacts
    period = 60.0 / 5000.0
    shares = event_mode_shares(tr)
    t = np.asarray(tr.t)
    labels = contact_modes(t, np.asarray(tr.clearance["B"]["penetration"]), 0.02 * period)
    spacing = t[1] - t[0]
    contacts = len(contact_events(tr)["B"]["onset"])
    for mode, name in ((0, "free"), (IMPACT, "impact"), (CONTINUOUS, "continuous")):
        # each contact's two ends can shift a grid share by a sample: 2 samples per contact
        assert shares["joints"]["B"][name] == pytest.approx(
            np.mean(labels == mode), abs=2 * contacts * spacing / T1
        ), name
    assert sum(shares["combinations"].values()) == pytest.approx(1.0)
    assert set(shares["combinations"]) <= {"B:free", "B:impact", "B:continuous"}


def test_without_recorded_events_the_error_says_how():
    tr_like = type("T", (), {"extremes": None})()
    with pytest.raises(ValueError, match="contact_events=K"):
        contact_events(tr_like)


def test_run_writes_located_modes(tmp_path):
    """``jaxclear run`` writes modes.csv (one row per contact, from the located events) and
    run.json shares over the kept window that equal the events' durations."""
    import csv
    import json

    from jaxclear import cli

    out = tmp_path / "run"
    args = "run --clearance-joints B --contact lankarani-nikravesh --friction modified-coulomb"
    args += " --revolutions 0.25 --skip-revolutions 0.05 --no-plots --quiet --out"
    assert cli.main([*args.split(), str(out)]) == 0
    info = json.loads((out / "run.json").read_text())
    with open(out / "modes.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and {r["mode"] for r in rows} <= {"impact", "continuous"}
    assert info["contact_mode_source"].startswith("contact onsets and ends located")
    keep, end = info["kept_window_s"]
    span = end - keep
    for mode in ("impact", "continuous"):
        total = sum(
            min(float(r["end_s"]), end) - max(float(r["onset_s"]), keep)
            for r in rows
            if r["mode"] == mode and float(r["end_s"]) > keep
        )
        assert info["contact_modes"]["B"][mode] == pytest.approx(total / span, abs=1e-9)
    assert sum(info["contact_mode_shares"].values()) == pytest.approx(1.0)
    assert "modes.csv" in info["files"]


def test_mode_timeline_draws_every_located_contact(first_contacts):
    """One tick per impact, one bar per continuous contact, first joint on top, units on the axis."""
    from matplotlib.collections import LineCollection, PolyCollection

    from jaxclear.plot import plot_mode_timeline

    e = contact_events(first_contacts)["B"]
    fig = plot_mode_timeline(first_contacts)
    ax = fig.axes[0]
    ticks = [c for c in ax.collections if isinstance(c, LineCollection)]
    bars = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert sum(len(c.get_segments()) for c in ticks) == np.sum(e["mode"] == IMPACT)
    assert sum(len(c.get_paths()) for c in bars) == np.sum(e["mode"] == CONTINUOUS)
    assert ax.get_xlabel() == "Crank angle (°)"
    assert [t.get_text() for t in ax.get_yticklabels()] == ["joint B"]


def test_grid_contacts_on_a_constructed_signal():
    """The saved-grid fallback (an overflowing event buffer): runs of δ > 0 with known extents;
    ``contact_modes`` labels the same runs."""
    from jaxclear.analysis._modes import grid_contacts

    t = np.arange(20) * 1e-4  # s
    delta = np.full(20, -1e-6)
    delta[2] = delta[8:15] = 1e-6  # one sample (impact), seven samples (continuous)
    runs = grid_contacts(t, delta, minimum_duration=5e-4)
    np.testing.assert_allclose(runs["onset"], [2e-4, 8e-4])
    np.testing.assert_allclose(runs["duration"], [1e-4, 7e-4])
    np.testing.assert_allclose(runs["end"], [3e-4, 15e-4])
    assert list(runs["mode"]) == [IMPACT, CONTINUOUS]
    labels = contact_modes(t, delta, 5e-4)
    assert labels[2] == IMPACT and np.all(labels[8:15] == CONTINUOUS)
    assert np.sum(labels > 0) == 8
