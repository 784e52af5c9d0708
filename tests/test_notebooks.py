"""Run the notebooks end to end in quick mode (JAXCLEAR_QUICK=1); full runs are `slow`.

The notebooks are split between this file (the workflow notebooks, 06 onwards) and
``test_notebooks_studies.py`` (the studies 01-05, ``STUDIES``) so that ``--dist loadfile`` hands
them to both workers."""

import os
import pathlib

import nbformat
import pytest
from nbclient import NotebookClient

from jaxclear.cli._common import FAST_COMPILE_FLAG

ALL_NOTEBOOKS = sorted((pathlib.Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))
STUDIES = [p for p in ALL_NOTEBOOKS if p.stem[:2] in ("01", "02", "03", "04", "05")]
NOTEBOOKS = [p for p in ALL_NOTEBOOKS if p not in STUDIES]
TIMEOUT = 600  # s per cell: compiles dominate


def _kernel_environment(quick):
    """Environment the kernel inherits: quick mode, and in quick mode XLA's faster CPU compilation
    (the ``jaxclear`` command's ``--fast-compile``, ``[solver] fast_compile``): the quick runs are dominated by
    compilation, and they check that the notebooks run, not their figures."""
    env = {"JAXCLEAR_QUICK": "1" if quick else "0"}
    flags = os.environ.get("XLA_FLAGS", "")
    if quick and "xla_cpu_use_fusion_emitters" not in flags:
        env["XLA_FLAGS"] = f"{flags} {FAST_COMPILE_FLAG}".strip()
    return env


def run_notebook(path, quick):
    nb = nbformat.read(path, as_version=4)
    env = _kernel_environment(quick)
    saved = {name: os.environ.get(name) for name in env}
    os.environ.update(env)
    try:
        NotebookClient(
            nb,
            timeout=TIMEOUT,
            kernel_name="python3",
            resources={"metadata": {"path": str(path.parent)}},
        ).execute()
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
    return nb


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_quick(path):
    run_notebook(path, quick=True)


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_full(path):
    run_notebook(path, quick=False)
