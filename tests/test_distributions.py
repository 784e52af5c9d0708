"""Parameter distributions for Monte Carlo runs: moments against SciPy, truncation, ISO fits,
reproducibility, descriptions and config errors."""

import json
import math

import numpy as np
import pytest
import scipy.special
import scipy.stats

from jaxclear.studies._distributions import (
    AbstractDistribution,
    Fixed,
    IsoFit,
    LogNormal,
    Normal,
    Uniform,
    _standard_normal_quantile,
    distribution_from_spec,
)
from jaxclear.studies._iso286 import fit_clearance, fit_zones

N_SAMPLES = 200_000
STANDARD_ERRORS = 5.0
"""Sample mean and standard deviation must be within 5 standard errors of the exact values: a
correct sampler fails with probability < 1e-6 per check (and the seeds are fixed)."""
QUANTILE_RTOL = 1e-14
"""Acklam's approximation refined by one Halley step is accurate to a few ulp (SciPy's ndtri is
the reference)."""


def _assert_moments(samples, reference):
    """Sample mean and std of ``samples`` vs a frozen SciPy distribution, within STANDARD_ERRORS."""
    mean, variance, _, excess_kurtosis = (float(m) for m in reference.stats(moments="mvsk"))
    std = math.sqrt(variance)
    n = samples.size
    mean_error = std / math.sqrt(n)
    # Var(s²) ≈ (μ4 − σ⁴)/n with μ4 = (excess kurtosis + 3) σ⁴; s = sqrt(s²) (delta method)
    std_error = math.sqrt((excess_kurtosis + 2.0) * variance**2 / n) / (2.0 * std)
    assert abs(samples.mean() - mean) < STANDARD_ERRORS * mean_error
    assert abs(samples.std() - std) < STANDARD_ERRORS * std_error


def _truncnorm(mean, std, low, high):
    a = -np.inf if low is None else (low - mean) / std
    b = np.inf if high is None else (high - mean) / std
    return scipy.stats.truncnorm(a, b, loc=mean, scale=std)


def test_fixed_draws_its_value():
    samples = Fixed(0.5).sample(np.random.default_rng(0), 4)
    assert samples.dtype == np.float64 and samples.shape == (4,)
    assert np.all(samples == 0.5)
    assert Fixed(0.5).support() == (0.5, 0.5)


def test_uniform_moments_and_support():
    distribution = Uniform(3e-4, 6e-4)
    samples = distribution.sample(np.random.default_rng(1), N_SAMPLES)
    _assert_moments(samples, scipy.stats.uniform(3e-4, 3e-4))
    assert samples.min() >= 3e-4 and samples.max() <= 6e-4
    assert distribution.support() == (3e-4, 6e-4)


def test_normal_moments():
    samples = Normal(0.21, 0.005).sample(np.random.default_rng(2), N_SAMPLES)
    _assert_moments(samples, scipy.stats.norm(0.21, 0.005))


@pytest.mark.parametrize(
    "low, high",
    [
        (0.2, 0.25),  # both sides
        (0.22, None),  # lower bound above the mean
        (None, 0.2),  # upper bound below the mean
        (0.26, 0.27),  # far upper tail: 10 to 12 std
        (0.15, 0.152),  # far lower tail, narrow
    ],
)
def test_truncated_normal_moments_and_bounds(low, high):
    distribution = Normal(0.21, 0.005, low=low, high=high)
    samples = distribution.sample(np.random.default_rng(3), N_SAMPLES)
    _assert_moments(samples, _truncnorm(0.21, 0.005, low, high))
    lowest, highest = distribution.support()
    assert samples.min() >= lowest and samples.max() <= highest
    assert lowest == (-math.inf if low is None else low)
    assert highest == (math.inf if high is None else high)


def test_normal_quantile_matches_scipy():
    p = np.concatenate(
        [
            np.logspace(-307, -1, 400),
            np.linspace(0.001, 0.999, 999),
            1.0 - np.logspace(-16, -1, 200),
        ]
    )
    x = _standard_normal_quantile(p)
    reference = scipy.special.ndtri(p)
    assert np.all(np.abs(x - reference) <= QUANTILE_RTOL * np.maximum(1.0, np.abs(reference)))


@pytest.mark.parametrize(
    "distribution, reference",
    [
        (LogNormal(2e9, 0.2), scipy.stats.lognorm(0.2, scale=2e9)),
        (LogNormal.from_mean_std(0.5, 0.1), None),
    ],
)
def test_lognormal_moments(distribution, reference):
    if reference is None:  # from_mean_std: the exact mean and std are the ones given
        reference = scipy.stats.lognorm(distribution.sigma, scale=distribution.median)
        assert reference.mean() == pytest.approx(0.5, rel=1e-12)
        assert reference.std() == pytest.approx(0.1, rel=1e-12)
    samples = distribution.sample(np.random.default_rng(4), N_SAMPLES)
    _assert_moments(samples, reference)
    assert samples.min() > 0.0
    assert distribution.support() == (0.0, math.inf)


