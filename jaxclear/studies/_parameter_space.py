"""Bounded parameters for fits and design optimisation: specs, transforms, scan points.

A fitted or designed parameter is a named mechanism parameter (``jaxclear.parameter_names``) with
an initial value and an open interval (lower, upper). Optimisers work on an unconstrained
variable u with θ = T(u), so every iterate is admissible:

- finite lower and upper: θ = lower + (upper − lower) · sigmoid(u) (logistic);
- finite lower only: θ = lower + exp(u) (log-space, for positive quantities);
- finite upper only: θ = upper − exp(u);
- neither: θ = initial + scale · u with scale = |initial| (or 1 if initial is 0).
"""

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core._errors import ModelError
from ..model import Mechanism, get_parameter, parameter_info

DEFAULT_SPAN = 4.0
"""Bounds of a positive parameter given without bounds: [initial / 4, initial · 4] (clipped to its
admissible interval). Wide enough for a clearance started 0.5 mm when the truth is 0.2 mm."""

INTERIOR = 1e-3
"""An admissible interval (a, b) given by the parameter's nature (restitution in (0, 1)) is used
as [a + 1e-3 (b − a), b − 1e-3 (b − a)], so the transform stays finite."""


@dataclasses.dataclass(frozen=True)
class FitParameter:
    """A parameter to fit or design.

    Attributes:
        name: dotted mechanism parameter name (``B.clearance``, ``rod_mass``, ...).
        initial: starting value (SI units).
        lower, upper: bounds (``-inf``/``inf`` for none); ``lower < initial < upper``.
        unit: SI unit (from ``jaxclear.parameter_info``).
    """

    name: str
    initial: float
    lower: float
    upper: float
    unit: str = ""

    def to_unconstrained(self, value) -> Any:
        """u from θ (NumPy or JAX)."""
        lo, hi = self.lower, self.upper
        x = jnp.asarray(value, dtype=float)
        if math.isfinite(lo) and math.isfinite(hi):
            p = (x - lo) / (hi - lo)
            return jnp.log(p) - jnp.log1p(-p)
        if math.isfinite(lo):
            return jnp.log(x - lo)
        if math.isfinite(hi):
            return jnp.log(hi - x)
        return (x - self.initial) / self._scale

    def from_unconstrained(self, u) -> Any:
        """θ from u (traceable)."""
        lo, hi = self.lower, self.upper
        if math.isfinite(lo) and math.isfinite(hi):
            return lo + (hi - lo) * jax.nn.sigmoid(u)
        if math.isfinite(lo):
            return lo + jnp.exp(u)
        if math.isfinite(hi):
            return hi - jnp.exp(u)
        return self.initial + self._scale * u

    @property
    def _scale(self) -> float:
        return abs(self.initial) if self.initial != 0 else 1.0

    def as_dict(self) -> dict[str, Any]:
        return {
            "initial": self.initial,
            "lower": self.lower,
            "upper": self.upper,
            "unit": self.unit,
        }


