"""Construction-time parameter checks: the one home of the checks made by model objects and laws.

Value checks run only on concrete values; under ``jit``/``vmap`` (tracers) they are skipped and
value checks fall to the compiled solve's input checks (``Trajectory.input_error``, raised by
``simulate``). Every message names the owner, the parameter, the value and a fix.
"""

import os

import jax
import jax.core  # jax.core.Tracer: imported for type checkers (jax imports it itself)
import numpy as np

from ._errors import ModelError


def is_concrete(x) -> bool:
    """False for JAX tracers (values inside ``jit``/``vmap``/``grad``), True otherwise."""
    return not isinstance(x, jax.core.Tracer)


def staging() -> bool:
    """True while a ``jax.jit`` (or another staging transformation) is being traced: operations
    on constants then give tracers too, and nothing can be checked or raised on values."""
    return isinstance(jax.numpy.zeros(()), jax.core.Tracer)


def _fail(owner: str, name: str, requirement: str, value, unit: str, fix: str):
    raise ModelError(
        f"{owner}: {name} must be {requirement}, got {value}{(' ' + unit) if unit else ''}; {fix}."
    )


def check_finite(owner: str, name: str, value, fix: str = "pass a real number") -> None:
    """Raise ``ModelError`` unless the concrete ``value`` is finite (every element)."""
    if is_concrete(value) and not np.all(np.isfinite(np.asarray(value))):
        _fail(owner, name, "finite", np.asarray(value), "", fix)


def check_positive(
    owner: str, name: str, value, unit: str = "", fix: str = "pass a positive value in SI units"
) -> None:
    """Raise ``ModelError`` unless the concrete ``value`` is finite and ``> 0`` (every element)."""
    check_finite(owner, name, value)
    if is_concrete(value) and not np.all(np.asarray(value) > 0):
        _fail(owner, name, "> 0", np.asarray(value), unit, fix)


def check_nonnegative(
    owner: str, name: str, value, unit: str = "", fix: str = "pass a value >= 0 in SI units"
) -> None:
    """Raise ``ModelError`` unless the concrete ``value`` is finite and ``>= 0`` (every element)."""
    check_finite(owner, name, value)
    if is_concrete(value) and not np.all(np.asarray(value) >= 0):
        _fail(owner, name, ">= 0", np.asarray(value), unit, fix)


def check_open_interval(owner: str, name: str, value, lower: float, upper: float, fix: str) -> None:
    """Raise ``ModelError`` unless the concrete ``value`` is finite and in (``lower``, ``upper``)."""
    check_finite(owner, name, value)
    if is_concrete(value) and not np.all((np.asarray(value) > lower) & (np.asarray(value) < upper)):
        _fail(owner, name, f"in ({lower:g}, {upper:g})", np.asarray(value), "", fix)


def check_restitution(owner: str, value, name: str = "restitution") -> None:
    """Raise ``ModelError`` unless the concrete coefficient of restitution is in (0, 1]."""
    if is_concrete(value):
        v = np.asarray(value)
        if not np.all((v > 0) & (v <= 1)):
            _fail(
                owner,
                name,
                "in (0, 1]",
                v,
                "",
                "use 1 for a perfectly elastic contact and e.g. 0.9 for steel on steel",
            )


def check_count(owner: str, name: str, value) -> None:
    """Raise ``ModelError`` unless ``value`` is a Python integer ``>= 1`` (a static count)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        _fail(owner, name, "an integer >= 1", repr(value), "", "pass a positive whole number")


def check_shape(owner: str, name: str, value, shape: tuple) -> None:
    """Raise ``ModelError`` unless ``value`` has ``shape``."""
    if np.shape(value) != shape:
        raise ModelError(f"{owner}: {name} must have shape {shape}, got shape {np.shape(value)}.")


def host_memory() -> int | None:
    """Bytes of physical memory of this machine, or ``None`` where the system does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, OSError, ValueError):
        return None


def check_solve_memory(state_size: int, channels: int, num_saved: int, events: int) -> None:
    """Raise ``ValueError`` if a solve's output buffers cannot fit in this machine's memory.

    XLA does not always report a buffer it cannot allocate: a compiled solve served by the
    program store (``_executable_cache``) waited forever for the result instead (``jaxclear run
    --revolutions 1e9`` asked for a 2 TB contact-event buffer per joint). So ``simulate`` refuses
    such a call before compiling anything. The two buffers counted are lower bounds of what the
    solve holds: the saved states (``num_saved`` x ``state_size`` float64) and the contact-event
    buffer (``channels`` x ``events`` x 2 float64).

    Args:
        state_size: length of the state vector y.
        channels: contact channels whose events are recorded (one per revolute clearance joint,
            three per translational one; the number of clearance joints is a lower bound).
        num_saved: saved instants (``num_points`` or ``len(ts)``).
        events: ``contact_events`` (0: none recorded).
    """
    memory = host_memory()
    if memory is None:
        return
    saved = 8 * max(num_saved, 0) * state_size
    buffer = 16 * max(events, 0) * channels
    if saved + buffer <= memory:
        return
    parts, fixes = [], []
    if saved >= 0.1 * (saved + buffer):
        parts.append(f"{saved / 1e9:.3g} GB for {num_saved} saved instants of {state_size} values")
        fixes.append("save fewer instants (num_points or ts; or split the window)")
    if buffer >= 0.1 * (saved + buffer):
        parts.append(
            f"{buffer / 1e9:.3g} GB for contact_events={events} on {channels} contact channels"
        )
        most = memory // (16 * channels)
        fixes.append(f"record fewer contact events (this memory holds at most {most} per channel)")
    raise ValueError(
        f"the solve needs at least {' and '.join(parts)}, more than this machine's "
        f"{memory / 1e9:.3g} GB of memory; {', or '.join(fixes)}."
    )
