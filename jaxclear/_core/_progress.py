"""Progress of long studies: a tqdm bar in a terminal or notebook, timed lines in a log file."""

import sys
import time

LINE_INTERVAL = 5.0
"""Seconds between progress lines when the output is not a terminal (a log file, a pipe)."""


class Progress:
    """Counts finished evaluations out of ``total`` and shows them.

    In a terminal or a notebook it drives a tqdm bar; when the stream is a file or a pipe (a batch
    job's log) it writes a line such as ``fit: 12/108 solves (11 %), 35 s`` at most every
    ``interval`` seconds, and a last line on ``close``. The count never exceeds ``total``: updates
    past it are dropped, so a bar never overruns its own total.

    Args:
        on: show anything at all (``False``: every call is a no-op).
        total: number of evaluations expected (> 0).
        description: prefix of the bar or line, e.g. ``"fit"``.
        stream: where to write (default ``sys.stderr``).
        interval: seconds between lines when ``stream`` is not a terminal.
    """

    def __init__(
        self,
        on: bool,
        total: int,
        description: str,
        *,
        stream=None,
        interval: float = LINE_INTERVAL,
    ):
        self.total = max(int(total), 0)
        self.count = 0
        self.description = description
        self.stream = sys.stderr if stream is None else stream
        self.interval = interval
        self._start = time.monotonic()
        self._last_line = self._start
        self._closed = not on
        self._bar = None
        self._lines = False
        if not on:
            return
        if _interactive(self.stream):
            from tqdm.auto import tqdm

            self._bar = tqdm(total=self.total, desc=description, unit="solve", file=self.stream)
        else:
            self._lines = True

    def update(self, n: int = 1) -> None:
        """Count ``n`` more finished evaluations (clamped to the total)."""
        n = max(0, min(int(n), self.total - self.count))
        self.count += n
        if self._closed or n == 0:
            return
        if self._bar is not None:
            self._bar.update(n)
        elif self._lines and time.monotonic() - self._last_line >= self.interval:
            self._write_line()

    def close(self) -> None:
        """Finish the bar, or write the last line."""
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
        elif self._lines:
            self._write_line()

    def _write_line(self) -> None:
        self._last_line = time.monotonic()
        share = f" ({100 * self.count / self.total:.0f} %)" if self.total else ""
        elapsed = self._last_line - self._start
        self.stream.write(
            f"{self.description}: {self.count}/{self.total} solves{share}, {elapsed:.0f} s\n"
        )
        self.stream.flush()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _interactive(stream) -> bool:
    """A terminal, or the standard error of a Jupyter kernel (where tqdm.auto draws a widget)."""
    isatty = getattr(stream, "isatty", None)
    try:
        if isatty and isatty():
            return True
    except ValueError:  # a closed stream
        return False
    return stream is sys.stderr and _in_notebook()


def _in_notebook() -> bool:
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    return type(shell).__name__ == "ZMQInteractiveShell"


def progress_bar(on: bool, total: int, description: str) -> Progress:
    """A ``Progress`` over ``total`` evaluations (no-op when not ``on``)."""
    return Progress(on, total, description)
