"""Contract and law-specific checks of the friction laws (docs/model.md §4)."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxclear.contact import Smoothing
from jaxclear.friction import (
    FRICTION_LAWS,
    Coulomb,
    LuGre,
    ModifiedCoulomb,
    NoFriction,
    friction_law_from_name,
)

SMOOTHING = Smoothing()
# Near-sharp |v| for comparisons with the unsmoothed Stribeck curve: relative bias (w/v)²/2.
SHARP = Smoothing(velocity_width=1e-9)
NAMES = list(FRICTION_LAWS)
NORMAL_FORCE = 250.0  # N
FN = jnp.asarray(NORMAL_FORCE)  # the laws take arrays (jaxtyping annotations)
SLIP_VELOCITIES = np.array(
    [-2.0, -0.3, -1e-2, -1e-3, -2e-4, -1e-5, 0.0, 1e-5, 2e-4, 1e-3, 1e-2, 0.3, 2.0]
)  # m/s
# Round-off allowance on the bound |F_T| <= μ_max F_N.
BOUND_RTOL = 1e-12
# Exact algebra against formulas written out here.
ALGEBRA_RTOL = 1e-12


def _steady_state(law, v, smoothing=SMOOTHING):
    """Internal state at constant slip v: LuGre's z_ss, nothing for stateless laws."""
    if isinstance(law, LuGre):
        return law.steady_state(v, smoothing)
    return law.initial_state()


@eqx.filter_jit
def _steady_forces(law, velocities, normal_force, smoothing):
    def one(v):
        v = jnp.asarray(v)
        state = _steady_state(law, v, smoothing)
        return (
            law.force(v, normal_force, state, smoothing),
            law.state_derivative(v, normal_force, state, smoothing),
        )

    return jax.vmap(one)(velocities)


def _max_coefficient(law) -> float:
    if isinstance(law, LuGre):
        return float(max(law.static_friction, law.kinetic_friction))
    if isinstance(law, NoFriction):
        return 0.0
    return float(law.friction_coefficient)


@pytest.fixture(scope="module", params=NAMES)
def law_and_steady(request):
    law = friction_law_from_name(request.param)
    forces, rates = _steady_forces(law, jnp.asarray(SLIP_VELOCITIES), FN, SMOOTHING)
    return request.param, law, np.asarray(forces), np.asarray(rates)


def test_contract_opposes_slip_and_is_bounded(law_and_steady):
    name, law, forces, rates = law_and_steady
    assert np.all(np.isfinite(forces)), name
    assert np.all(forces * SLIP_VELOCITIES <= 0.0), name
    bound = _max_coefficient(law) * NORMAL_FORCE
    assert np.all(np.abs(forces) <= bound * (1.0 + BOUND_RTOL)), name
    sliding = np.abs(SLIP_VELOCITIES) >= 1e-2
    if name != "none":
        assert np.all(np.abs(forces[sliding]) > 0.5 * bound), name  # fully developed friction
        assert forces[SLIP_VELOCITIES == 0.0] == 0.0, name
    assert rates.shape == (len(SLIP_VELOCITIES), law.num_states), name
    assert law.initial_state().shape == (law.num_states,), name
    np.testing.assert_allclose(rates, 0.0, atol=1e-12)  # steady states are steady


def test_contract_zero_without_normal_force(law_and_steady):
    name, law, _, _ = law_and_steady
    forces, _ = _steady_forces(law, jnp.asarray(SLIP_VELOCITIES), jnp.asarray(0.0), SMOOTHING)
    assert np.all(np.asarray(forces) == 0.0), name
    if law.num_states:  # also off the steady state
        z = jnp.asarray([3e-7])
        assert float(law.force(jnp.asarray(0.2), jnp.asarray(0.0), z, SMOOTHING)) == 0.0


@eqx.filter_jit
def _gradients(law, velocity, normal_force, state):
    def force(v, fn, z, law):
        return law.force(v, fn, z, SMOOTHING)

    def rate(v, fn, z, law):
        return jnp.sum(law.state_derivative(v, fn, z, SMOOTHING))

    return (
        jax.grad(force, argnums=(0, 1, 2, 3))(velocity, normal_force, state, law),
        jax.grad(rate, argnums=(0, 1, 2, 3))(velocity, normal_force, state, law),
    )