@pytest.mark.parametrize("fit, diameter", [("H7/g6", 0.02), ("H8/f7", 0.05), ("H7/s6", 0.1)])
def test_iso_fit_uniform_draws_inside_the_fit_with_the_mean_in_the_middle(fit, diameter):
    distribution = IsoFit(fit, diameter)
    samples = distribution.sample(np.random.default_rng(5), N_SAMPLES)
    low, high = fit_clearance(fit, diameter)
    assert distribution.support() == (low, high)
    assert samples.min() >= low and samples.max() <= high
    (hole_low, hole_high), (shaft_low, shaft_high) = fit_zones(fit, diameter)
    # c = (D − d)/2 with D, d independent uniforms: mean in the middle of the fit's range,
    # variance (w_D² + w_d²)/12/4
    hole_width, shaft_width = hole_high - hole_low, shaft_high - shaft_low
    std = math.sqrt((hole_width**2 + shaft_width**2) / 12.0) / 2.0
    assert abs(samples.mean() - 0.5 * (low + high)) < STANDARD_ERRORS * std / math.sqrt(N_SAMPLES)
    assert samples.std() == pytest.approx(std, rel=0.01)  # > 5 standard errors (~0.0013) at 2e5


def test_iso_fit_normal_is_centred_with_the_zone_at_three_sigma():
    distribution = IsoFit("H7/g6", 0.02, within="normal")
    samples = distribution.sample(np.random.default_rng(6), N_SAMPLES)
    low, high = fit_clearance("H7/g6", 0.02)
    assert samples.min() >= low and samples.max() <= high
    # each diameter: truncnorm(−3, 3) scaled by width/6; c = (D − d)/2
    unit_std = scipy.stats.truncnorm(-3.0, 3.0).std()
    std = 0.5 * unit_std * math.sqrt(21e-6**2 + 13e-6**2) / 6.0
    assert abs(samples.mean() - 0.5 * (low + high)) < STANDARD_ERRORS * std / math.sqrt(N_SAMPLES)
    assert samples.std() == pytest.approx(std, rel=0.01)


def test_interference_fit_draws_negative_clearance():
    samples = IsoFit("H7/u6", 0.1).sample(np.random.default_rng(7), 1000)
    assert samples.max() <= fit_clearance("H7/u6", 0.1)[1] < 0.0


@pytest.mark.parametrize(
    "distribution",
    [
        Uniform(0.0, 1.0),
        Normal(0.0, 1.0),
        Normal(0.0, 1.0, low=-0.5, high=2.0),
        LogNormal(1.0, 0.3),
        IsoFit("H7/g6", 0.02),
        IsoFit("H7/g6", 0.02, within="normal"),
    ],
)
def test_same_seed_same_draws(distribution):
    first = distribution.sample(np.random.default_rng(42), 100)
    again = distribution.sample(np.random.default_rng(42), 100)
    other = distribution.sample(np.random.default_rng(43), 100)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


DISTRIBUTIONS = [
    Fixed(2.5),
    Uniform(3e-4, 6e-4),
    Normal(0.21, 0.005),
    Normal(0.21, 0.005, low=0.2),
    Normal(0.21, 0.005, low=0.2, high=0.22),
    LogNormal(2e9, 0.2),
    LogNormal.from_mean_std(0.5, 0.1),
    IsoFit("H7/g6", 0.02),
    IsoFit("H8/f7", 0.05, within="normal"),
]


@pytest.mark.parametrize("distribution", DISTRIBUTIONS)
def test_describe_round_trips_through_json_and_the_spec(distribution):
    description = json.loads(json.dumps(distribution.describe()))
    assert distribution_from_spec(description, "x") == distribution
    assert distribution_from_spec(description, "x").describe() == distribution.describe()


def test_specs_build_the_documented_distributions():
    assert distribution_from_spec(0.5, "m") == Fixed(0.5)
    assert distribution_from_spec({"distribution": "fixed", "value": 1}, "m") == Fixed(1.0)
    assert distribution_from_spec(
        {"distribution": "uniform", "low": 3e-4, "high": 6e-4}, "B.clearance"
    ) == Uniform(3e-4, 6e-4)
    assert distribution_from_spec(
        {"distribution": "normal", "mean": 0.21, "std": 0.005, "high": 0.22}, "L"
    ) == Normal(0.21, 0.005, high=0.22)
    assert distribution_from_spec(
        {"distribution": "lognormal", "mean": 0.5, "std": 0.1}, "k"
    ) == LogNormal.from_mean_std(0.5, 0.1)
    assert distribution_from_spec({"fit": "H7/g6", "diameter": 0.02}, "B.clearance") == IsoFit(
        "H7/g6", 0.02
    )
    assert distribution_from_spec({"fit": " H7 / g6 ", "diameter": 0.02}, "B") == IsoFit(
        "H7/g6", 0.02
    )
    uniform = Uniform(0.0, 1.0)
    assert distribution_from_spec(uniform, "x") is uniform
    assert isinstance(uniform, AbstractDistribution)


