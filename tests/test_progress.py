"""Progress of long studies: timed lines in a log file, a count that never overruns its total."""

import io

from jaxclear._core._progress import Progress


class _Clock:
    """Stands in for time.monotonic: advances only when told."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_lines_in_a_log_file_every_interval(monkeypatch):
    import ipykernel  # noqa: F401  # a Jupyter kernel's modules loaded (as by the notebook tests) is no kernel

    clock = _Clock()
    monkeypatch.setattr("jaxclear._core._progress.time.monotonic", clock)
    log = io.StringIO()  # not a terminal
    bar = Progress(True, 10, "fit", stream=log, interval=5.0)
    bar.update(3)
    assert log.getvalue() == "", "a line before the interval has passed"
    clock.now += 6.0
    bar.update(1)
    assert log.getvalue() == "fit: 4/10 solves (40 %), 6 s\n"
    clock.now += 1.0
    bar.update(1)
    assert log.getvalue().count("\n") == 1, "lines closer than the interval"
    clock.now += 2.0
    bar.close()
    assert log.getvalue().splitlines()[-1] == "fit: 5/10 solves (50 %), 9 s"
    bar.close()
    assert log.getvalue().count("\n") == 2, "close twice writes twice"


def test_count_never_overruns_the_total():
    log = io.StringIO()
    bar = Progress(True, 4, "members", stream=log, interval=0.0)
    bar.update(3)
    bar.update(5)
    bar.update(1)
    assert bar.count == 4
    bar.close()
    assert all("/4 solves" in line for line in log.getvalue().splitlines())
    assert "5/4" not in log.getvalue() and "8/4" not in log.getvalue()


def test_off_writes_nothing():
    log = io.StringIO()
    bar = Progress(False, 4, "fit", stream=log, interval=0.0)
    bar.update(2)
    bar.close()
    assert log.getvalue() == "" and bar.count == 2
