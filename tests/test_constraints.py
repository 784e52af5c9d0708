"""Constraint Jacobian Φ_q and acceleration right-hand side γ against finite differences of Φ,
and constraint drift over a long run (docs/model.md §1)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import NUM_POINTS, central_difference_jvp

import jaxclear
from jaxclear.dynamics import constraint_jacobian, constraint_velocity, constraints, gamma
from jaxclear.mechanisms import four_bar, slider_crank


def _driver_angle(t, p):
    return p[0] * jnp.sin(p[1] * t) + p[2] * t


def _moving_guide_mechanism():
    """Slider–crank bodies with every joint type in a less special position: a translational joint
    whose guide is on a moving body (inclined axis, non-zero angle and offsets) and a
    time-dependent driver with Φ_tt ≠ 0, relative to another moving body."""
    base = slider_crank()
    joints = tuple(j for j in base.joints if j.name != "slider_guide") + (
        jaxclear.TranslationalJoint(
            "guide", "slider", (0.01, 0.02), "crank", (0.03, -0.01), axis=(0.6, 0.8), angle=0.3
        ),
    )
    driver = jaxclear.FunctionDriver(
        "crank", function=_driver_angle, parameters=jnp.array([0.3, 7.0, 2.0]), relative_to="rod"
    )
    return jaxclear.Mechanism(bodies=base.bodies, joints=joints, driver=driver, gravity=(0.0, 0.0))


MECHANISMS = {
    "slider_crank": slider_crank,
    "four_bar": four_bar,
    "moving_guide": _moving_guide_mechanism,
}
NUM_CONFIGURATIONS = 4  # random (q, q̇, t) per mechanism; Φ need not vanish there

JACOBIAN_ATOL = 1e-7
"""Central difference with step √ε ≈ 1.5e-8: round-off ≈ ε|Φ|/√ε ≈ 1e-8 for |Φ| ≲ 1; truncation
≈ √ε² |Φ'''| / 6 ≈ 1e-16. Entries of Φ_q are O(1) (lengths ≤ 0.3 m, unit entries). Measured <= 2e-9."""
GAMMA_STEP = 1e-3
"""Step in s for the 5-point second difference of Φ(q + s q̇, t + s): truncation h⁴/90 |Φ⁽⁶⁾| and
round-off ≈ 5ε|Φ|/h², both ≲ 1e-9 with |q̇| = O(1–10)."""
GAMMA_RTOL = 1e-7  # relative to max(1, max|γ|); measured <= 6e-9


def _random_state(mech, seed):
    rng = np.random.default_rng(seed)
    n = mech.num_coordinates
    q = np.zeros(n)
    qd = np.zeros(n)
    for k in range(len(mech.bodies)):
        q[3 * k : 3 * k + 2] = rng.uniform(-0.2, 0.2, 2)  # m
        q[3 * k + 2] = rng.uniform(-np.pi, np.pi)  # rad
        qd[3 * k : 3 * k + 2] = rng.normal(0.0, 2.0, 2)  # m/s
        qd[3 * k + 2] = rng.normal(0.0, 10.0)  # rad/s
    t = rng.uniform(0.0, 0.05)
    return jnp.asarray(q), jnp.asarray(qd), jnp.asarray(t)


CASES = [(name, seed) for name in MECHANISMS for seed in range(NUM_CONFIGURATIONS)]


@pytest.mark.parametrize("name,seed", CASES)
def test_constraint_jacobian_matches_finite_differences(name, seed):
    mech = MECHANISMS[name]()
    q, _, t = _random_state(mech, seed)
    jac = np.asarray(constraint_jacobian(mech, q, t))
    assert jac.shape == (mech.num_constraints, mech.num_coordinates)
    fd = np.stack(
        [
            np.asarray(
                central_difference_jvp(
                    lambda x: constraints(mech, x, t),
                    q,
                    jnp.eye(mech.num_coordinates)[k],
                    scale=1.0,
                )
            )
            for k in range(mech.num_coordinates)
        ],
        axis=1,
    )
    err = np.abs(jac - fd).max()
    print(f"{name} #{seed}: max |Φ_q - FD| = {err:.3g}")
    assert err < JACOBIAN_ATOL


def _path(mech, q, qd, t):
    return lambda s: np.asarray(constraints(mech, q + s * qd, t + s))


@pytest.mark.parametrize("name,seed", CASES)
def test_gamma_matches_second_difference_along_path(name, seed):
    """γ = −d²/ds² Φ(q + s q̇, t + s) at s = 0 (i.e. −(q̇ᵀΦ_qq q̇ + 2Φ_qt q̇ + Φ_tt)), and the second
    output Φ̇ = d/ds Φ(q + s q̇, t + s)."""
    mech = MECHANISMS[name]()
    q, qd, t = _random_state(mech, seed)
    gam, phi_dot = (np.asarray(x) for x in gamma(mech, q, qd, t))
    f = _path(mech, q, qd, t)
    h = GAMMA_STEP
    fm2, fm1, f0, fp1, fp2 = f(-2 * h), f(-h), f(0.0), f(h), f(2 * h)
    d2 = (-fp2 + 16 * fp1 - 30 * f0 + 16 * fm1 - fm2) / (12 * h**2)
    d1 = (-fp2 + 8 * fp1 - 8 * fm1 + fm2) / (12 * h)  # 5-point first derivative, error ~h⁴
    scale = max(1.0, np.abs(d2).max())
    err = np.abs(gam - (-d2)).max()
    print(f"{name} #{seed}: max |γ + d²Φ/ds²| = {err:.3g} (|γ| up to {np.abs(d2).max():.3g})")
    assert err < GAMMA_RTOL * scale
    np.testing.assert_allclose(phi_dot, d1, rtol=0, atol=GAMMA_RTOL * max(1.0, np.abs(d1).max()))
    np.testing.assert_allclose(
        np.asarray(constraint_velocity(mech, q, qd, t)), phi_dot, rtol=1e-13, atol=1e-13
    )


def test_time_terms_are_exercised():
    """The moving-guide case is not degenerate: Φ_t and Φ_tt are non-zero there."""
    mech = _moving_guide_mechanism()
    q, _, t = _random_state(mech, 0)
    zero = jnp.zeros_like(q)
    gam, phi_dot = gamma(mech, q, zero, t)  # q̇ = 0: Φ̇ = Φ_t and γ = −Φ_tt
    assert np.abs(np.asarray(phi_dot)).max() > 0.1
    assert np.abs(np.asarray(gam)).max() > 0.1


# --------------------------------------------------------------------------------------------
# Long run: Baumgarte keeps the drift bounded
# --------------------------------------------------------------------------------------------
RPM = 5000.0
OMEGA = RPM * 2 * np.pi / 60
PERIOD = 2 * np.pi / OMEGA
NUM_REVOLUTIONS = (
    200  # 2.4 s of motion, ~5400 Tsit5 steps: well past the Baumgarte settling time 1/α = 0.2 s
)
DRIFT_BOUND = 1e-4
"""m (or rad). With α = β = 5 1/s the constraint residual settles where Baumgarte's restoring
acceleration β²Φ balances the integrator's systematic error: measured 3.0e-5 m at rtol 1e-6 (it
scales as 1/β²: 3.4e-7 m with α = β = 50). Bound: about three times the settled value."""
VELOCITY_DRIFT_TOL = 1e-3  # m/s: 4e-5 of the crank-pin speed (26 m/s); measured 8e-5
SATURATION_RATIO = 1.05
"""Settled: the largest residual in the last quarter of the run exceeds the one in the third
quarter by at most 5 % (the Baumgarte transient, time constant 0.2 s = 17 revolutions, is over)."""
STRICT_DRIFT_TOL = (
    1e-5  # m: far below any clearance studied (>= 0.1 mm) and below penetrations (~1-30 µm)
)


@pytest.fixture(scope="module")
def long_run():
    t1 = NUM_REVOLUTIONS * PERIOD
    return jaxclear.simulate(slider_crank(rpm=RPM), t1, num_points=NUM_POINTS, solver="fast")


def test_constraint_violation_stays_bounded(long_run):
    assert bool(long_run.succeeded)
    viol = np.asarray(long_run.constraint_violation)
    vviol = np.asarray(long_run.velocity_violation)
    quarter = NUM_POINTS // 4
    third_q, last_q = viol[2 * quarter : 3 * quarter].max(), viol[3 * quarter :].max()
    print(
        f"{NUM_REVOLUTIONS} revolutions at {RPM:g} rpm in {int(long_run.num_steps)} steps: max |Φ| = {viol.max():.3g} "
        f"(third quarter {third_q:.3g}, last quarter {last_q:.3g}), max |Φ̇| = {vviol.max():.3g}"
    )
    assert viol.max() < DRIFT_BOUND
    assert vviol.max() < VELOCITY_DRIFT_TOL
    assert last_q < SATURATION_RATIO * third_q  # no secular growth


def test_long_run_stays_on_closed_form(long_run):
    """After 200 revolutions the slider is still where the closed form puts it (no phase drift).
    An axial offset ε of the rod at both pins moves B by up to 2ε, hence twice the drift bound."""
    r, ell = 0.05, 0.12
    th = OMEGA * np.asarray(long_run.t)
    xb = r * np.cos(th) + np.sqrt(ell**2 - r**2 * np.sin(th) ** 2)
    err = np.abs(np.asarray(long_run.coordinates("slider"))[:, 0] - xb).max()
    print(f"max |x_B - closed form| over {NUM_REVOLUTIONS} revolutions: {err:.3g} m")
    assert err < 2 * DRIFT_BOUND


def test_constraint_violation_below_strict_tolerance_over_50_revolutions(long_run):
    per_rev = (NUM_POINTS - 1) // NUM_REVOLUTIONS
    viol = np.asarray(long_run.constraint_violation)[: 50 * per_rev + 1]
    print(f"max |Φ| over the first 50 revolutions: {viol.max():.3g}")
    assert viol.max() < STRICT_DRIFT_TOL


ASSEMBLED_VELOCITY_TOLERANCE = 1e-10  # m/s: was 2.7e-6 with one regularised least-norm correction


@pytest.mark.parametrize("name", ["slider_crank", "four_bar"])  # moving_guide does not assemble
def test_assembled_velocities_satisfy_the_velocity_constraints(name):
    """Φ_q q̇ + Φ_t = 0 at the assembled state, to round-off (the reference data start exactly so)."""
    mech = MECHANISMS[name]()
    y0 = jaxclear.assemble(mech)
    n = mech.num_coordinates
    q, qd = y0[:n], y0[n : 2 * n]
    residual = constraint_velocity(mech, q, qd, 0.0)
    assert float(jnp.max(jnp.abs(residual))) < ASSEMBLED_VELOCITY_TOLERANCE


ASSEMBLY_DERIVATIVE_RTOL = 1e-6
"""dq0/dθ against central differences of the converged assembly (Newton to ~1e-15, relative step
1e-6 on a 0.3 m geometry: truncation ~1e-12, round-off ~1e-10 relative)."""
GUESS_DERIVATIVE_ATOL = 1e-6
"""dq0/d(initial guess) on a determined mechanism: nil but for the least-norm solve's
regularisation ε = 1e-9 relative (``RANK_TOLERANCE``; measured up to 4e-7 on the slider–crank)."""
COM_X = -5.9554e-3  # m: the second iterate of notebook 08's optimisation, rod_com_x in ±40 mm
ROUNDED_COM_X = -0.04 + 0.08 * float(jax.nn.sigmoid(jnp.log((COM_X + 0.04) / (0.04 - COM_X))))
"""m: rod_com_x = −5.9554 mm as a bounded fit variable gives it (through a sigmoid, so rounded
otherwise than the literal): there, differentiating the damped Newton loop itself gave
dq0/d(rod guess x) = 0.5 instead of ~0 and dq0/d(joint point x) half the true value (a step
length frozen by the loop's "never worse" test), and the sensitivity solve of a fit or an
optimisation then took 16x the steps to integrate that noise."""


def _rod_shifted(position_shift, point_shift):
    """The slider–crank with clearance at B, rod_com_x = ``ROUNDED_COM_X``, the rod's initial
    position guess and its joint point on the slider side shifted."""
    mech = jaxclear.with_parameters(
        slider_crank(clearance_joints="B"), {"rod_com_x": ROUNDED_COM_X}
    )
    mech = eqx.tree_at(
        lambda m: m.bodies[1].position, mech, mech.bodies[1].position + position_shift
    )
    return eqx.tree_at(lambda m: m.joints[1].point_j, mech, mech.joints[1].point_j + point_shift)


def test_assembled_positions_derivative_is_the_implicit_one():
    """q0's derivatives (``jaxclear.dynamics.assemble_state``) are the implicit function theorem's,
    whatever iterates the damped Newton loop took: nil along a body's initial guess (the
    slider–crank is determined), the converged central difference's along a joint point."""
    from jaxclear.dynamics import assemble_state

    @jax.jit
    def q0(shifts):
        return assemble_state(_rod_shifted(shifts[:3], shifts[3:]))[0]

    zero = jnp.zeros(5)
    derivative = np.asarray(jax.jacfwd(q0)(zero))
    assert np.max(np.abs(derivative[:, :3])) < GUESS_DERIVATIVE_ATOL
    h = 1e-6 * 0.3
    for k in (3, 4):
        step = jnp.zeros(5).at[k].set(h)
        central = np.asarray((q0(zero + step) - q0(zero - step)) / (2 * h))
        scale = np.max(np.abs(central))
        assert scale > 0.1
        np.testing.assert_allclose(derivative[:, k], central, atol=ASSEMBLY_DERIVATIVE_RTOL * scale)
