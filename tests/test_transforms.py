"""``simulate`` under JAX transformations: jit, vmap (``simulate_batch``), grad; and no recompile
when only parameter values change.

How compilations are counted: ``jax.monitoring`` reports an event
``/jax/core/compile/jaxpr_trace_duration`` each time a function is traced for jit and
``/jax/core/compile/backend_compile_duration`` each time XLA compiles one. A listener registered
around a call counts them; zero of each means every jitted function the call used (the
``eqx.filter_jit`` core, the jitted assembly, eager primitives) was served from the caches. A freshly
jitted function inside the same window shows the listener works. As a second, equinox-specific
view, the core's own cache (``_simulate_core._cached._cache_size()``) must not grow.
"""

import collections
import contextlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import NUM_POINTS, central_difference_jvp, tree_allclose

import jaxclear
from jaxclear._simulate import _simulate_core
from jaxclear.mechanisms import four_bar, slider_crank

RPM = 5000.0
OMEGA = RPM * 2 * np.pi / 60
PERIOD = 2 * np.pi / OMEGA
T1 = 2 * PERIOD
FAST = jaxclear.PRESETS["fast"]

SAME_RTOL = 1e-9
"""jit vs eager, vmap vs loop: the same arithmetic up to XLA fusion and batching, so round-off
differences that the adaptive controller can amplify only slightly (it takes the same steps)."""


def _grid(t1=T1):
    return jnp.linspace(0.0, t1, NUM_POINTS)


def _compared(traj):
    return dict(
        q=traj.q, qd=traj.qd, qdd=traj.qdd, input_torque=traj.input_torque, reactions=traj.reactions, t_final=traj.t_final
    )


def _close(a, b, rtol=SAME_RTOL):
    """Leaf-wise closeness relative to each leaf's largest magnitude."""
    ok = True
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        x, y = np.asarray(x), np.asarray(y)
        scale = max(np.abs(x).max(), 1e-300)
        err = np.abs(x - y).max()
        ok &= err <= rtol * scale
    return ok


@pytest.fixture(scope="module")
def eager():
    return jaxclear.simulate(slider_crank(rpm=RPM), T1, num_points=NUM_POINTS, solver="fast")


# --------------------------------------------------------------------------------------------
# jit
# --------------------------------------------------------------------------------------------
def test_jit_matches_eager(eager):
    """The whole pipeline (mechanism built from traced parameters, assembly, solve, outputs)
    under ``jax.jit`` gives the eager ``simulate`` result."""

    @jax.jit
    def run(rpm, crank_mass):
        mech = slider_crank(rpm=rpm, crank_mass=crank_mass)
        return _simulate_core(mech, _grid(), jnp.asarray(0.0), jnp.asarray(T1), None, FAST, False)

    jitted = run(jnp.asarray(RPM), jnp.asarray(0.30))
    assert bool(jitted.succeeded)
    assert int(jitted.num_steps) == int(eager.num_steps)
    a, b = _compared(jitted), _compared(eager)
    diff = {k: float(np.max(np.abs(np.asarray(a[k]) - np.asarray(b[k])))) for k in ("q", "qd", "qdd", "input_torque")}
    print(f"jit vs eager, max abs differences: {diff}")
    assert _close(a, b)
    assert tree_allclose(jitted.mechanism, eager.mechanism, rtol=1e-14, atol=0.0)


# --------------------------------------------------------------------------------------------
# vmap
# --------------------------------------------------------------------------------------------
BATCH = {"rpm": np.array([2000.0, 5000.0, 6000.0]), "crank_mass": np.array([0.30, 0.45, 0.20])}


def _build(p):
    return slider_crank(rpm=p["rpm"], crank_mass=p["crank_mass"])


@pytest.fixture(scope="module")
def batched():
    params = jax.tree_util.tree_map(jnp.asarray, BATCH)
    return jaxclear.simulate_batch(_build, params, T1, num_points=NUM_POINTS, solver="auto")  # ideal joints: auto -> fast


