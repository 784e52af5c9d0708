from jaxclear.cli._common import apply_fast_compile

# XLA reads XLA_FLAGS once, when JAX's backend starts (the first array): set here, before any test
# makes one, in each pytest-xdist worker (and inherited by the command-line tests' subprocesses).
# The CPU fusion emitters off: the suite's time is mostly compilation, and this flag, the
# command's own ``fast_compile`` default, cut it from 1517 s to 729 s on the 2-core machine
# (2026-12-03). A suite-wide JAX persistent compilation cache on top was slower, 977 s: few
# programs repeat across tests, and every compile over a second was written to disk.
# The command's own setter: a user's XLA_FLAGS that already decide the flag are left alone.
apply_fast_compile(True)

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

LONGEST_FIRST = (
    "test_notebooks_studies.py",
    "test_sensitivity.py",
    "test_notebooks.py",
    "test_identify.py",
    "test_transforms.py",
    "test_ensemble.py",
    "test_fast_paths.py",
    "test_optimize.py",
    "test_cli.py",
    "test_executable_cache.py",
    "test_cli_ensemble.py",
    "test_extremes_sampling.py",
    "test_startup.py",
    "test_statistics.py",
    "test_cli_folders.py",
    "test_plot.py",
    "test_force_elements.py",
    "test_imex_affine.py",
    "test_errors.py",
    "test_constraints.py",
    "test_signals.py",
    "test_reference_agreement.py",
    "test_contact_events.py",
    "test_revolutions.py",
    "test_cli_fuzz.py",
    "test_lawson.py",
    "test_contact_laws.py",
    "test_clearance_joint.py",
    "test_wall_start.py",
    "test_lubrication.py",
    "test_lanes.py",
    "test_member_replay.py",
    "test_lyapunov.py",
    "test_gradient_settings.py",
    "test_translational_clearance.py",
    "test_four_bar.py",
)
"""Test files by time taken (mostly compilation), longest first; the others follow in collection
order. ``--dist loadfile`` hands whole files to the two workers in collection order, each worker
taking the next file as it finishes one: longest first keeps one long file from starting last
while the other worker idles. (pytest-xdist's own order, most tests first, started the few-test,
compile-heavy files last.) Update the list when a file's time changes much
(``pytest --durations=0``)."""


def pytest_configure(config):
    if hasattr(config.option, "loadscopereorder"):  # pytest-xdist present
        config.option.loadscopereorder = False  # keep the order set below


def pytest_collection_modifyitems(config, items):
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: files stay whole
