"""Lubricated revolute joints (docs/model.md §3b) wired into the rest: ``jaxclear run`` on the
example TOML (film columns, film plots, run.json), the bad-input paths of the ``lubrication``
table (exit 2, one line naming the key), ``slider_crank(clearance_joints={J: {"lubrication": ...}})``
and the batched evaluation, which must keep joints with different static film options apart.

The film's physics is checked in tests/test_lubrication.py. One simulation here: the example as
written (hybrid contact, LuGre, IMEX) over a quarter revolution; its compilation is the cost of
this file (measured 24-27 s of CPU cold, 1 s with the compilation cache warm; dry laws and the
explicit solver instead saved only ~2.5 s, so the example runs unchanged).
"""

import csv
import json
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear import cli
from jaxclear.contact import LankaraniNikravesh
from jaxclear.dynamics import _clearance as clearance
from jaxclear.dynamics._batched import groups
from jaxclear.dynamics._equations import forces_and_caches
from jaxclear.friction import Coulomb
from jaxclear.mechanisms import slider_crank

EXAMPLE = Path(jaxclear.__file__).parent / "model" / "slider_crank_lubricated.toml"
SHORT = [
    "--revolutions",
    "0.25",
    "--skip-revolutions",
    "0",
    "--points-per-revolution",
    "360",
    "--no-progress",
    "--quiet",
]
"""A quarter revolution from the centred start (as tests/test_cli.py, so the ideal reference run
of the plots shares its compilation): the journal crosses the film and reaches the wall."""
NUM_POINTS = 91
FORCE_RTOL = 1e-12
"""Batched vs one-by-one evaluation: the same arithmetic, up to the order of the sums."""