@pytest.mark.parametrize("state_value", [0.0, 1e-6])
def test_contract_finite_gradients_at_zero_slip(law_and_steady, state_value):
    name, law, _, _ = law_and_steady
    state = jnp.full((law.num_states,), state_value)
    for velocity in (0.0, 1e-12):
        grads = _gradients(law, jnp.asarray(velocity), FN, state)
        leaves = jax.tree_util.tree_leaves(eqx.filter(grads, eqx.is_inexact_array))
        assert leaves or name == "none"
        assert all(bool(jnp.all(jnp.isfinite(x))) for x in leaves), name


def test_contract_stiff_part_is_part_of_state_derivative(law_and_steady):
    # IMEX contract: state_derivative − stiff_state_derivative is the explicit part; for LuGre
    # the stiff part is the whole ż = v − σ0 |v| z/g(v) (relaxation and its forcing together),
    # so the explicit part is zero.
    name, law, _, _ = law_and_steady
    for v, z in ((0.0, 1e-6), (0.02, -3e-7), (-1.5, 2e-6)):
        v, state = jnp.asarray(v), jnp.full((law.num_states,), z)
        full = law.state_derivative(v, FN, state, SMOOTHING)
        stiff = law.stiff_state_derivative(v, state, SMOOTHING)
        assert stiff.shape == full.shape == (law.num_states,), name
        explicit = np.asarray(full - stiff)
        np.testing.assert_allclose(explicit, 0.0, atol=1e-15)


def test_coulomb_formula():
    law = Coulomb(friction_coefficient=0.2, velocity_tolerance=1e-3)
    for v in (-0.01, -1e-4, 0.0, 3e-4, 0.05):
        expected = -0.2 * NORMAL_FORCE * math.tanh(v / 1e-3)
        got = float(law.force(jnp.asarray(v), FN, law.initial_state(), SMOOTHING))
        np.testing.assert_allclose(got, expected, rtol=ALGEBRA_RTOL, atol=1e-300)
    # Default tolerance is the smoothing's velocity width.
    default = Coulomb(friction_coefficient=0.2)
    got = float(default.force(jnp.asarray(1e-5), FN, default.initial_state(), SMOOTHING))
    np.testing.assert_allclose(got, -0.2 * NORMAL_FORCE * math.tanh(1.0), rtol=ALGEBRA_RTOL)


def test_modified_coulomb_dynamic_correction_profile():
    law = ModifiedCoulomb(friction_coefficient=0.12)
    v0, v1 = 1e-4, 1e-3
    width = float(SMOOTHING.velocity_width)
    speeds = np.concatenate(
        [np.linspace(0.0, v0, 11), np.linspace(v0, v1, 91), [v1 + width, 2 * v1, 0.1, 3.0]]
    )
    for sign in (1.0, -1.0):
        forces, _ = _steady_forces(law, jnp.asarray(sign * speeds), FN, SMOOTHING)
        c_d = -np.asarray(forces) / (0.12 * NORMAL_FORCE * sign)
        assert np.all(c_d[speeds <= v0] == 0.0)
        np.testing.assert_allclose(c_d[speeds >= v1 + width], 1.0, rtol=ALGEBRA_RTOL)
        sharp = np.clip((speeds - v0) / (v1 - v0), 0.0, 1.0)
        # Rounded corners: smooth_ramp deviates from max(x, 0) by at most w/2 on each corner.
        assert np.all(np.abs(c_d - sharp) <= width / (v1 - v0) + 1e-12)
        assert np.all(np.diff(c_d) >= -1e-12)  # monotone in |v|


def _stribeck(v, law):
    return law.kinetic_friction + (law.static_friction - law.kinetic_friction) * math.exp(
        -((v / law.stribeck_velocity) ** 2)
    )


