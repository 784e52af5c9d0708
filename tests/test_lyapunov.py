"""Largest Lyapunov exponent: Lorenz, a damped oscillator, the ideal slider-crank
(jaxclear.studies._lyapunov)."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear.dynamics._constraints import constraint_velocity, constraints
from jaxclear.studies import (
    ConstraintProjection,
    ODEFlow,
    flow_lyapunov,
    largest_lyapunov,
    lyapunov_sweep,
    mechanism_weights,
    two_trajectory_lyapunov,
)

LORENZ_EXPONENT = 0.9056
"""Largest exponent of the Lorenz system at σ = 10, ρ = 28, β = 8/3 (Sprott, Chaos and
Time-Series Analysis, 2003, Table A.1)."""

LORENZ_HORIZON = 200.0
"""Averaging time after the transient (200 intervals of 1 time unit)."""

LORENZ_TOLERANCE = 0.05
"""Finite-time estimates over LORENZ_HORIZON scatter with the initial point: over 64 random starts
near (1, 1, 20) (transient 10) they had mean 0.906, standard deviation 0.011 and range 0.881–0.939
(0.37/√T; 0.022 at T = 100). 0.05 is 4.5 standard deviations."""

METHODS_AGREE = 1e-4
"""Tangent and two-trajectory estimates from the same start and direction: the divided difference
over a separation of 1e-8 differs from the tangent by O(separation × curvature) plus the
difference of the two solves' errors (correlated: nearly the same step sequence); measured 7e-8 in
the exponent."""

MECHANISM_AGREE = 0.15
"""Tangent against two trajectories on the one-joint slider-crank over two revolutions: the
divided difference over 1e-7 m is not linear through the contact (penetrations of ~10 µm) and
carries the difference of the two solves' errors; measured 4 % apart at rtol 1e-10."""

OSCILLATOR_TOLERANCE = 0.01
"""Damped oscillator: the exponent −ζω0 is reached up to the norm's oscillation within a period
(the eigenvectors are not orthogonal in the (x, ẋ/ω0) norm), a bounded term ~ ln(1 + ζ)/T ≈ 1e-3
over T = 50."""


def _lorenz(t, y, args):
    sigma, rho, beta = args
    x, v, z = y[0], y[1], y[2]
    return jnp.stack([sigma * (v - x), x * (rho - z) - v, x * v - beta * z])


@pytest.fixture(scope="module")
def lorenz():
    return ODEFlow(diffrax.ODETerm(_lorenz), args=(10.0, 28.0, 8.0 / 3.0), rtol=1e-10, atol=1e-10)


@pytest.fixture(scope="module")
def lorenz_estimates(lorenz):
    y0 = jnp.array([1.0, 1.0, 20.0])
    options = dict(interval=1.0, transient=10.0)
    t1 = 10.0 + LORENZ_HORIZON
    return {
        method: flow_lyapunov(lorenz, y0, t1, method=method, **options)
        for method in ("tangent", "two_trajectory")
    }


def test_lorenz_exponent(lorenz_estimates):
    result = lorenz_estimates["tangent"]
    assert bool(result.succeeded)
    assert result.running.shape == result.log_growth.shape == result.times.shape == (200,)
    np.testing.assert_allclose(np.asarray(result.times)[[0, -1]], [11.0, 210.0])
    assert float(result.exponent) == pytest.approx(LORENZ_EXPONENT, abs=LORENZ_TOLERANCE)
    # the running estimate has settled: the spread over the last half is within the tolerance
    assert 0 < float(result.spread) < LORENZ_TOLERANCE


def test_tangent_and_two_trajectory_agree_on_lorenz(lorenz_estimates):
    tangent, pair = lorenz_estimates["tangent"], lorenz_estimates["two_trajectory"]
    assert pair.method == "two_trajectory"
    assert float(pair.exponent) == pytest.approx(float(tangent.exponent), abs=METHODS_AGREE)
    np.testing.assert_allclose(pair.log_growth, tangent.log_growth, atol=10 * METHODS_AGREE)


def test_damped_forced_oscillator_has_its_damping_rate():
    """ẍ + 2ζω0 ẋ + ω0² x = F cos Ωt: a periodic response whose exponent is −ζω0 (both
    eigenvalues of the homogeneous part have real part −ζω0)."""
    omega0, zeta = 2 * np.pi, 0.05

    def field(t, y, args):
        return jnp.stack([y[1], -2 * zeta * omega0 * y[1] - omega0**2 * y[0] + jnp.cos(3.0 * t)])

    flow = ODEFlow(diffrax.ODETerm(field), rtol=1e-10, atol=1e-12)
    result = flow_lyapunov(
        flow, jnp.array([1.0, 0.0]), 55.0, interval=1.0, transient=5.0, weights=[1, 1 / omega0]
    )
    assert bool(result.succeeded)
    assert float(result.exponent) == pytest.approx(-zeta * omega0, abs=OSCILLATOR_TOLERANCE)


