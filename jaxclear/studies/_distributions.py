"""Distributions of uncertain parameters (manufacturing tolerances) for Monte Carlo runs.

Each distribution draws float64 NumPy samples from a ``numpy.random.Generator`` (the same seed
gives the same draws), describes itself as a JSON-able dict that fully determines it (a run
refuses to resume when a description changed), and states its support.

Config tables (``distribution_from_spec``)::

    B.clearance = {distribution = "uniform", low = 3e-4, high = 6e-4}
    rod_length = {distribution = "normal", mean = 0.21, std = 0.005}        # low/high: truncation
    B.stiffness = {distribution = "lognormal", median = 1e9, sigma = 0.2}   # or mean, std
    C.clearance = {fit = "H7/g6", diameter = 0.02}                          # within = "normal"
    crank_mass = {distribution = "fixed", value = 0.5}                      # or just 0.5

No SciPy: the truncated normal is drawn by inverse CDF with ``math.erfc`` and Acklam's rational
approximation of the normal quantile, refined by one Halley step (full double precision).
"""

import abc
import dataclasses
import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._iso286 import fit_clearance, fit_zones

_CHOICES = 'choose fixed, uniform, normal, lognormal, or give fit = "H7/g6" and diameter'

# P. J. Acklam, "An algorithm for computing the inverse normal cumulative distribution function"
# (2003): rational approximations, relative error < 1.15e-9 before refinement.
_ACKLAM_A = (-39.69683028665376, 220.9460984245205, -275.9285104469687, 138.3577518672690,
             -30.66479806614716, 2.506628277459239)  # fmt: skip
_ACKLAM_B = (-54.47609879822406, 161.5858368580409, -155.6989798598866, 66.80131188771972,
             -13.28068155288572)  # fmt: skip
_ACKLAM_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838,
             -2.549732539343734, 4.374664141464968, 2.938163982698783)  # fmt: skip
_ACKLAM_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996, 3.754408661907416)
_ACKLAM_P_LOW = 0.02425  # below: tail formula; from there to 1/2: central formula

_erfc = np.vectorize(math.erfc, otypes=[np.float64])


def _standard_normal_cdf(x: float) -> float:
    """Φ(x) = erfc(−x/√2)/2, accurate in the lower tail."""
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def _polyval(coefficients: tuple[float, ...], x: np.ndarray) -> np.ndarray:
    result = np.zeros_like(x)
    for coefficient in coefficients:
        result = result * x + coefficient
    return result


def _standard_normal_quantile(p: np.ndarray) -> np.ndarray:
    """Φ⁻¹(p) for p in (0, 1), elementwise, to double precision.

    Computed on the lower half, x = Φ⁻¹(min(p, 1 − p)) <= 0 (1 − p is exact for p >= 1/2), where
    Φ(x) = erfc(−x/√2)/2 has full relative precision for the refinement; the sign is restored.
    """
    upper = p > 0.5
    tail = np.where(upper, 1.0 - p, p)
    x = np.empty_like(tail)
    low = tail < _ACKLAM_P_LOW
    t = np.sqrt(-2.0 * np.log(tail[low]))
    x[low] = _polyval(_ACKLAM_C, t) / (_polyval(_ACKLAM_D, t) * t + 1.0)
    q = tail[~low] - 0.5
    r = q * q
    x[~low] = q * _polyval(_ACKLAM_A, r) / (_polyval(_ACKLAM_B, r) * r + 1.0)
    # one Halley step on Φ(x) − tail = 0 (Acklam's refinement)
    error = 0.5 * _erfc(-x / math.sqrt(2.0)) - tail
    u = error * math.sqrt(2.0 * math.pi) * np.exp(0.5 * x * x)
    x = x - u / (1.0 + 0.5 * x * u)
    return np.where(upper, -x, x)


def _truncation_masses(a: float, b: float) -> tuple[float, float, bool]:
    """(Φ(a'), Φ(b'), flipped) for standardised bounds a < b, mirrored into the lower tail
    (a' = −b, b' = −a) when a > 0, where Φ is computed without cancellation."""
    flipped = a > 0.0
    if flipped:
        a, b = -b, -a
    return _standard_normal_cdf(a), _standard_normal_cdf(b), flipped


def _truncated_standard_normal(rng: np.random.Generator, a: float, b: float, n: int) -> np.ndarray:
    """n draws of a standard normal truncated to [a, b] (a < b; ±inf allowed), inverse CDF."""
    p_a, p_b, flipped = _truncation_masses(a, b)
    p = p_a + (p_b - p_a) * rng.random(n)
    # keep p inside (0, 1) so the quantile is finite; the clip to [a, b] below restores the bounds
    x = _standard_normal_quantile(np.clip(p, np.finfo(np.float64).tiny, 1.0 - 2.0**-53))
    x = -x if flipped else x
    return np.clip(x, a, b)


