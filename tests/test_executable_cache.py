"""The on-disk store of compiled programs (``jaxclear.enable_compilation_cache``).

A loaded program must give exactly what a freshly compiled one gives, and a call the key cannot
vouch for (a user's own function, a progress bar's host callback, a changed static setting, an
unreadable entry) must never be served from the store. Entries are loaded here in the same
process after forgetting the in-memory ones; tests/test_cli.py checks a second process.
"""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear.mechanisms import slider_crank

HORIZON = 2e-3  # s: a sixth of a revolution at 5000 rpm
NUM_POINTS = 5


def _mechanism(rpm=5000.0):
    """The ideal benchmark slider–crank: the store's code paths (assembly, initial state, solve
    with extremes) at the smallest compile cost; the clearance joints' solve goes through the same
    code and is stored by tests/test_cli.py's fresh processes."""
    return slider_crank(rpm=rpm)


def _entries(folder):
    return sorted(p.name for p in folder.glob("*.jaxclear"))


def _forget_loaded(folder):
    """Drop the programs held in memory (``enable_compilation_cache`` does), so the next call must
    go to the folder (or compile)."""
    jaxclear.enable_compilation_cache(folder)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """One folder for the file: its tests share entries (each new static setting compiles)."""
    return tmp_path_factory.mktemp("store")


@pytest.fixture
def store(folder):
    """The store on, in the file's folder, with nothing in memory (an in-process CLI test before
    this one, in the same worker, may have loaded the same programs from another folder)."""
    jaxclear.enable_compilation_cache(folder)
    try:
        yield folder
    finally:
        jaxclear.disable_compilation_cache()


def _arrays(traj):
    return [np.asarray(x) for x in jax.tree_util.tree_leaves(traj) if hasattr(x, "shape")]


def test_a_loaded_program_gives_the_same_trajectory(store):
    """Cold call: compiled and stored; after forgetting it in memory, the same call loads its
    programs from the folder (none compiled) and returns bit-identical arrays, as does the same call with the
    store off; new parameter values reuse the entry."""
    cold = jaxclear.simulate(_mechanism(), HORIZON, num_points=NUM_POINTS)
    stored = _entries(store)
    assert any(name.startswith("simulate_core-") for name in stored), stored
    _forget_loaded(store)
    counts = jaxclear.compilation_cache_statistics()
    warm = jaxclear.simulate(_mechanism(), HORIZON, num_points=NUM_POINTS)
    after = jaxclear.compilation_cache_statistics()
    assert after["compiled"] == counts["compiled"], "compiled again instead of loaded"
    assert after["loaded"] == counts["loaded"] + 3  # assembly, initial state, solve
    assert _entries(store) == stored
    for a, b in zip(_arrays(cold), _arrays(warm), strict=True):
        np.testing.assert_array_equal(a, b)
    assert int(warm.num_steps) > 0 and bool(warm.succeeded)
    other = jaxclear.simulate(_mechanism(rpm=4000.0), HORIZON, num_points=NUM_POINTS)
    assert _entries(store) == stored
    assert not np.array_equal(np.asarray(other.q), np.asarray(warm.q))
    jaxclear.disable_compilation_cache()
    plain = jaxclear.simulate(_mechanism(), HORIZON, num_points=NUM_POINTS)
    for a, b in zip(_arrays(cold), _arrays(plain), strict=True):
        np.testing.assert_array_equal(a, b)


def test_an_unreadable_entry_is_compiled_again(store):
    """Garbage in the assembly's entries: compiled again (same result) and rewritten."""
    m = _mechanism()
    first = jaxclear.assemble(m)
    damaged = sorted(store.glob("assembly_diagnostics-*.jaxclear"))
    assert damaged
    for path in damaged:
        path.write_bytes(b"not a program")
    _forget_loaded(store)
    np.testing.assert_array_equal(np.asarray(first), np.asarray(jaxclear.assemble(m)))
    assert all(p.stat().st_size > 1000 for p in damaged)


def _driver_angle(t, parameters):
    return parameters[0] * t


