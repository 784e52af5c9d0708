"""``run_ensemble`` on refilled lanes (``EnsembleSettings(engine="refill")``, issue 25 part 1):
bad settings name the field; the member table equals the lockstep engine's (``slow``: the two
engines' compilations of a clearance-joint ensemble take ~35 s).

The refilled engine's fast tests share the compiled solves of tests/test_lanes.py (the refilled
ensemble's members against their own ``simulate``, resuming across engines, replaying a member).
"""

import jax
import numpy as np
import pytest
from cases import one_joint_b

import jaxclear
from jaxclear.studies import EnsembleError, EnsembleSettings

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


@pytest.mark.slow  # two compilations of the clearance-joint ensemble (~35 s)
def test_clearance_members_refilled_equal_lockstep():
    """One clearance joint (B) over 2 ms (free flight and the first impacts), five members in
    chunks of four on two lanes: contact modes from the located contacts and the deviations from
    the ideal mechanism (a second refilled solve); one member not admissible, one out of steps."""
    mechanism = one_joint_b()
    values = {
        "B.clearance": np.array([4e-4, 5e-4, 6e-4, -1e-4, 5e-4]),
        "rpm": np.array([5000.0, 4000.0, 6000.0, 5000.0, 5e5]),
    }
    runs = {}
    for engine in ("lockstep", "refill"):
        settings = EnsembleSettings(
            chunk_size=4, devices=jax.local_devices()[:1], progress=False, engine=engine, lanes=2
        )
        runs[engine] = jaxclear.run_ensemble(
            mechanism,
            values,
            2e-3,
            statistics_start=5e-4,
            num_points=41,
            solver=jaxclear.SolverConfig(method="tsit5", max_steps=2000),
            settings=settings,
        )
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
