"""Entry point of the ``jaxclear`` command: the parser, one subcommand per file, error handling.

Exit codes: 0 success; 1 the simulation failed or results could not be written; 2 bad input.
Every error is one line on stderr, ``jaxclear: error: <what is wrong and how to fix it>``; an
unexpected exception too (``JAXCLEAR_TRACEBACK=1`` shows its traceback).
"""

import argparse
import difflib
import os
import sys
from typing import NoReturn

from . import _fit, _montecarlo, _run, _sweep
from ._common import (
    EXIT_FAILURE,
    EXIT_USAGE,
    PROG,
    RunError,
    UsageError,
    one_line,
    restore_error_mode,
)
from ._ensemble_common import ENSEMBLE_FLAGS
from ._settings import all_flags

SUBCOMMANDS = {"run": _run, "fit": _fit, "montecarlo": _montecarlo, "sweep": _sweep}
"""Subcommand name -> module with ``add_parser(subparsers, parser_class)`` and ``run(args, argv)``."""
ENSEMBLE_OPTIONS = ("--samples", "--seed", "--param", "--values", "--range")
"""Options of ``montecarlo`` and ``sweep`` (for 'did you mean' hints)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line and exit code 2."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def _usage_hint(message: str, argv: list[str]) -> str:
    """Add close matches of mistyped options and where to find help."""
    prefix = "unrecognized arguments: "
    if message.startswith(prefix):
        flags = [*all_flags(), *ENSEMBLE_FLAGS, *ENSEMBLE_OPTIONS, "--help"]
        guesses = []
        for token in message[len(prefix) :].split():
            match = difflib.get_close_matches(token.split("=")[0], flags, n=1, cutoff=0.75)
            if token.startswith("--") and match:
                guesses.append(f"did you mean {match[0]} for {token}?")
        message = "; ".join([message, *guesses])
    command = next((a for a in argv if a in SUBCOMMANDS), None)
    where = f"jaxclear {command} --help" if command else "jaxclear --help"
    return f"{message} (see '{where}')"


def build_parser() -> argparse.ArgumentParser:
    """The ``jaxclear`` argument parser with every subcommand."""
    from .. import __version__

    parser = _Parser(
        prog=PROG,
        allow_abbrev=False,
        description="Simulate planar mechanisms with revolute clearance joints (jaxclear).",
        epilog="Run 'jaxclear run --help' for the options and config-file keys.",
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(
        dest="command", metavar="COMMAND", required=True, parser_class=_Parser
    )
    for module in SUBCOMMANDS.values():
        module.add_parser(sub, _Parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxclear`` command.

    Args:
        argv: arguments without the program name (default ``sys.argv[1:]``).

    Returns:
        0 on success.

    Raises:
        SystemExit: 2 for bad input, 1 for a failed run, 130 when interrupted; the message is one
            line on stderr.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        try:
            args = build_parser().parse_args(argv)
        except UsageError as e:
            raise UsageError(_usage_hint(str(e), argv)) from None
        try:
            return SUBCOMMANDS[args.command].run(args, argv)
        finally:
            restore_error_mode()
    except UsageError as e:
        _fail(str(e), EXIT_USAGE)
    except RunError as e:
        _fail(str(e), EXIT_FAILURE)
    except KeyboardInterrupt:
        _fail("interrupted", 130)
    except Exception as e:  # one line for anything unexpected; JAXCLEAR_TRACEBACK=1 shows it all
        if os.environ.get("JAXCLEAR_TRACEBACK"):
            raise
        _fail(
            f"{type(e).__name__}: {one_line(e)} (set JAXCLEAR_TRACEBACK=1 for the traceback)",
            EXIT_FAILURE,
        )


def _fail(message: str, code: int) -> NoReturn:
    print(f"{PROG}: error: {' '.join(message.split())}", file=sys.stderr)
    raise SystemExit(code)