def test_user_code_and_callbacks_are_never_stored(store):
    """A user's driver function is pickled by name only (an edit would not change the key), and a
    progress bar calls back into Python: neither call is stored, both still run."""
    base = _mechanism()
    driven = jaxclear.Mechanism(
        bodies=base.bodies,
        joints=base.joints,
        driver=jaxclear.FunctionDriver(
            "crank", function=_driver_angle, parameters=jnp.array([523.6])
        ),
        gravity=(0.0, 0.0),
    )
    before = _entries(store)
    traj = jaxclear.simulate(driven, HORIZON, num_points=NUM_POINTS, solver="fast")
    assert bool(traj.succeeded)
    assert _entries(store) == before
    jaxclear.simulate(base, HORIZON, num_points=NUM_POINTS, solver="fast", progress=True)
    new = set(_entries(store)) - set(before)
    assert not any(name.startswith("simulate_core-") for name in new), new


def test_transformed_calls_bypass_the_store(store):
    m = _mechanism()
    before = _entries(store)
    y = jax.jit(lambda c: jaxclear.simulate(m, c, num_points=NUM_POINTS, solver="fast").q[-1])(
        HORIZON
    )
    assert np.all(np.isfinite(np.asarray(y)))
    assert _entries(store) == before


ASSEMBLE = """
import sys, jax, numpy as np
jax.config.update("jax_compilation_cache_dir", sys.argv[1])
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
import jaxclear
jaxclear.enable_compilation_cache(sys.argv[1])
y0 = np.asarray(jaxclear.assemble(jaxclear.mechanisms.slider_crank()))
print(repr(y0.tolist()), jaxclear.compilation_cache_statistics()["loaded"])
"""


def _assemble_in_a_fresh_process(folder, package=None):
    """``ASSEMBLE`` in a new Python process with the store (and JAX's cache) in ``folder``; with
    ``package``, importing jaxclear from that folder: (the state's repr, programs loaded)."""
    env = dict(os.environ, PYTHONPATH=str(package)) if package is not None else None
    result = subprocess.run(
        [sys.executable, "-c", ASSEMBLE, str(folder)],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=folder.parent,  # not the checkout: python -c puts the working folder first on the path
    )
    assert result.returncode == 0, result.stderr
    state, loaded = result.stdout.strip().rsplit(" ", 1)
    return state, int(loaded)


def test_beside_jax_persistent_cache(tmp_path):
    """JAX's persistent cache in the same folder (as ``jaxclear run`` sets it up), in fresh
    processes: a program JAX hands back from its cache cannot be serialized again, so the store's
    programs must never come from there. Cold, then with the store's entries deleted (JAX's cache
    kept), then warm: every process gets the same state, the last one from loaded programs."""

    def assemble():
        return _assemble_in_a_fresh_process(tmp_path)

    cold, loaded = assemble()
    assert loaded == 0 and list(tmp_path.glob("*.jaxclear"))
    for path in tmp_path.glob("*.jaxclear"):
        path.unlink()
    again, loaded = assemble()
    assert (again, loaded) == (cold, 0)
    warm, loaded = assemble()
    assert warm == cold and loaded >= 2


def test_an_edit_anywhere_in_the_package_changes_the_key(tmp_path):
    """The key hashes the source of the whole package: after an edit outside ``jaxclear/_core``
    (here a comment appended to ``solve/_extremes.py`` of a copy of the package) a fresh process
    compiles again instead of loading programs of the older code. (The hash had covered
    ``_core`` only, and processes loaded programs built from older code.)"""
    import shutil
    from pathlib import Path

    package = Path(jaxclear.__file__).parent
    copy = tmp_path / "src"
    shutil.copytree(package, copy / "jaxclear", ignore=shutil.ignore_patterns("__pycache__"))
    store = tmp_path / "store"

    def assemble():
        return _assemble_in_a_fresh_process(store, package=copy)[1]

    assert assemble() == 0
    with open(copy / "jaxclear" / "solve" / "_extremes.py", "a", encoding="utf-8") as f:
        f.write("\n# an edit\n")
    # compiled again (that the same source loads: test_beside_jax_persistent_cache)
    assert assemble() == 0
