"""What every subcommand shares: program name, exit codes, the two error kinds, XLA start-up flags.

Exit codes: 0 success; 1 the simulation failed or results could not be written; 2 bad input
(unknown option or config key, wrong type, malformed TOML, invalid value, mechanism that cannot be
built or assembled, output folder that cannot be written). Errors are one line on stderr:
``jaxclear: error: <what is wrong and how to fix it>``.
"""

import os

PROG = "jaxclear"
EXIT_FAILURE = 1
EXIT_USAGE = 2


class UsageError(Exception):
    """Bad input: reported as one line, exit code 2, before any solve."""


class RunError(Exception):
    """The run failed: reported as one line, exit code 1."""


def one_line(error: BaseException) -> str:
    """The message of ``error`` on one line (its type name if it has none)."""
    text = " ".join(str(error).split())
    return text or type(error).__name__


FAST_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"
"""XLA flag that turns the CPU fusion emitters off: measured 5.4 -> 2.2 s XLA time for about a tenth
longer runs (Tsit5, three clearance joints; see the ``fast_compile`` setting)."""


def apply_fast_compile(on: bool) -> str:
    """Add ``FAST_COMPILE_FLAG`` to the ``XLA_FLAGS`` environment variable if ``on``.

    XLA reads ``XLA_FLAGS`` once, when JAX's backend starts, i.e. when the process makes its first
    array. Importing ``jaxclear`` makes none (``tests/test_cli.py`` checks this in a fresh process),
    so the ``jaxclear`` command, which calls this before any JAX computation, always gets the flag.
    JAX has no public query for "has the backend started", so this function does not guess: called
    through ``jaxclear.cli.main([...])`` from a Python process that already ran JAX computations,
    the variable is still set but has no effect on that process.

    Args:
        on: whether the flag is wanted (``[solver] fast_compile``).

    Returns:
        For run.json: ``"on"``, ``"off"``, or ``"set by XLA_FLAGS"`` when the user's own ``XLA_FLAGS``
        already decides it.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags:
        return "set by XLA_FLAGS"
    if not on:
        return "off"
    os.environ["XLA_FLAGS"] = f"{flags} {FAST_COMPILE_FLAG}".strip()
    return "on"
