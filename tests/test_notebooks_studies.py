"""The study notebooks (01-05) end to end in quick mode; full runs are `slow` (see
``test_notebooks.py``, which runs the others)."""

import pytest
from test_notebooks import STUDIES, run_notebook


@pytest.mark.parametrize("path", STUDIES, ids=[p.stem for p in STUDIES])
def test_study_notebook_quick(path):
    run_notebook(path, quick=True)


@pytest.mark.slow
@pytest.mark.parametrize("path", STUDIES, ids=[p.stem for p in STUDIES])
def test_study_notebook_full(path):
    run_notebook(path, quick=False)
