"""``run_ensemble`` on refilled lanes (``EnsembleSettings(engine="refill")``, issue 25 part 1):
bad settings name the field; the member table equals the lockstep engine's (``slow``: the two
engines' compilations of a clearance-joint ensemble take ~35 s).

The refilled engine's fast tests share the compiled solves of tests/test_lanes.py (the refilled
ensemble's members against their own ``simulate``, resuming across engines, replaying a member).
"""

import json
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cases import one_joint_b
from helpers import two_cpu_devices_environment

import jaxclear
from jaxclear.studies import EnsembleError, EnsembleSettings, map_members

STATISTICS_RTOL = 1e-12
"""A refilled member's statistics against the same member solved in lockstep, relative: the two
engines take the same steps, in programs compiled apart (vmapped over members against vmapped
over lanes), which may round differently; measured: 0 (bitwise equal)."""


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("engine", "lanes", "engine must be 'lockstep' or 'refill'"),
        ("engine", "Refill", "engine must be 'lockstep' or 'refill'"),
        ("lanes", 0, "lanes must be a positive integer"),
        ("lanes", 2.5, "lanes must be a positive integer"),
        ("lanes", True, "lanes must be a positive integer"),
    ],
)
def test_bad_engine_settings_name_the_field(field, value, match):
    with pytest.raises(EnsembleError, match=match):
        EnsembleSettings(**{field: value})


def test_whole_lanes_are_accepted():
    assert EnsembleSettings(engine="refill", lanes=np.int64(16)).lanes == 16
    assert EnsembleSettings(lanes=32.0).lanes == 32


VALUES = {
    "B.clearance": [4e-4, 5e-4, 6e-4, -1e-4, 5e-4],
    "rpm": [5000.0, 4000.0, 6000.0, 5000.0, 5e5],
}
"""Five members: one clearance joint (B) over 2 ms (free flight and the first impacts); the fourth
is not admissible, the fifth runs out of steps."""
RUN = dict(statistics_start=5e-4, num_points=41, solver={"method": "tsit5", "max_steps": 2000})


def _run(engine, devices, chunk=4):
    settings = EnsembleSettings(
        chunk_size=chunk, devices=devices, progress=False, engine=engine, lanes=2
    )
    options = dict(RUN, solver=jaxclear.SolverConfig(**RUN["solver"]))
    values = {k: np.asarray(v) for k, v in VALUES.items()}
    return jaxclear.run_ensemble(one_joint_b(), values, 2e-3, settings=settings, **options)


@pytest.fixture(scope="module")
def runs():
    """The five members on one device in chunks of four, by each engine (slow: ~35 s)."""
    return {e: _run(e, jax.local_devices()[:1]) for e in ("lockstep", "refill")}


@pytest.mark.slow  # two compilations of the clearance-joint ensemble (~35 s)
def test_clearance_members_refilled_equal_lockstep(runs):
    """Five members in chunks of four on two lanes: contact modes from the located contacts and
    the deviations from the ideal mechanism (a second refilled solve)."""
    got, lockstep = runs["refill"], runs["lockstep"]
    assert got.messages == lockstep.messages
    assert [s == "ok" for s in got.status] == [True, True, True, False, False]
    np.testing.assert_array_equal(got.num_steps, lockstep.num_steps)
    assert set(got.statistics) == set(lockstep.statistics)
    for name, theirs in lockstep.statistics.items():
        mine = got.statistics[name]
        np.testing.assert_array_equal(np.isnan(mine), np.isnan(theirs), err_msg=name)
        ok = ~np.isnan(theirs)
        np.testing.assert_allclose(mine[ok], theirs[ok], rtol=STATISTICS_RTOL, err_msg=name)
    assert np.all(got.statistics["B_impacts"][:3] >= 1)
    assert np.all(got.statistics["slider_a_deviation"][:3] > 0)


TWO_DEVICES = textwrap.dedent(
    """
    import json, sys
    sys.path.insert(0, sys.argv[1])
    import jax
    import test_refill_engine as t
    r = t._run("refill", None)
    print(json.dumps({"devices": len(jax.devices()), "status": list(r.status),
                      "statistics": {k: v.tolist() for k, v in r.statistics.items()}}))
    """
)


@pytest.mark.slow  # a subprocess compiling both refilled programs (~40 s)
def test_refilled_shares_run_at_once_on_two_devices(runs):
    """Two CPU devices (``XLA_FLAGS``): each chunk's two shares are refilled programs that run at
    once, one from each thread (the clearance mechanism's 7-row and the ideal one's 9-row
    constraint solves are unrolled, so no LAPACK call sits in their loops; with the 9-row solve
    on LAPACK, such programs deadlocked in a Monte Carlo of 256 members). Each member equals its
    solve on one device. The subprocess's timeout ends a hang."""
    env = two_cpu_devices_environment()
    tests = str(Path(__file__).parent)
    done = subprocess.run(
        [sys.executable, "-c", TWO_DEVICES, tests],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["devices"] == 2
    one = runs["refill"]
    assert out["status"] == list(one.status)
    for name, theirs in one.statistics.items():
        np.testing.assert_allclose(
            np.asarray(out["statistics"][name], dtype=float),
            theirs,
            rtol=STATISTICS_RTOL,
            equal_nan=True,
            err_msg=name,
        )


def _doubled(rows, count):
    return rows * 2.0


def test_shares_that_cannot_run_at_once_say_so():
    """A batched function on several devices whose shares must run one after another (the refill
    engine's programs with LAPACK in their loops) warns, naming the way to use every device;
    the results are those of the shares run at once. (Two entries of one CPU device stand in
    for two devices: the split is the same.)"""
    device = jax.local_devices()[0]
    settings = EnsembleSettings(chunk_size=4, devices=[device, device], progress=False)
    rows = np.arange(10.0)[:, None]
    with pytest.warns(UserWarning, match="one after another .* engine='lockstep'"):
        serial = map_members(_doubled, (), rows, settings=settings, batched=True)
    np.testing.assert_array_equal(serial, 2.0 * rows)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning when the shares run at once
        at_once = map_members(_doubled, (), rows, settings=settings, batched=True, concurrent=True)
    np.testing.assert_array_equal(at_once, serial)


def _counted(rows, count):
    return rows * 2.0, jnp.full(rows.shape[0], count)


def test_partial_chunk_splits_evenly_over_devices():
    """A last, partial chunk's members are split evenly over the devices (each device's share
    padded to its shape), so that no device waits on another with more members: 10 rows in
    chunks of 8 on two devices give shares of 4 and 4, then 1 and 1 (not 2 and 0)."""
    device = jax.local_devices()[0]
    settings = EnsembleSettings(chunk_size=8, devices=[device, device], progress=False)
    rows = np.arange(10.0)[:, None]
    doubled, counts = map_members(
        _counted, (), rows, settings=settings, batched=True, concurrent=True
    )
    np.testing.assert_array_equal(doubled, 2.0 * rows)
    np.testing.assert_array_equal(counts, [4] * 8 + [1, 1])