def _rows(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {name: np.array([float(r[k]) for r in rows[1:]]) for k, name in enumerate(rows[0])}


WALL_TABLE = """[clearance.B]
lubrication = { viscosity = 0.4, length = 0.01, theory = "short", transition_eccentricity = 0.9, transition_width = 0.1 }

"""
"""A film too weak for the load (L = 10 mm), in place of the example's (where the film carries the
load): the quarter revolution crosses the film and reaches the wall."""


@pytest.fixture(scope="module")
def example_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("lubricated")
    text = EXAMPLE.read_text(encoding="utf-8")
    start, end = text.index("[clearance.B]"), text.index("[simulation]")
    config = out.parent / "lubricated_wall.toml"
    config.write_text(text[:start] + WALL_TABLE + text[end:], encoding="utf-8")
    assert cli.main(["run", str(config), *SHORT, "--out", str(out)]) == 0
    return out


def test_example_writes_film_columns(example_run):
    columns = _rows(example_run / "results.csv")
    assert columns["t"].shape == (NUM_POINTS,)
    fx, fy = columns["B_film_force_x"], columns["B_film_force_y"]
    film = np.hypot(fx, fy)
    ratio = np.hypot(columns["B_ecc_x"], columns["B_ecc_y"]) / 5e-4  # [clearance] clearance
    # the film carries the journal inside ε₀ = 0.9 and is gone at the wall (ε₀ + Δ = 1), where the
    # dry law takes over: the two never act at the same saved instant
    inside = (ratio > 0.05) & (ratio < 0.9)
    assert inside.sum() >= 3 and np.all(film[inside] > 0)
    wall = columns["B_penetration"] > 0
    assert wall.sum() >= 3, "the quarter revolution must reach the wall"
    assert np.all(film[wall] == 0) and np.all(columns["B_normal_force"][wall] > 0)
    assert np.all(columns["B_normal_force"][inside] == 0)
    # squeeze: while the journal moves out (ε̇ > 0) the film pushes it back towards the centre
    outward = inside & (columns["B_penetration_rate"] > 0)
    radial = (fx * columns["B_ecc_x"] + fy * columns["B_ecc_y"])[outward]
    assert outward.sum() >= 3 and np.all(radial < 0)
    info = json.loads((example_run / "run.json").read_text())
    assert info["status"] == "complete"
    table = info["clearance_per_joint"]["B"]["lubrication"]
    assert table == {
        "viscosity": 0.4,
        "length": 0.01,
        "theory": "short",
        "transition_eccentricity": 0.9,
        "transition_width": 0.1,
    }
    for axis in "xy":
        assert info["columns"][f"B_film_force_{axis}"]["unit"] == "N"


def test_example_writes_film_plots(example_run):
    info = json.loads((example_run / "run.json").read_text())
    for name in ("film_orbit_B.png", "film_force.png", "orbit_B.png"):
        assert name in info["files"]
        data = (example_run / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, name


LUBRICATED = '[clearance]\njoints = "B"\n[clearance.B]\nlubrication = {{ {} }}\n'
GOOD = "viscosity = 0.4, length = 0.01"
BAD_TABLES = {
    "negative viscosity": (
        LUBRICATED.format("viscosity = -0.4, length = 0.01"),
        "[clearance.B] lubrication viscosity: must be positive, got -0.4",
    ),
    "zero length": (LUBRICATED.format("viscosity = 0.4, length = 0"), "lubrication length"),
    "unknown theory": (
        LUBRICATED.format(f'{GOOD}, theory = "medium"'),
        "lubrication theory: must be one of 'short', 'long'",
    ),
    "transition at the wall": (
        LUBRICATED.format(f"{GOOD}, transition_eccentricity = 1.0"),
        "lubrication transition_eccentricity: must be in (0, 1)",
    ),
    "blend past the wall": (
        LUBRICATED.format(f"{GOOD}, transition_eccentricity = 0.95, transition_width = 0.1"),
        "transition_eccentricity + transition_width must be at most 1",
    ),
    "petroff not a bool": (LUBRICATED.format(f"{GOOD}, petroff = 1"), "lubrication petroff"),
    "misspelt key": (
        LUBRICATED.format("viscosty = 0.4, length = 0.01"),
        "unknown key 'viscosty'; known keys: viscosity, length",
    ),
    "missing length": (LUBRICATED.format("viscosity = 0.4"), "missing key 'length'"),
    "not a table": (
        '[clearance]\njoints = "B"\n[clearance.B]\nlubrication = 0.4\n',
        "[clearance.B] lubrication in '{path}' must be an inline table",
    ),
    "shared table": (
        f"[clearance]\nlubrication = {{ {GOOD} }}\n",
        "unknown key 'lubrication' in [clearance] of '{path}' (it belongs in a per-joint table",
    ),
    "table of a joint left ideal": (
        LUBRICATED.format("viscosity = -0.4, length = 0.01") + "[mechanism]\nrpm = 3000\n",
        "[clearance.B] lubrication viscosity: must be positive",
    ),
}


@pytest.mark.parametrize("case", list(BAD_TABLES))
def test_bad_lubrication_table_exits_2(case, tmp_path, capsys):
    text, match = BAD_TABLES[case]
    config = tmp_path / "bad.toml"
    config.write_text(text)
    argv = ["run", str(config), "--no-progress", "--out", str(tmp_path / "out")]
    if case == "table of a joint left ideal":
        argv += ["--clearance-joints", "none"]  # B stays ideal: its table is checked anyway
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith("jaxclear: error: ") and match.replace("{path}", str(config)) in err, err
    assert not (tmp_path / "out").exists()


# --- batched evaluation -------------------------------------------------------------------------

DRY = dict(contact_law=LankaraniNikravesh(), friction_law=Coulomb())


@eqx.filter_jit
def _forces(mech, q, qd, states):
    """(Q as the equations evaluate it, Q with every clearance joint through its own
    mechanism-level function, the first joint's Q with the second joint's film)."""
    grouped = forces_and_caches(mech, 0.0, q, qd, states)[0]
    m = jnp.stack([b.mass for b in mech.bodies])
    one_by_one = jnp.concatenate(
        [m[:, None] * mech.gravity[None, :], jnp.zeros((len(m), 1))], axis=1
    ).reshape(-1)
    for c in mech.clearance_joints:
        one_by_one = one_by_one + clearance.generalized_force(c, mech.index, q, qd, states[c.name])
    first, second = mech.clearance_joints
    other = eqx.tree_at(lambda c: c.lubrication, first, second.lubrication)
    return (
        grouped,
        one_by_one,
        clearance.generalized_force(first, mech.index, q, qd, states[first.name]),
        clearance.generalized_force(other, mech.index, q, qd, states[first.name]),
    )


def test_lubricated_joints_with_other_theories_are_evaluated_apart():
    """A (long bearing) and B (short) differ only in a static option: evaluated together, B's
    film would be A's (were ``lubrication`` not part of the grouping signature). Films that differ
    in array values only still share one vmapped evaluation."""
    short = jaxclear.Lubrication(0.4, 0.02, theory="short")
    mech = slider_crank(
        clearance_joints={
            "A": {"lubrication": jaxclear.Lubrication(0.4, 0.02, theory="long")},
            "B": {"lubrication": short},
        },
        **DRY,
    )
    assert [tuple(e.name for e in g) for g in groups(mech)] == [("A",), ("B",)]
    other_values = {"lubrication": jaxclear.Lubrication(0.1, 0.03, theory="short")}
    shared = slider_crank(clearance_joints={"A": other_values, "B": {"lubrication": short}}, **DRY)
    assert [tuple(e.name for e in g) for g in groups(shared)] == [("A", "B")]
    dry = slider_crank(clearance_joints={"A": {}, "B": {"lubrication": short}}, **DRY)
    assert [tuple(e.name for e in g) for g in groups(dry)] == [("A",), ("B",)]
    # the ideal joints' pose and speeds, journals moved off-centre (ε ~ 0.3, inside ε₀: the films
    # act), random velocities; no assembly needed for comparing two evaluations of the forces
    rng = np.random.default_rng(26)
    q, qd = (np.asarray(x) for x in mech.initial_guess())
    q = q + 8e-5 * rng.standard_normal(q.shape)
    qd = qd + 0.5 * rng.standard_normal(qd.shape)
    states = 1e-6 * rng.standard_normal(mech.state_size - 2 * q.size)
    grouped, one_by_one, long, short_film = (
        np.asarray(x)
        for x in _forces(mech, *mech.split_state(jnp.asarray(np.concatenate([q, qd, states]))))
    )
    scale = np.max(np.abs(one_by_one))
    np.testing.assert_allclose(grouped, one_by_one, rtol=FORCE_RTOL, atol=FORCE_RTOL * scale)
    # at this state A's film differs between the theories, so the comparison above can fail
    assert np.max(np.abs(long - short_film)) > 0.1 * np.max(np.abs(long)) > 0
