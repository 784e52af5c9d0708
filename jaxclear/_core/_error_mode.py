"""How equinox's runtime checks (``eqx.error_if``) behave in programs jaxclear traces.

A raising check is a host callback, and a program with a host callback cannot be serialized:
neither jaxclear's store of compiled programs nor JAX's persistent compilation cache keeps it.
The only such checks in a solve are diffrax's on the output times, which ``simulate`` has already
checked on the host; so programs meant to be kept are traced with the checks in NaN mode.

Equinox reads the mode from the ``EQX_ON_ERROR`` environment variable once, when it is imported,
and has no public setter; jaxclear runs inside processes that imported equinox long before. This
module is therefore the one place in jaxclear that changes the value equinox reads at trace time
(``equinox._errors.EQX_ON_ERROR``), always restoring it. A user who wants NaN mode everywhere sets
``EQX_ON_ERROR=nan`` before starting Python, as equinox documents.
"""

import contextlib
from collections.abc import Iterator


def _module():
    import equinox._errors as errors  # the module global equinox reads at trace time

    return errors


def error_mode() -> str:
    """The mode equinox's checks are traced in now (``"raise"``, ``"nan"``, ...)."""
    return getattr(_module(), "EQX_ON_ERROR")


def set_error_mode(mode: str) -> str:
    """Trace equinox's checks in ``mode`` from now on; returns the mode it replaces."""
    if mode not in ("raise", "nan", "breakpoint", "off"):
        raise ValueError(f"mode must be 'raise', 'nan', 'breakpoint' or 'off', got {mode!r}.")
    previous = error_mode()
    setattr(_module(), "EQX_ON_ERROR", mode)
    return previous


@contextlib.contextmanager
def error_mode_set(mode: str) -> Iterator[None]:
    """Trace equinox's checks in ``mode`` inside the block, and restore the mode after it."""
    previous = set_error_mode(mode)
    try:
        yield
    finally:
        set_error_mode(previous)
