"""Run every notebook end to end in quick mode (JAXCLEAR_QUICK=1); full runs are `slow`."""

import os
import pathlib

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((pathlib.Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))
TIMEOUT = 600  # s per cell: compiles dominate


def _run(path, quick):
    nb = nbformat.read(path, as_version=4)
    os.environ["JAXCLEAR_QUICK"] = "1" if quick else "0"
    try:
        NotebookClient(
            nb,
            timeout=TIMEOUT,
            kernel_name="python3",
            resources={"metadata": {"path": str(path.parent)}},
        ).execute()
    finally:
        os.environ.pop("JAXCLEAR_QUICK", None)
    return nb


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_quick(path):
    _run(path, quick=True)


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_full(path):
    _run(path, quick=False)