def _finite(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{what} must be a finite number; got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number; got {value!r}")
    return float(value)


def _positive(value: Any, what: str) -> float:
    number = _finite(value, what)
    if not number > 0.0:
        raise ValueError(f"{what} must be > 0; got {number!r}")
    return number


class AbstractDistribution(abc.ABC):
    """A distribution of one scalar parameter (SI units)."""

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw n values.

        Args:
            rng: NumPy generator; the same seed gives the same draws.
            n: number of draws, >= 0.

        Returns:
            float64 array of shape (n,), inside `support`.

        Raises:
            TypeError: rng is not a ``numpy.random.Generator`` or n is not an integer.
            ValueError: n < 0.
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(
                f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)); got "
                f"{type(rng).__name__}"
            )
        if isinstance(n, bool) or not isinstance(n, numbers.Integral):
            raise TypeError(f"n must be an integer; got {n!r}")
        if n < 0:
            raise ValueError(f"n must be >= 0; got {n}")
        values = np.asarray(self._draw(rng, int(n)), dtype=np.float64)
        return values.reshape(int(n))

    @abc.abstractmethod
    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n draws (arguments already checked)."""

    @abc.abstractmethod
    def describe(self) -> dict[str, Any]:
        """JSON-able description; ``distribution_from_spec(d.describe(), name) == d``."""

    @abc.abstractmethod
    def support(self) -> tuple[float, float]:
        """(lowest, highest) value a draw can take; may be infinite."""


@dataclasses.dataclass(frozen=True)
class Fixed(AbstractDistribution):
    """Always the same value.

    Attributes:
        value: the value (finite).
    """

    value: float

    def __post_init__(self):
        object.__setattr__(self, "value", _finite(self.value, "Fixed value"))

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return np.full(n, self.value)

    def describe(self) -> dict[str, Any]:
        return {"distribution": "fixed", "value": self.value}

    def support(self) -> tuple[float, float]:
        return self.value, self.value


@dataclasses.dataclass(frozen=True)
class Uniform(AbstractDistribution):
    """Uniform on [low, high].

    Attributes:
        low, high: bounds, finite, low < high.
    """

    low: float
    high: float

    def __post_init__(self):
        low = _finite(self.low, "Uniform low")
        high = _finite(self.high, "Uniform high")
        if not low < high:
            raise ValueError(f"Uniform low must be < high; got low={low!r}, high={high!r}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return rng.uniform(self.low, self.high, n)

    def describe(self) -> dict[str, Any]:
        return {"distribution": "uniform", "low": self.low, "high": self.high}

    def support(self) -> tuple[float, float]:
        return self.low, self.high


@dataclasses.dataclass(frozen=True)
class Normal(AbstractDistribution):
    """Normal (Gaussian), optionally truncated to [low, high].

    Truncated draws use the inverse CDF: u uniform in (Φ(α), Φ(β)), x = mean + std Φ⁻¹(u) with
    α = (low − mean)/std, β = (high − mean)/std (mirrored into the lower tail when α > 0, so far
    tails keep their precision).

    Attributes:
        mean: mean of the untruncated normal.
        std: its standard deviation, > 0.
        low, high: optional truncation bounds (None: none); finite, low < high, and the range must
            hold probability mass (within about 37 std of the mean).
    """

    mean: float
    std: float
    low: float | None = None
    high: float | None = None

    def __post_init__(self):
        mean = _finite(self.mean, "Normal mean")
        std = _positive(self.std, "Normal std")
        low = None if self.low is None else _finite(self.low, "Normal low")
        high = None if self.high is None else _finite(self.high, "Normal high")
        if low is not None and high is not None and not low < high:
            raise ValueError(
                f"Normal truncation is empty: low must be < high; got low={low!r}, high={high!r}"
            )
        for field, value in (("mean", mean), ("std", std), ("low", low), ("high", high)):
            object.__setattr__(self, field, value)
        a, b = self._standardised_bounds()
        p_a, p_b, _ = _truncation_masses(a, b)
        if not p_b > p_a:
            raise ValueError(
                f"Normal truncation [{low}, {high}] holds no probability mass for mean={mean!r}, "
                f"std={std!r} (too many std from the mean); move the bounds or the mean"
            )

    def _standardised_bounds(self) -> tuple[float, float]:
        a = -math.inf if self.low is None else (self.low - self.mean) / self.std
        b = math.inf if self.high is None else (self.high - self.mean) / self.std
        return a, b

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.low is None and self.high is None:
            return rng.normal(self.mean, self.std, n)
        z = _truncated_standard_normal(rng, *self._standardised_bounds(), n)
        low, high = self.support()
        return np.clip(self.mean + self.std * z, low, high)

    def describe(self) -> dict[str, Any]:
        description: dict[str, Any] = {
            "distribution": "normal",
            "mean": self.mean,
            "std": self.std,
        }
        if self.low is not None:
            description["low"] = self.low
        if self.high is not None:
            description["high"] = self.high
        return description

    def support(self) -> tuple[float, float]:
        return (
            -math.inf if self.low is None else self.low,
            math.inf if self.high is None else self.high,
        )


@dataclasses.dataclass(frozen=True)
class LogNormal(AbstractDistribution):
    """Log-normal: log(x) is normal with mean log(median) and standard deviation sigma.

    For positive parameters known by a typical value and a relative spread (sigma ≈ coefficient
    of variation when small). ``LogNormal.from_mean_std(mean, std)`` takes the mean and standard
    deviation of x instead: sigma² = log(1 + (std/mean)²), median = mean·exp(−sigma²/2).

    Attributes:
        median: median of x (= exp of the mean of log x), > 0.
        sigma: standard deviation of log x, > 0.
    """

    median: float
    sigma: float

    def __post_init__(self):
        object.__setattr__(self, "median", _positive(self.median, "LogNormal median"))
        object.__setattr__(self, "sigma", _positive(self.sigma, "LogNormal sigma"))

    @classmethod
    def from_mean_std(cls, mean: float, std: float) -> "LogNormal":
        """The log-normal with mean ``mean`` and standard deviation ``std`` (both > 0)."""
        mean = _positive(mean, "LogNormal mean")
        std = _positive(std, "LogNormal std")
        sigma = math.sqrt(math.log1p((std / mean) ** 2))
        return cls(median=mean * math.exp(-0.5 * sigma**2), sigma=sigma)

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self.median * np.exp(self.sigma * rng.standard_normal(n))

    def describe(self) -> dict[str, Any]:
        return {"distribution": "lognormal", "median": self.median, "sigma": self.sigma}

    def support(self) -> tuple[float, float]:
        return 0.0, math.inf


_WITHIN = ("uniform", "normal")


@dataclasses.dataclass(frozen=True)
class IsoFit(AbstractDistribution):
    """Radial clearance of a revolute joint made to an ISO 286 fit.

    The hole diameter D and the pin (shaft) diameter d are drawn independently inside their
    ISO 286 tolerance zones (see ``tolerance_zone``); the radial clearance is
    c = (D − d)/2, so every draw lies in ``fit_clearance(fit, diameter)`` (negative values:
    interference).

    ISO 286 fixes only the limits of each zone; how diameters spread inside them is an
    ASSUMPTION chosen by ``within``:

    - ``"uniform"`` (default): uniform inside each zone (no knowledge of the process);
    - ``"normal"``: normal centred in the zone with the zone = ±3σ, truncated to the zone (a
      centred process with capability Cp = 1).

    Attributes:
        fit: ISO fit, hole/shaft, e.g. ``"H7/g6"``.
        diameter: nominal diameter in metres (0.02 for 20 mm), 0 < diameter <= 0.5.
        within: ``"uniform"`` or ``"normal"``.
    """

    fit: str
    diameter: float
    within: str = "uniform"

    def __post_init__(self):
        if not isinstance(self.fit, str):
            raise ValueError(f"IsoFit fit must be a string such as 'H7/g6'; got {self.fit!r}")
        object.__setattr__(self, "fit", "/".join(p.strip() for p in self.fit.strip().split("/")))
        object.__setattr__(self, "diameter", _finite(self.diameter, "IsoFit diameter"))
        if self.within not in _WITHIN:
            raise ValueError(
                f"IsoFit within must be 'uniform' or 'normal' (how diameters spread inside their "
                f"ISO zones); got {self.within!r}"
            )
        fit_zones(self.fit, self.diameter)  # raises on an unknown fit or a bad diameter

    def _inside(self, rng: np.random.Generator, lower: float, upper: float, n: int) -> np.ndarray:
        if self.within == "uniform":
            return rng.uniform(lower, upper, n)
        z = _truncated_standard_normal(rng, -3.0, 3.0, n)  # zone = ±3σ
        return np.clip(0.5 * (lower + upper) + (upper - lower) / 6.0 * z, lower, upper)

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        (hole_lower, hole_upper), (shaft_lower, shaft_upper) = fit_zones(self.fit, self.diameter)
        hole = self._inside(rng, hole_lower, hole_upper, n)  # deviations from nominal, m
        shaft = self._inside(rng, shaft_lower, shaft_upper, n)
        return 0.5 * (hole - shaft)

    def describe(self) -> dict[str, Any]:
        return {"fit": self.fit, "diameter": self.diameter, "within": self.within}

    def support(self) -> tuple[float, float]:
        return fit_clearance(self.fit, self.diameter)


# distribution name -> (class or constructor, required keys, optional keys)
_KINDS: dict[str, tuple[Any, tuple[str, ...], tuple[str, ...]]] = {
    "fixed": (Fixed, ("value",), ()),
    "uniform": (Uniform, ("low", "high"), ()),
    "normal": (Normal, ("mean", "std"), ("low", "high")),
    "lognormal": (LogNormal, ("median", "sigma"), ()),
}
_LOGNORMAL_MEAN_STD = (LogNormal.from_mean_std, ("mean", "std"), ())
_ISO_FIT = (IsoFit, ("fit", "diameter"), ("within",))


def _names(keys) -> str:
    return ", ".join(repr(key) for key in keys)


def _build(spec: Mapping[str, Any], name: str, what: str, kind) -> AbstractDistribution:
    constructor, required, optional = kind
    given = set(spec) - {"distribution"}
    missing = [key for key in required if key not in given]
    if missing:
        alternative = " (or mean, std)" if constructor is LogNormal else ""
        raise ValueError(
            f"{name}: missing key(s) {_names(missing)} for {what}; give {', '.join(required)}"
            + alternative
            + (f" (optional: {', '.join(optional)})" if optional else "")
        )
    extra = sorted(given - set(required) - set(optional))
    if extra:
        raise ValueError(
            f"{name}: unexpected key(s) {_names(extra)} for {what}; allowed: "
            f"{', '.join((*required, *optional))}"
        )
    arguments = {}
    for key in given:
        value = spec[key]
        if key in ("fit", "within"):
            if not isinstance(value, str):
                raise ValueError(f"{name}: {key!r} must be a string; got {value!r}")
            arguments[key] = value
        else:
            arguments[key] = _finite(value, f"{name}: {key!r}")
    try:
        return constructor(**arguments)
    except ValueError as error:
        raise ValueError(f"{name}: {error}") from None


def distribution_from_spec(spec: Any, name: str) -> AbstractDistribution:
    """The distribution a config entry describes.

    Args:
        spec: a number (fixed value); a table (mapping) with ``distribution`` = ``"fixed"``
            (``value``), ``"uniform"`` (``low``, ``high``), ``"normal"`` (``mean``, ``std``,
            optional truncation ``low``, ``high``), ``"lognormal"`` (``median``, ``sigma`` or
            ``mean``, ``std``); or a table with ``fit`` (``"H7/g6"``), ``diameter`` (m) and
            optional ``within`` (``"uniform"``/``"normal"``) for `IsoFit`; or an
            `AbstractDistribution` (returned as is). Values in SI units.
        name: the parameter's name, starting every error message (``"B.clearance"``).

    Returns:
        The distribution; ``distribution_from_spec(d.describe(), name) == d``.

    Raises:
        ValueError: ``"<name>: ..."``: unknown distribution, missing or unexpected keys,
            non-finite numbers, std/sigma/median <= 0, low >= high, a truncation without
            probability mass, or a bad ISO fit or diameter.
    """
    if isinstance(spec, AbstractDistribution):
        return spec
    if isinstance(spec, numbers.Real) and not isinstance(spec, bool):
        return Fixed(_finite(spec, f"{name}: fixed value"))
    if not isinstance(spec, Mapping):
        raise ValueError(
            f"{name}: expected a number or a table such as "
            f'{{distribution = "uniform", low = ..., high = ...}}; got {spec!r}'
        )
    if not all(isinstance(key, str) for key in spec):
        raise ValueError(f"{name}: table keys must be strings; got {_names(spec)}")
    if "fit" in spec:
        if "distribution" in spec:
            raise ValueError(
                f"{name}: give either distribution = ... or fit = ..., not both; got "
                f"distribution = {spec['distribution']!r} and fit = {spec['fit']!r}"
            )
        return _build(spec, name, "an ISO fit", _ISO_FIT)
    if "distribution" not in spec:
        raise ValueError(f"{name}: missing key 'distribution'; {_CHOICES}")
    kind = spec["distribution"]
    if not isinstance(kind, str) or kind not in _KINDS:
        raise ValueError(f"{name}: unknown distribution {kind!r}; {_CHOICES}")
    what = f"distribution {kind!r}"
    if kind == "lognormal" and not {"median", "sigma"} & set(spec) and {"mean", "std"} & set(spec):
        return _build(spec, name, f"{what} given by mean and std", _LOGNORMAL_MEAN_STD)
    return _build(spec, name, what, _KINDS[kind])
