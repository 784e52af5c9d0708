"""Construction-time value checks shared by the model objects.

Checks run only on concrete values; under ``jit``/``vmap`` (tracers) they are skipped and
value checks fall to the compiled solve's input checks (``Trajectory.input_error``, raised by
``simulate``).
"""

import jax
import numpy as np

from ._errors import ModelError


def is_concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


def check_finite(owner: str, name: str, value) -> None:
    if is_concrete(value) and not np.all(np.isfinite(np.asarray(value))):
        raise ModelError(f"{owner}: {name} must be finite, got {np.asarray(value)}; pass a real number.")


def check_positive(owner: str, name: str, value, unit: str = "") -> None:
    check_finite(owner, name, value)
    if is_concrete(value) and not np.all(np.asarray(value) > 0):
        raise ModelError(
            f"{owner}: {name} must be > 0, got {np.asarray(value)}{(' ' + unit) if unit else ''}; "
            f"pass a positive value in SI units."
        )


def check_shape(owner: str, name: str, value, shape: tuple) -> None:
    if np.shape(value) != shape:
        raise ModelError(f"{owner}: {name} must have shape {shape}, got shape {np.shape(value)}.")


def build_from_registry(registry, kind: str, name: str, params: dict):
    """Instantiate ``registry[name](**params)``; unknown names raise ValueError listing valid ones."""
    try:
        cls = registry[name]
    except KeyError:
        valid = ", ".join(repr(k) for k in registry)
        raise ValueError(f"unknown {kind} {name!r}: use one of {valid}") from None
    return cls(**params)