def test_ideal_slider_crank_is_not_chaotic():
    """All joints ideal and the crank driven: no degree of freedom. Every perturbation violates the
    constraints and decays under Baumgarte stabilisation, Φ̈ + 2αΦ̇ + β²Φ = 0 (α = β = 50/s: a double
    root at −50/s). Over K intervals of length Δ the double root's estimate approaches −α from above
    as ln K/(K Δ); the test checks it is negative and within that bound."""
    mech = jaxclear.mechanisms.slider_crank(clearance_joints="")
    period = 60.0 / 5000.0
    alpha = float(mech.baumgarte_alpha)
    with pytest.raises(ValueError, match="no degrees of freedom"):
        largest_lyapunov(mech, 5 * period)
    k = 8
    result = largest_lyapunov(mech, k * period, project=False)
    assert bool(result.succeeded)
    bound = -alpha + 2 * np.log(k) / (k * period)  # factor 2: the first interval's alignment
    assert -alpha * 1.01 < float(result.exponent) < min(bound, 0.0)
    # vmapped over a parameter (the exponent per value of a sweep): equals the single run
    batch = lyapunov_sweep(mech, "rpm", [5000.0, 4000.0], k * period, project=False)
    assert batch.interval == pytest.approx(period)  # the base mechanism's crank period
    assert np.all(batch.succeeded)
    assert batch.exponents[0] == pytest.approx(float(result.exponent), rel=1e-6)
    assert batch.exponents[1] < 0.0
    with pytest.raises(ValueError, match="not a parameter"):
        lyapunov_sweep(mech, "B.clearance", [1e-4], k * period)


PROJECTION_ATOL = 1e-12
"""A projected perturbation of unit norm keeps the linearised position and velocity constraints to
rounding (the projection solves a 14×14 system with condition ~1e4)."""


def test_constraint_projection_keeps_perturbations_consistent():
    """One clearance joint: 9 coordinates, 7 constraints (2 degrees of freedom). A projected
    perturbation d satisfies J d = 0 for c = (Φ, Φ̇), the projection is idempotent, leaves the
    internal-state rows alone, and keeps a 4-dimensional space of (q, q̇) perturbations."""
    mech = jaxclear.mechanisms.slider_crank(clearance_joints="B")
    y = jaxclear.assemble(mech, 0.003)
    t = 0.003
    weights = mechanism_weights(mech)
    project = eqx.filter_jit(ConstraintProjection(mech, weights))  # compiled, not op by op
    n = mech.num_coordinates
    d = jax.random.normal(jax.random.PRNGKey(1), y.shape)
    p = project(y, t, d)

    def residual(x):
        return jnp.concatenate(
            [constraints(mech, x[:n], t), constraint_velocity(mech, x[:n], x[n:], t)]
        )

    jac = jax.jit(jax.jacfwd(residual))(y[: 2 * n])
    scale = float(jnp.linalg.norm(p[: 2 * n]))
    np.testing.assert_allclose(jac @ p[: 2 * n], 0.0, atol=PROJECTION_ATOL * scale)
    np.testing.assert_allclose(project(y, t, p), p, atol=PROJECTION_ATOL * scale)
    np.testing.assert_array_equal(p[2 * n :], d[2 * n :])
    basis = jax.vmap(lambda e: project(y, t, e))(jnp.eye(mech.state_size))[:, : 2 * n]
    assert np.linalg.matrix_rank(np.asarray(basis), tol=1e-8) == 2 * mech.degrees_of_freedom


@pytest.mark.slow
def test_one_clearance_joint_is_periodic_and_both_estimates_agree():
    """Joint B with clearance (hybrid law, LuGre friction) at 5000 rpm: the response settles on a
    stable periodic orbit (λ ≈ −480/s, about −5.8 per revolution, docs/chaos.md), and the tangent
    and two-trajectory estimates agree over two revolutions in sixths of a revolution (the
    two-trajectory separation must stay above the two solves' error difference, so the intervals
    are short). Measured at rtol 1e-10: −481/s and −461/s."""
    mech = jaxclear.mechanisms.slider_crank(clearance_joints="B")
    period = 60.0 / 5000.0
    options = dict(transient=2 * period, interval=period / 6)
    tangent = largest_lyapunov(mech, 4 * period, **options)
    pair = two_trajectory_lyapunov(mech, 4 * period, **options)
    assert bool(tangent.succeeded) and bool(pair.succeeded)
    assert float(tangent.exponent) < -100.0
    assert float(pair.exponent) == pytest.approx(float(tangent.exponent), rel=MECHANISM_AGREE)


def test_argument_errors(lorenz):
    y0 = jnp.array([1.0, 1.0, 20.0])
    with pytest.raises(ValueError, match="interval must be > 0"):
        flow_lyapunov(lorenz, y0, 10.0, interval=0.0)
    with pytest.raises(ValueError, match="leaves no interval"):
        flow_lyapunov(lorenz, y0, 1.0, interval=2.0)
    with pytest.raises(ValueError, match="transient"):
        flow_lyapunov(lorenz, y0, 10.0, interval=1.0, transient=-1.0)
    with pytest.raises(ValueError, match="method"):
        flow_lyapunov(lorenz, y0, 10.0, interval=1.0, method="qr")
    with pytest.raises(ValueError, match="weights"):
        flow_lyapunov(lorenz, y0, 10.0, interval=1.0, weights=[1.0, 1.0])
    with pytest.raises(ValueError, match="separation"):
        flow_lyapunov(lorenz, y0, 10.0, interval=1.0, separation=0.0)
    with pytest.raises(ValueError, match="t1 must be a concrete"):
        jax.jit(lambda t1: flow_lyapunov(lorenz, y0, t1, interval=1.0).exponent)(10.0)
    free = jaxclear.mechanisms.four_bar(rpm=None, clearance_joints="A")
    with pytest.raises(ValueError, match="interval"):
        two_trajectory_lyapunov(free, 1.0)