def test_batch_matches_loop(batched):
    assert np.asarray(batched.succeeded).shape == (3,)
    assert np.all(np.asarray(batched.succeeded))
    for k in range(3):
        p = {name: float(v[k]) for name, v in BATCH.items()}
        single = jaxclear.simulate(_build(p), T1, num_points=NUM_POINTS, solver="fast")
        member = jax.tree_util.tree_map(lambda x: x[k], _compared(batched))
        err = float(np.max(np.abs(np.asarray(member["qdd"]) - np.asarray(single.qdd))))
        print(f"member {k} {p}: steps batch {int(batched.num_steps[k])} / loop {int(single.num_steps)}, max |Δq̈| = {err:.3g}")
        assert int(batched.num_steps[k]) == int(single.num_steps)
        assert _close(member, _compared(single))


def test_batch_members_differ_physically(batched):
    """Not a broadcast of one member: the slider acceleration at outer dead centre,
    −r ω² (1 + r/l), scales as ω²."""
    a = np.asarray(batched.qdd)[:, :, 6]
    ratio = a.min(axis=1) / a.min(axis=1)[1]
    np.testing.assert_allclose(ratio, (BATCH["rpm"] / 5000.0) ** 2, rtol=1e-4)


# --------------------------------------------------------------------------------------------
# No recompilation when only parameter values change
# --------------------------------------------------------------------------------------------
TRACE_EVENT = "/jax/core/compile/jaxpr_trace_duration"
COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"


@contextlib.contextmanager
def count_compilations():
    counts = collections.Counter()

    def listener(event, duration, **kwargs):
        counts[event] += 1

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield counts
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def _core_cache_size():
    cached = getattr(_simulate_core, "_cached", None)
    return cached._cache_size() if hasattr(cached, "_cache_size") else None


def test_listener_sees_a_fresh_compilation():
    with count_compilations() as counts:
        jax.jit(lambda x: 2.0 * x + 1.0)(jnp.ones(3)).block_until_ready()
    assert counts[TRACE_EVENT] >= 1 and counts[COMPILE_EVENT] >= 1


def test_no_recompile_when_parameters_change(eager, batched):
    """New parameter values, a new end time and new batch values reuse the compiled code."""
    size_before = _core_cache_size()
    with count_compilations() as counts:
        mech = slider_crank(rpm=4321.0, crank_mass=0.37, rod_length=0.13, rod_inertia=3e-4)
        traj = jaxclear.simulate(mech, 1.5 * T1, num_points=NUM_POINTS, solver="fast")
        traj.q.block_until_ready()
        params = {"rpm": jnp.array([1000.0, 3000.0, 4000.0]), "crank_mass": jnp.array([0.1, 0.2, 0.3])}
        again = jaxclear.simulate_batch(_build, params, 0.5 * T1, num_points=NUM_POINTS, solver="fast")
        again.q.block_until_ready()
    print(f"events during the second calls: {dict(counts)}; core cache size {size_before} -> {_core_cache_size()}")
    assert bool(traj.succeeded) and np.all(np.asarray(again.succeeded))
    assert counts[TRACE_EVENT] == 0
    assert counts[COMPILE_EVENT] == 0
    assert _core_cache_size() == size_before


# --------------------------------------------------------------------------------------------
# grad through simulate vs finite differences (short horizons, MODEL.md §5b)
# --------------------------------------------------------------------------------------------
STEPS_PER_REVOLUTION = 400
FIXED_STEP = jaxclear.SolverConfig(
    method="tsit5", rtol=1e-3, atol=1e-3, dt0=PERIOD / STEPS_PER_REVOLUTION, dtmax=PERIOD / STEPS_PER_REVOLUTION
)
"""Tsit5 at a constant step T/400 (the local error, ~(ωh)⁵ ≈ 1e-9, never trips the loose
tolerances, so dtmax fixes every step): the discrete solution is then a smooth function of the
parameters and its finite differences converge to what reverse mode computes. Adaptive step
selection would add a piecewise-constant dependence (the accepted step sizes) that finite
differences see and gradients do not."""
FD_RELATIVE_STEP = 1e-5
"""Central differences of a smooth map with relative step 1e-5: truncation ~1e-10 relative;
round-off of the ~1e-15-accurate solutions ~1e-15 / 1e-5 = 1e-10. (√ε steps would let the
solve's accumulated round-off dominate.)"""
GRAD_RTOL = 1e-7  # grad vs FD of the same discrete map; measured <= 5e-10
ANALYTIC_RTOL = 1e-6
"""Value and gradient vs the closed form: the fixed-step solve (50 steps of ωh = 0.016 rad, local
error ~(ωh)⁵) is accurate to ~3e-8 relative (measured)."""