def test_sample_arguments_are_checked():
    rng = np.random.default_rng(0)
    assert Uniform(0.0, 1.0).sample(rng, 0).shape == (0,)
    with pytest.raises(ValueError, match=r"n must be >= 0; got -1"):
        Uniform(0.0, 1.0).sample(rng, -1)


U = "distribution"
SPEC_ERRORS = [
    (
        {U: "uniformm", "low": 0.0, "high": 1.0},
        r"^B\.clearance: unknown distribution 'uniformm'; choose fixed, uniform, normal, "
        r"lognormal, or give fit = \"H7/g6\" and diameter$",
    ),
    ({"low": 0.0, "high": 1.0}, r"^B\.clearance: missing key 'distribution'; choose fixed"),
    ({U: "uniform", "low": 0.0}, r"^B\.clearance: missing key\(s\) 'high' for distribution"),
    (
        {U: "uniform", "low": 0.0, "high": 1.0, "hihg": 2.0},
        r"^B\.clearance: unexpected key\(s\) 'hihg' .*allowed: low, high$",
    ),
    ({U: "uniform", "low": 1.0, "high": 1.0}, r"^B\.clearance: Uniform low must be < high"),
    ({U: "uniform", "low": 0.0, "high": math.inf}, r"^B\.clearance: 'high' must be a finite"),
    ({U: "uniform", "low": "0", "high": 1.0}, r"^B\.clearance: 'low' must be a finite number"),
    ({U: "normal", "mean": 0.2, "std": 0.0}, r"^B\.clearance: Normal std must be > 0; got 0\.0"),
    ({U: "normal", "mean": 0.2, "std": -1.0}, r"^B\.clearance: Normal std must be > 0"),
    ({U: "normal", "mean": math.nan, "std": 1.0}, r"^B\.clearance: 'mean' must be a finite"),
    (
        {U: "normal", "mean": 0.2, "std": 0.1, "low": 0.3, "high": 0.3},
        r"^B\.clearance: Normal truncation is empty: low must be < high",
    ),
    (
        {U: "normal", "mean": 0.0, "std": 1.0, "low": 50.0},
        r"^B\.clearance: Normal truncation \[50\.0, None\] holds no probability mass",
    ),
    ({U: "normal", "mean": 0.2}, r"^B\.clearance: missing key\(s\) 'std'"),
    ({U: "lognormal"}, r"^B\.clearance: missing key\(s\) 'median', 'sigma'.*\(or mean, std\)"),
    ({U: "lognormal", "median": 1.0, "std": 0.1}, r"^B\.clearance: missing key\(s\) 'sigma'"),
    ({U: "lognormal", "mean": 1.0}, r"^B\.clearance: missing key\(s\) 'std'"),
    ({U: "lognormal", "median": -1.0, "sigma": 0.1}, r"^B\.clearance: LogNormal median must be >"),
    ({U: "lognormal", "mean": 1.0, "std": 0.0}, r"^B\.clearance: LogNormal std must be > 0"),
    ({U: "fixed"}, r"^B\.clearance: missing key\(s\) 'value'"),
    ({"fit": "H7/g6"}, r"^B\.clearance: missing key\(s\) 'diameter' for an ISO fit"),
    (
        {"fit": "H7/g6", "diameter": 0.02, U: "uniform"},
        r"^B\.clearance: give either distribution = \.\.\. or fit = \.\.\., not both",
    ),
    (
        {"fit": "H7/g6", "diameter": 0.02, "within": "triangular"},
        r"^B\.clearance: IsoFit within must be 'uniform' or 'normal'",
    ),
    ({"fit": "H7/x6", "diameter": 0.02}, r"^B\.clearance: unknown fundamental deviation letter"),
    ({"fit": "H7g6", "diameter": 0.02}, r"^B\.clearance: cannot read fit 'H7g6'"),
    ({"fit": "H7/g6", "diameter": 20.0}, r"^B\.clearance: diameter must be in metres"),
    ({"fit": 7, "diameter": 0.02}, r"^B\.clearance: 'fit' must be a string"),
    (True, r"^B\.clearance: expected a number or a table"),
    ("0.5", r"^B\.clearance: expected a number or a table"),
    (math.nan, r"^B\.clearance: fixed value must be a finite number"),
]


@pytest.mark.parametrize("spec, match", SPEC_ERRORS)
def test_bad_specs_raise_naming_the_parameter(spec, match):
    with pytest.raises(ValueError, match=match):
        distribution_from_spec(spec, "B.clearance")
