"""Monte Carlo over manufacturing tolerances and one-parameter sweeps, on the ensemble engine."""

import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._core._errors import EnsembleError
from ..model import Mechanism, parameter_info
from ._distributions import distribution_from_spec
from ._engine import EnsembleSettings
from ._ensemble import run_ensemble
from ._ensemble_result import EnsembleResult


def draw(distributions: Mapping[str, Any], samples: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Draw ``samples`` values of each named parameter, reproducibly.

    Each name gets its own random stream, seeded by ``seed`` and the name (CRC-32), so adding or
    removing one parameter does not change the draws of the others.

    Args:
        distributions: ``{name: distribution}``: an ``AbstractDistribution`` or a config spec
            (``{"distribution": "uniform", "low": ..., "high": ...}``, ``{"fit": "H7/g6",
            "diameter": 0.02}``, a number, ...; see ``distribution_from_spec``).
        samples: number of members (≥ 1).
        seed: the seed (non-negative integer).

    Returns:
        ``{name: (samples,) float64 values}``.
    """
    if int(samples) != samples or samples < 1:
        raise EnsembleError(f"samples must be a positive integer, got {samples!r}.")
    if int(seed) != seed or seed < 0:
        raise EnsembleError(f"seed must be a non-negative integer, got {seed!r}.")
    out = {}
    for name, spec in distributions.items():
        dist = distribution_from_spec(spec, name)
        rng = np.random.default_rng([int(seed), zlib.crc32(name.encode())])
        out[name] = np.asarray(dist.sample(rng, int(samples)), dtype=float)
    return out


def montecarlo(
    mechanism: Mechanism,
    distributions: Mapping[str, Any],
    samples: int,
    t1: float,
    *,
    seed: int = 0,
    settings: EnsembleSettings = EnsembleSettings(),
    description: Mapping[str, Any] | None = None,
    **options,
) -> EnsembleResult:
    """Monte Carlo: members with parameters drawn from distributions, solved by ``run_ensemble``.

    Args:
        mechanism: the nominal mechanism.
        distributions: ``{parameter name: distribution or spec}`` (see ``draw``), e.g.
            ``{"B.clearance": {"fit": "H7/g6", "diameter": 0.02}, "rod_mass": {"distribution":
            "normal", "mean": 0.21, "std": 0.005}}``.
        samples: number of members.
        t1: end time, s.
        seed: the seed of the draws.
        settings: how the members run and where the results go (``EnsembleSettings``: chunk
            size, devices, order, ``out``, table name, progress bar), as in ``run_ensemble``.
        description: more JSON-able configuration a resumed run must match (e.g. the command).
        **options: passed to ``run_ensemble`` (``t0``, ``statistics_start``, ``solver``,
            ``deviation``, ...).

    Returns:
        An ``EnsembleResult`` whose ``names`` are the drawn parameters.
    """
    dists = {n: distribution_from_spec(d, n) for n, d in distributions.items()}
    for n in dists:
        parameter_info(mechanism, n)  # ModelError with the closest valid name
    values = draw(dists, samples, seed)
    info = {
        "kind": "montecarlo",
        "seed": int(seed),
        "samples": int(samples),
        "distributions": {n: d.describe() for n, d in dists.items()},
        **dict(description or {}),
    }
    return run_ensemble(mechanism, values, t1, settings=settings, description=info, **options)


def sweep_values(
    *, values: Sequence[float] | None = None, start=None, stop=None, num: int | None = None
) -> np.ndarray:
    """The values of a sweep: given ``values``, or ``num`` points from ``start`` to ``stop``."""
    if values is not None:
        v = np.asarray(values, dtype=float).ravel()
        if v.size == 0:
            raise EnsembleError("values is empty: give at least one value to sweep.")
    else:
        if start is None or stop is None or num is None:
            raise EnsembleError("give values, or start, stop and num for a range.")
        if int(num) != num or num < 1:
            raise EnsembleError(f"num must be a positive integer, got {num!r}.")
        v = np.linspace(float(start), float(stop), int(num))
    if not np.all(np.isfinite(v)):
        raise EnsembleError(f"sweep values must be finite, got {v.tolist()}.")
    return v


def sweep(
    mechanism: Mechanism,
    name: str,
    values: Sequence[float],
    t1: float,
    *,
    settings: EnsembleSettings = EnsembleSettings(),
    description: Mapping[str, Any] | None = None,
    **options,
) -> EnsembleResult:
    """One parameter over given values, all else nominal: a member per value (``run_ensemble``).

    Args:
        mechanism: the nominal mechanism.
        name: the swept parameter (``jaxclear.parameter_names``), e.g. ``"B.clearance"``, ``"rpm"``.
        values: its values, SI units.
        t1: end time, s.
        settings: how the members run and where the results go (``EnsembleSettings``), as in
            ``run_ensemble``.
        description: more JSON-able configuration a resumed run must match.
        **options: passed to ``run_ensemble``.
    """
    parameter_info(mechanism, name)
    v = sweep_values(values=values)
    info = {"kind": "sweep", "parameter": name, **dict(description or {})}
    return run_ensemble(mechanism, {name: v}, t1, settings=settings, description=info, **options)