def test_lugre_steady_state_follows_stribeck_curve():
    law = LuGre()
    velocities = np.array([-1.0, -1e-2, -1e-3, -1e-4, 1e-4, 1e-3, 1e-2, 1.0])
    forces, rates = _steady_forces(law, jnp.asarray(velocities), FN, SHARP)
    expected = np.array(
        [-_stribeck(v, law) * NORMAL_FORCE * math.copysign(1.0, v) for v in velocities]
    )
    # Sharp |v| of width 1e-9 m/s: bias (w/v)²/2 <= 5e-11 at |v| >= 1e-4.
    np.testing.assert_allclose(np.asarray(forces), expected, rtol=1e-9)
    np.testing.assert_allclose(np.asarray(rates), 0.0, atol=1e-12)
    # Stribeck: static level at low speed, kinetic level when sliding.
    low, high = np.abs(np.asarray(forces))[[3, 7]]
    assert low > 0.95 * 0.15 * NORMAL_FORCE and abs(high - 0.1 * NORMAL_FORCE) < 1e-9


def test_lugre_formula_off_steady_state():
    law = LuGre(viscous_friction=0.05)
    width = float(SMOOTHING.velocity_width)
    for v, z in ((0.0, 2e-6), (3e-4, -1e-6), (-0.02, 1.5e-6)):
        g = _stribeck(v, law)
        z_dot = v - 1e5 * math.sqrt(v * v + width**2) * z / g
        sigma1 = 316.0 * math.exp(-((v / 1e-3) ** 2))
        expected = -(1e5 * z + sigma1 * z_dot + 0.05 * v) * NORMAL_FORCE
        state = jnp.asarray([z])
        np.testing.assert_allclose(
            float(law.state_derivative(jnp.asarray(v), FN, state, SMOOTHING)[0]),
            z_dot,
            rtol=ALGEBRA_RTOL,
        )
        np.testing.assert_allclose(
            float(law.force(jnp.asarray(v), FN, state, SMOOTHING)), expected, rtol=1e-10
        )


def test_lugre_relaxes_to_steady_state():
    # At constant v the z equation is linear: z → z_ss with rate σ0 |v| / g(v).
    law = LuGre()
    v = jnp.asarray(0.01)
    z_ss = float(law.steady_state(v, SMOOTHING)[0])
    rate = float(law.state_derivative(v, FN, jnp.asarray([0.0]), SMOOTHING)[0])
    np.testing.assert_allclose(rate, 0.01, rtol=ALGEBRA_RTOL)  # from rest, ż = v
    slope = float(law.state_derivative(v, FN, jnp.asarray([2 * z_ss]), SMOOTHING)[0]) / z_ss
    speed = math.sqrt(0.01**2 + float(SMOOTHING.velocity_width) ** 2)
    expected = -1e5 * speed / _stribeck(0.01, law)
    np.testing.assert_allclose(slope, expected, rtol=1e-9)


def test_unknown_friction_name_lists_valid_names():
    with pytest.raises(ValueError, match=r"unknown friction law 'lugr'.*'none'.*'lugre'"):
        friction_law_from_name("lugr")


@pytest.mark.parametrize(
    "name, params, match",
    [
        (
            "coulomb",
            {"friction_coefficient": -0.1},
            r"Coulomb: friction_coefficient must be >= 0, got -0.1",
        ),
        ("coulomb", {"velocity_tolerance": 0.0}, "velocity_tolerance"),
        ("modified-coulomb", {"lower_velocity": 1e-3, "upper_velocity": 1e-4}, "upper_velocity"),
        ("modified-coulomb", {"lower_velocity": -1e-4}, "lower_velocity"),
        ("lugre", {"bristle_stiffness": 0.0}, r"LuGre: bristle_stiffness must be > 0, got 0.0"),
        ("lugre", {"stribeck_velocity": -1e-3}, "stribeck_velocity"),
        ("lugre", {"kinetic_friction": 0.0}, "kinetic_friction"),
        (
            "lugre",
            {"bristle_damping": float("nan")},
            "LuGre: bristle_damping must be finite, got nan",
        ),
    ],
)
def test_bad_parameters_raise(name, params, match):
    with pytest.raises(ValueError, match=match):
        friction_law_from_name(name, **params)
