"""What every subcommand shares: program name, exit codes, the two error kinds, XLA start-up flags.

Exit codes: 0 success; 1 the simulation failed or results could not be written; 2 bad input
(unknown option or config key, wrong type, malformed TOML, invalid value, mechanism that cannot be
built or assembled, output folder that cannot be written). Errors are one line on stderr:
``jaxclear: error: <what is wrong and how to fix it>``.
"""

import os
from pathlib import Path

from ..internal import set_error_mode

PROG = "jaxclear"
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_NOT_FITTED = 3
"""``jaxclear fit``: the fit did not reach the noise level (its files are written and say why)."""


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


NOT_APPLIED = "not applied: JAX had started (XLA_FLAGS is read once, at its start)"
"""What ``apply_fast_compile`` and ``apply_device_count`` return in a process whose JAX backend had
already started (``jaxclear.cli.main`` called from Python)."""


def backend_started() -> bool:
    """Whether this process's JAX backend has started (XLA has read ``XLA_FLAGS``).

    Read from JAX's private ``xla_bridge.backends_are_initialized`` (no public query exists); if
    that is gone, ``False``, as before this check existed.
    """
    try:
        from jax._src import xla_bridge

        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):  # pragma: no cover - another JAX version
        return False


def apply_fast_compile(on: bool) -> str:
    """Add ``FAST_COMPILE_FLAG`` to the ``XLA_FLAGS`` environment variable if ``on``.

    XLA reads ``XLA_FLAGS`` once, when JAX's backend starts, i.e. when the process makes its first
    array. Importing ``jaxclear`` makes none (``tests/test_cli.py`` checks this in a fresh process),
    so the ``jaxclear`` command, which calls this before any JAX computation, always gets the flag.
    Called through ``jaxclear.cli.main([...])`` from a Python process whose backend has started
    (``backend_started``), the variable is left alone: it would not change the running backend,
    but JAX's compilation cache keys (and jaxclear's store of programs) include it, and programs
    compiled without the flag would be stored under keys that claim it (loading such a program in
    a process that has the flag fails: "Function ... not found").

    Args:
        on: whether the flag is wanted (``[solver] fast_compile``).

    Returns:
        For run.json: ``"on"``, ``"off"``, ``"set by XLA_FLAGS"`` when the user's own ``XLA_FLAGS``
        already decides it, or ``NOT_APPLIED``.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags:
        return "set by XLA_FLAGS"
    if not on:
        return "off"
    if backend_started():
        return NOT_APPLIED
    os.environ["XLA_FLAGS"] = f"{flags} {FAST_COMPILE_FLAG}".strip()
    return "on"


CACHE_DIR_ENV = "JAXCLEAR_CACHE_DIR"
"""Environment variable naming the folder of the command's persistent compilation cache (default
``$XDG_CACHE_HOME/jaxclear/xla``, else ``~/.cache/jaxclear/xla``)."""


def compilation_cache_dir() -> Path:
    """The command's compilation-cache folder (``CACHE_DIR_ENV``, else the user cache folder)."""
    if os.environ.get(CACHE_DIR_ENV):
        return Path(os.environ[CACHE_DIR_ENV]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "jaxclear" / "xla"


def apply_compilation_cache(on: bool) -> str:
    """Turn on JAX's persistent compilation cache for this process (``[solver] compilation_cache``).

    Compiled solves are written to ``compilation_cache_dir()`` and read back by later runs with
    the same mechanism topology, solver settings, output grid, XLA flags and JAX version, which
    then skip XLA's compilation (tracing and lowering remain). JAX does not store executables
    that call back into Python, and the compiled solve has two such calls: diffrax's checks that
    the output times increase and lie in [t0, t1], which hold by construction here (``simulate``
    makes them from t0 and t1). Equinox's runtime checks are therefore switched to NaN mode
    (``EQX_ON_ERROR=nan``: a failed check gives NaN instead of raising) for the command;
    ``restore_error_mode`` undoes it. Failures of the solve itself are data (``Trajectory.result``),
    unaffected. A user's own ``JAX_COMPILATION_CACHE_DIR`` wins over ours.

    The eager solves and assemblies also go to jaxclear's own store of whole compiled programs in
    the same folder (``jaxclear.enable_compilation_cache``): a warm run skips their tracing and
    lowering as well.

    Must run before the process's first compilation: JAX decides once whether to use the cache.

    Returns:
        For run.json: the folder, ``"off"``, or ``"off (...)"`` when the folder cannot be made.
    """
    if not on:
        return "off"
    import jax

    import jaxclear

    user = jax.config.jax_compilation_cache_dir  # pyright: ignore[reportAttributeAccessIssue]
    if user:
        folder = str(user)
    else:
        path = compilation_cache_dir()
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            return f"off (cannot create {str(path)!r}: {e.strerror or e})"
        folder = str(path)
        jax.config.update("jax_compilation_cache_dir", folder)
    # every program, not only those over JAX's default 1 s of compile time: the command's ~50
    # small ones (building the mechanism, outputs, statistics) took ~0.5 s per warm run
    if not _saved_min_compile_time:
        _saved_min_compile_time.append(
            jax.config.jax_persistent_cache_min_compile_time_secs  # pyright: ignore[reportAttributeAccessIssue]
        )
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    _set_error_mode("nan")
    try:
        jaxclear.enable_compilation_cache(folder)  # whole programs too: no tracing when warm
    except OSError as e:
        return f"off (cannot create {folder!r}: {e.strerror or e})"
    return folder


_saved_error_mode: list[str] = []
_saved_min_compile_time: list[float] = []


def _set_error_mode(mode: str) -> None:
    previous = set_error_mode(mode)
    if not _saved_error_mode:
        _saved_error_mode.append(previous)


def restore_error_mode() -> None:
    """Undo ``apply_compilation_cache``'s error mode, executable store and compile-time threshold
    (for ``jaxclear.cli.main`` called in-process; JAX's cache folder stays set: JAX reads it once)."""
    import jaxclear

    jaxclear.disable_compilation_cache()
    if _saved_min_compile_time:
        import jax

        jax.config.update(
            "jax_persistent_cache_min_compile_time_secs", _saved_min_compile_time.pop()
        )
    if _saved_error_mode:
        set_error_mode(_saved_error_mode.pop())