class ParameterSpace(eqx.Module):
    """The transforms of several ``FitParameter``s as one traceable map u -> {name: θ}.

    Names and transform kinds are static; bounds and initial values are arrays, so one compiled
    fit or design serves any bounds and starting values.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    kinds: tuple[str, ...] = eqx.field(static=True)
    lower: Float[Array, " p"]
    upper: Float[Array, " p"]
    initial: Float[Array, " p"]
    scale: Float[Array, " p"]

    @classmethod
    def of(cls, specs: Sequence[FitParameter]) -> "ParameterSpace":
        kinds = []
        for q in specs:
            lo, hi = math.isfinite(q.lower), math.isfinite(q.upper)
            kinds.append("interval" if lo and hi else "lower" if lo else "upper" if hi else "free")

        def finite(values):
            return jnp.asarray([v if math.isfinite(v) else 0.0 for v in values], dtype=float)

        return cls(
            names=tuple(q.name for q in specs),
            kinds=tuple(kinds),
            lower=finite([q.lower for q in specs]),
            upper=finite([q.upper for q in specs]),
            initial=jnp.asarray([q.initial for q in specs], dtype=float),
            scale=jnp.asarray([q._scale for q in specs], dtype=float),
        )

    def values(self, u) -> dict[str, Any]:
        """{name: θ} from the unconstrained vector u (p,) (traceable)."""
        out = {}
        for k, (name, kind) in enumerate(zip(self.names, self.kinds, strict=True)):
            lo, hi = self.lower[k], self.upper[k]
            if kind == "interval":
                out[name] = lo + (hi - lo) * jax.nn.sigmoid(u[k])
            elif kind == "lower":
                out[name] = lo + jnp.exp(u[k])
            elif kind == "upper":
                out[name] = hi - jnp.exp(u[k])
            else:
                out[name] = self.initial[k] + self.scale[k] * u[k]
        return out


def parse_parameters(
    mechanism: Mechanism, parameters: "Mapping[str, Any] | Sequence[str | FitParameter]"
) -> list[FitParameter]:
    """``FitParameter``s from a user's spec.

    Args:
        mechanism: gives the names, units, admissible intervals and default initial values.
        parameters: a sequence of names or ``FitParameter``s, or a mapping ``{name: spec}`` where
            spec is ``None`` (initial value from the mechanism), a number (initial value), a tuple
            ``(initial, lower, upper)`` or a dict with keys ``initial``, ``lower``, ``upper``
            (each optional). Missing bounds: the admissible interval if finite on both sides
            (shrunk by ``INTERIOR``), else [initial / ``DEFAULT_SPAN``, initial · ``DEFAULT_SPAN``]
            for positive parameters, clipped to the admissible interval.

    Raises:
        ModelError: unknown name (with suggestions), duplicate names, no parameter, bounds not
            ordered or outside the admissible interval, initial value not strictly inside the bounds.
    """
    if isinstance(parameters, Mapping):
        items = list(parameters.items())
    else:
        items = [(p.name, p) if isinstance(p, FitParameter) else (p, None) for p in parameters]
    if not items:
        raise ModelError("no parameter to fit: give at least one name, e.g. 'B.clearance'.")
    names = [n for n, _ in items]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ModelError(f"parameter {dupes[0]!r} is given twice; give each parameter once.")
    return [_one(mechanism, name, spec) for name, spec in items]


def _one(mechanism: Mechanism, name: str, spec) -> FitParameter:
    info = parameter_info(mechanism, name)  # ModelError for unknown names
    if isinstance(spec, FitParameter):
        initial, lower, upper = spec.initial, spec.lower, spec.upper
    elif isinstance(spec, Mapping):
        unknown = set(spec) - {"initial", "lower", "upper"}
        if unknown:
            raise ModelError(
                f"parameter {name!r}: unknown key {sorted(unknown)[0]!r}; use initial, lower, upper."
            )
        initial, lower, upper = spec.get("initial"), spec.get("lower"), spec.get("upper")
    elif isinstance(spec, tuple | list):
        if len(spec) != 3:
            raise ModelError(
                f"parameter {name!r}: give (initial, lower, upper), got {len(spec)} values."
            )
        initial, lower, upper = spec
    else:
        initial, lower, upper = spec, None, None
    if initial is None:
        initial = float(get_parameter(mechanism, name))
    initial = float(initial)
    a, b = info.domain
    if lower is None or upper is None:
        if math.isfinite(a) and math.isfinite(b):
            da, db = a + INTERIOR * (b - a), b - INTERIOR * (b - a)
        elif initial > 0 and a >= 0:
            da, db = initial / DEFAULT_SPAN, initial * DEFAULT_SPAN
        else:
            da, db = a, b
        if math.isfinite(a) and math.isfinite(b) and initial > 0 and a >= 0:
            da, db = max(da, initial / DEFAULT_SPAN), min(db, initial * DEFAULT_SPAN)
        lower = da if lower is None else lower
        upper = db if upper is None else upper
    lower, upper = float(lower), float(upper)
    if not lower < upper:
        raise ModelError(f"parameter {name!r}: need lower < upper, got {lower:g} and {upper:g}.")
    if lower < a or upper > b:
        raise ModelError(
            f"parameter {name!r}: bounds [{lower:g}, {upper:g}] leave its admissible interval "
            f"({a:g}, {b:g}) {info.unit}; narrow them."
        )
    if not lower < initial < upper:
        raise ModelError(
            f"parameter {name!r}: initial value {initial:g} is not strictly inside its bounds "
            f"[{lower:g}, {upper:g}]; move it inside or widen the bounds."
        )
    return FitParameter(name, initial, lower, upper, info.unit)


def scan_values(parameters: Sequence[FitParameter], count: int, seed: int = 0) -> np.ndarray:
    """Points spread over the bounded box, (count, p), for a global scan; the initial point first.

    One parameter: a uniform grid (log-uniform when both bounds are positive and span more than a
    factor 3). Several: a scrambled Halton sequence in the same coordinates. Unbounded directions
    are scanned over initial ± 50 %.
    """
    p = len(parameters)
    if count < 1:
        return np.zeros((0, p))
    if p == 1:
        unit = (np.arange(count - 1) + 0.5)[:, None] / max(count - 1, 1)
    else:
        unit = _halton(count - 1, p, seed)
    out = np.empty((count, p))
    out[0] = [q.initial for q in parameters]
    for k, q in enumerate(parameters):
        lo, hi = q.lower, q.upper
        if not (math.isfinite(lo) and math.isfinite(hi)):
            lo, hi = q.initial - 0.5 * abs(q.initial), q.initial + 0.5 * abs(q.initial)
        if lo > 0 and hi / lo > 3.0:
            out[1:, k] = np.exp(np.log(lo) + unit[:, k] * (np.log(hi) - np.log(lo)))
        else:
            out[1:, k] = lo + unit[:, k] * (hi - lo)
    return out


def _halton(n: int, dims: int, seed: int) -> np.ndarray:
    primes = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53)
    if dims > len(primes):
        raise ModelError(f"a scan over {dims} parameters is not supported (at most {len(primes)}).")
    rng = np.random.default_rng(seed)
    out = np.empty((n, dims))
    for d in range(dims):
        base = primes[d]
        perm = np.concatenate([[0], rng.permutation(np.arange(1, base))])  # digit scrambling
        for i in range(n):
            k, f, x = i + 1, 1.0, 0.0
            while k > 0:
                f /= base
                x += f * perm[k % base]
                k //= base
            out[i, d] = x
    return out