def test_grad_slider_position_wrt_rod_length():
    """d x_B(t1) / d l at t1 = T/8 (crank at 45°): reverse mode through assembly (Newton with
    pseudo-inverse) and the solve, vs central differences and vs the closed form
    ∂/∂l (r cos θ + √(l² − r² sin² θ)) = l / √(l² − r² sin² θ). The driven slider position is
    kinematic, so its derivative w.r.t. the rod mass (taken in the same pass) vanishes."""
    t1 = PERIOD / 8
    grid = jnp.linspace(0.0, t1, NUM_POINTS)

    def slider_x(p):
        mech = slider_crank(rpm=RPM, rod_length=p["rod_length"], rod_mass=p["rod_mass"])
        traj = _simulate_core(mech, grid, jnp.asarray(0.0), jnp.asarray(t1), None, FIXED_STEP, False)
        return traj.q[-1, 6], (traj.num_steps, traj.num_rejected_steps)

    value_and_grad = jax.jit(jax.value_and_grad(slider_x, has_aux=True))
    ell = 0.12
    p = {"rod_length": jnp.asarray(ell), "rod_mass": jnp.asarray(0.21)}
    (value, (steps, rejected)), grad = value_and_grad(p)
    assert int(rejected) == 0 and int(steps) == STEPS_PER_REVOLUTION // 8

    def value_only(x):
        return value_and_grad(x)[0][0]

    direction = {"rod_length": jnp.asarray(1.0), "rod_mass": jnp.asarray(0.0)}
    fd = float(central_difference_jvp(value_only, p, direction, eps=FD_RELATIVE_STEP * ell))
    r, th = 0.05, OMEGA * t1
    analytic = ell / np.sqrt(ell**2 - r**2 * np.sin(th) ** 2)
    g = float(grad["rod_length"])
    print(f"d x_B/d l: grad {g:.12g}, FD {fd:.12g}, closed form {analytic:.12g}; d x_B/d m_rod = {float(grad['rod_mass']):.3g}")
    assert float(value) == pytest.approx(r * np.cos(th) + np.sqrt(ell**2 - r**2 * np.sin(th) ** 2), rel=ANALYTIC_RTOL)
    assert g == pytest.approx(fd, rel=GRAD_RTOL)
    assert g == pytest.approx(analytic, rel=ANALYTIC_RTOL)
    assert abs(float(grad["rod_mass"])) < 1e-6  # m/kg; a 1e-6 m drift per kg would be visible


FREE_T1 = 0.25  # s: the free four-bar falls from rest through about 90° of crank angle
FREE_STEP = 1e-3  # s


def test_grad_free_four_bar_wrt_masses():
    """A genuinely dynamic gradient: the undriven four-bar released from rest under gravity; its
    crank angle at t1 depends on the link masses only through the equations of motion."""
    config = jaxclear.SolverConfig(method="tsit5", rtol=1e-3, atol=1e-3, dt0=FREE_STEP, dtmax=FREE_STEP)
    grid = jnp.linspace(0.0, FREE_T1, NUM_POINTS)

    def crank_angle(masses):
        mech = four_bar(rpm=None, coupler_mass=masses["coupler"], rocker_mass=masses["rocker"])
        traj = _simulate_core(mech, grid, jnp.asarray(0.0), jnp.asarray(FREE_T1), None, config, False)
        return traj.q[-1, 2], (traj.num_steps, traj.num_rejected_steps)

    value_and_grad = jax.jit(jax.value_and_grad(crank_angle, has_aux=True))
    p = {"coupler": jnp.asarray(0.5), "rocker": jnp.asarray(0.4)}
    (value, (steps, rejected)), grad = value_and_grad(p)
    assert int(rejected) == 0 and int(steps) == round(FREE_T1 / FREE_STEP)
    assert abs(float(value) - np.pi / 3) > 0.5  # it moved

    def value_only(x):
        return value_and_grad(x)[0][0]

    for name in p:
        direction = {k: jnp.asarray(1.0 if k == name else 0.0) for k in p}
        fd = float(central_difference_jvp(value_only, p, direction, eps=FD_RELATIVE_STEP * float(p[name])))
        print(f"d crank angle / d {name} mass: grad {float(grad[name]):.12g}, FD {fd:.12g}")
        assert abs(fd) > 1e-3  # not a trivially zero derivative
        assert float(grad[name]) == pytest.approx(fd, rel=GRAD_RTOL)
