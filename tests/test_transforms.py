"""``jaxclear.simulate`` under JAX transformations, from the public API as users call it:
jit, vmap (and ``simulate_batch``), grad, jvp/jacfwd and their compositions; no recompile when
only parameter values change.

How compilations are counted: ``jax.monitoring`` reports an event
``/jax/core/compile/jaxpr_trace_duration`` each time a function is traced for jit and
``/jax/core/compile/backend_compile_duration`` each time XLA compiles one. A listener registered
around a call counts them; zero of each means every jitted function the call used (the
compiled solve, the jitted assembly, eager primitives) was served from the caches. A freshly
jitted function inside the same window shows the listener works.
"""

import collections
import contextlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import NUM_POINTS, central_difference_jvp, tree_allclose

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
from jaxclear.mechanisms import four_bar, slider_crank

RPM = 5000.0
OMEGA = RPM * 2 * np.pi / 60
PERIOD = 2 * np.pi / OMEGA
T1 = 2 * PERIOD
FAST = jaxclear.PRESETS["fast"]

SAME_RTOL = 1e-9
"""jit vs eager, vmap vs loop: the same arithmetic up to XLA fusion and batching, so round-off
differences that the adaptive controller can amplify only slightly (it takes the same steps)."""


def _compared(traj):
    return dict(
        q=traj.q,
        qd=traj.qd,
        qdd=traj.qdd,
        input_torque=traj.input_torque,
        reactions=traj.reactions,
        t_final=traj.t_final,
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
        return jaxclear.simulate(
            slider_crank(rpm=rpm, crank_mass=crank_mass), T1, num_points=NUM_POINTS, solver=FAST
        )

    jitted = run(jnp.asarray(RPM), jnp.asarray(0.30))
    assert bool(jitted.succeeded)
    assert int(jitted.num_steps) == int(eager.num_steps)
    a, b = _compared(jitted), _compared(eager)
    diff = {
        k: float(np.max(np.abs(np.asarray(a[k]) - np.asarray(b[k]))))
        for k in ("q", "qd", "qdd", "input_torque")
    }
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
    return jaxclear.simulate_batch(
        _build, params, T1, num_points=NUM_POINTS, solver="auto"
    )  # ideal joints: auto -> fast


def test_batch_matches_loop(batched):
    assert np.asarray(batched.succeeded).shape == (3,)
    assert np.all(np.asarray(batched.succeeded))
    for k in range(3):
        p = {name: float(v[k]) for name, v in BATCH.items()}
        single = jaxclear.simulate(_build(p), T1, num_points=NUM_POINTS, solver="fast")
        member = _compared(batched.member(k))
        err = float(np.max(np.abs(np.asarray(member["qdd"]) - np.asarray(single.qdd))))
        print(
            f"member {k} {p}: steps batch {int(batched.num_steps[k])} / loop {int(single.num_steps)}, max |Δq̈| = {err:.3g}"
        )
        assert int(batched.num_steps[k]) == int(single.num_steps)
        assert _close(member, _compared(single))


def test_member_is_a_single_trajectory(batched):
    member = batched.member(-1)
    assert np.shape(member.t_final) == () and member.q.shape == batched.q.shape[1:]
    assert float(member.mechanism.driver.speed) == pytest.approx(BATCH["rpm"][-1] * np.pi / 30)
    assert jaxclear.analysis.statistics(member)["peak_slider_acceleration"] > 0
    with pytest.raises(IndexError, match="outside the batch of 3"):
        batched.member(3)
    with pytest.raises(ValueError, match="one batch axis"):
        member.member(0)


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


def test_listener_sees_a_fresh_compilation():
    with count_compilations() as counts:
        jax.jit(lambda x: 2.0 * x + 1.0)(jnp.ones(3)).block_until_ready()
    assert counts[TRACE_EVENT] >= 1 and counts[COMPILE_EVENT] >= 1


def test_no_recompile_when_parameters_change(eager, batched):
    """New parameter values, a new end time and new batch values reuse the compiled code."""
    # the inputs are made outside the count: an eager jnp.array of a list compiles a conversion
    # the first time the process makes one of that shape, whatever simulate does
    params = {
        "rpm": jnp.array([1000.0, 3000.0, 4000.0]),
        "crank_mass": jnp.array([0.1, 0.2, 0.3]),
    }
    with count_compilations() as counts:
        mech = slider_crank(rpm=4321.0, crank_mass=0.37, rod_length=0.13, rod_inertia=3e-4)
        traj = jaxclear.simulate(mech, 1.5 * T1, num_points=NUM_POINTS, solver="fast")
        traj.q.block_until_ready()
        again = jaxclear.simulate_batch(
            _build, params, 0.5 * T1, num_points=NUM_POINTS, solver="fast"
        )
        again.q.block_until_ready()
    print(f"events during the second calls: {dict(counts)}")
    assert bool(traj.succeeded) and np.all(np.asarray(again.succeeded))
    assert counts[TRACE_EVENT] == 0
    assert counts[COMPILE_EVENT] == 0


# --------------------------------------------------------------------------------------------
# grad through simulate vs finite differences (short horizons, docs/model.md §5b)
# --------------------------------------------------------------------------------------------
STEPS_PER_REVOLUTION = 400
FIXED_STEP = jaxclear.SolverConfig(
    method="tsit5",
    rtol=1e-3,
    atol=1e-3,
    dt0=PERIOD / STEPS_PER_REVOLUTION,
    dtmax=PERIOD / STEPS_PER_REVOLUTION,
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
GRADIENT_EXTREMES = False
"""The two gradients of the ideal mechanisms below leave ``Trajectory.extremes`` out
(``extremes=False``, as fits do): it cuts their reverse-mode compilations by a third (measured
18 -> 11 s of CPU) and does not change the trajectory. Reverse and forward mode through the default
extremes tracking, contact peaks included, are the one-joint Jacobians further down."""


def test_grad_slider_position_wrt_rod_length():
    """d x_B(t1) / d l at t1 = T/8 (crank at 45°): reverse mode through assembly (Newton with
    pseudo-inverse) and the solve, vs central differences and vs the closed form
    ∂/∂l (r cos θ + √(l² − r² sin² θ)) = l / √(l² − r² sin² θ). The driven slider position is
    kinematic, so its derivative w.r.t. the rod mass (taken in the same pass) vanishes."""
    t1 = PERIOD / 8

    def slider_x(p):
        mech = slider_crank(rpm=RPM, rod_length=p["rod_length"], rod_mass=p["rod_mass"])
        traj = jaxclear.simulate(
            mech, t1, num_points=NUM_POINTS, solver=FIXED_STEP, extremes=GRADIENT_EXTREMES
        )
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
    print(
        f"d x_B/d l: grad {g:.12g}, FD {fd:.12g}, closed form {analytic:.12g}; d x_B/d m_rod = {float(grad['rod_mass']):.3g}"
    )
    assert float(value) == pytest.approx(
        r * np.cos(th) + np.sqrt(ell**2 - r**2 * np.sin(th) ** 2), rel=ANALYTIC_RTOL
    )
    assert g == pytest.approx(fd, rel=GRAD_RTOL)
    assert g == pytest.approx(analytic, rel=ANALYTIC_RTOL)
    assert abs(float(grad["rod_mass"])) < 1e-6  # m/kg; a 1e-6 m drift per kg would be visible


FREE_T1 = 0.25  # s: the free four-bar falls from rest through about 90° of crank angle
FREE_STEP = 1e-3  # s


def test_grad_free_four_bar_wrt_masses():
    """A genuinely dynamic gradient: the undriven four-bar released from rest under gravity; its
    crank angle at t1 depends on the link masses only through the equations of motion."""
    config = jaxclear.SolverConfig(
        method="tsit5", rtol=1e-3, atol=1e-3, dt0=FREE_STEP, dtmax=FREE_STEP
    )

    def crank_angle(masses):
        mech = four_bar(rpm=None, coupler_mass=masses["coupler"], rocker_mass=masses["rocker"])
        traj = jaxclear.simulate(
            mech, FREE_T1, num_points=NUM_POINTS, solver=config, extremes=GRADIENT_EXTREMES
        )
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
        fd = float(
            central_difference_jvp(value_only, p, direction, eps=FD_RELATIVE_STEP * float(p[name]))
        )
        print(f"d crank angle / d {name} mass: grad {float(grad[name]):.12g}, FD {fd:.12g}")
        assert abs(fd) > 1e-3  # not a trivially zero derivative
        assert float(grad[name]) == pytest.approx(fd, rel=GRAD_RTOL)


def test_vmap_of_simulate_matches_batch(batched):
    """``jax.vmap`` of the public ``simulate`` is what ``simulate_batch`` does; and
    ``simulate_batch`` itself can be jitted."""
    params = jax.tree_util.tree_map(jnp.asarray, BATCH)
    mapped = jax.vmap(
        lambda p: jaxclear.simulate(_build(p), T1, num_points=NUM_POINTS, solver=FAST)
    )(params)
    jitted = jax.jit(
        lambda p: jaxclear.simulate_batch(_build, p, T1, num_points=NUM_POINTS, solver=FAST)
    )(params)
    assert _close(_compared(mapped), _compared(batched))
    assert _close(_compared(jitted), _compared(batched))


# --------------------------------------------------------------------------------------------
# One clearance joint: the whole transform matrix through the public simulate
# --------------------------------------------------------------------------------------------
WINDOW = 3e-4
"""s: the journal at B (starting centred) flies free, hits the bearing wall (first impact near
0.2 ms, peak penetration ~78 µm) and rebounds inside this window."""
TIGHT = jaxclear.SolverConfig(method="tsit5", rtol=1e-10, atol=1e-13)
"""At the default rtol 1e-6 the derivative of the discrete solve is not the derivative of the
solution (step sizes are not differentiated and contact onsets move with rounding; issue 10).
At rtol 1e-10 over this window reverse mode, forward mode and converged central differences
agree to ~1e-4 (measured: d x_slider / d c = 1.77716 reverse, 1.77731 forward, 1.77729 FD)."""
ONE_JOINT = {
    "clearance": 5e-4,
    "slider_mass": 0.14,
    "restitution": 0.9,
    "friction_coefficient": 0.01,
    "rpm": RPM,
    "journal_speed": 0.0,
}
"""Parameters differentiated below: clearance (m), a mass (kg), restitution, friction
coefficient, crank speed (rpm; y0 stays the one assembled at 5000 rpm, so the driver's Baumgarte
terms pull the velocities in: still a smooth map) and the journal's initial velocity in y0 (m/s)."""
MODES_RTOL = 1e-3
"""Reverse vs forward mode vs central differences, relative to the largest entry of a column
(measured worst 1e-4; see TIGHT)."""
FD_RELATIVE_STEPS = (1e-3, 1e-4)
"""Central differences at two steps: their agreement shows convergence (measured 1e-6 apart)."""
JOURNAL_SPEED_STEPS = (1e-4, 5e-5)
"""m/s. The slider's initial velocity leaves the constraints' velocity level, so the Baumgarte
terms pull it back in; from ±2e-4 m/s on that transient stalls the TIGHT solve (inf); measured
with XLA's fusion emitters off, the central differences at 1e-4 / 5e-5 / 3e-5 m/s agree to 5
digits and at 1e-5 m/s are rounding-limited (0.08 % off)."""


def _one_joint(p):
    return slider_crank(
        rpm=p["rpm"],
        slider_mass=p["slider_mass"],
        clearance_joints="B",
        clearance=p["clearance"],
        friction_law=ModifiedCoulomb(p["friction_coefficient"]),
        contact_law=LankaraniNikravesh(restitution=p["restitution"]),
    )


@pytest.fixture(scope="module")
def one_joint_y0():
    """Assembled initial state (journal centred: the same for every parameter value here)."""
    return jaxclear.assemble(_one_joint(ONE_JOINT))


def _response(p, y0, adjoint="auto"):
    """Slider x and journal eccentricity x at the end of the window, m. ``journal_speed`` (m/s)
    is added to the slider's initial x velocity in y0, so the same function differentiates with
    respect to y0."""
    mechanism = _one_joint(p)
    n = mechanism.num_coordinates
    start = y0.at[n + 3 * mechanism.index("slider")].add(p["journal_speed"])
    traj = jaxclear.simulate(
        mechanism, WINDOW, num_points=3, solver=TIGHT, y0=start, adjoint=adjoint
    )
    return jnp.stack([traj.q[-1, 3 * mechanism.index("slider")], traj.clearance["B"]["ecc_x"][-1]])


CLEARANCES = np.array([ONE_JOINT["clearance"], 4.5e-4, 5.5e-4])
"""Clearances of the vmapped reverse-mode Jacobian, the nominal one first: its member 0 is the
reverse mode compared with forward mode and central differences below, so vmap, jit and reverse
mode share one compilation (an unbatched ``jacrev`` would be one more, ~40 s of CPU)."""


@pytest.fixture(scope="module")
def one_joint_derivatives(one_joint_y0):
    """Values and derivatives of the one-joint response, all jitted. (An eager call would be one
    compilation more, ~9 s of CPU: jit against eager is checked on the ideal mechanism by
    ``test_jit_matches_eager``, and for this clearance joint by tests/test_ensemble.py's
    ``test_members_equal_their_single_runs``, jitted vmapped members against eager single runs.)"""
    p = jax.tree_util.tree_map(jnp.asarray, ONE_JOINT)
    f = lambda q: _response(q, one_joint_y0)  # noqa: E731

    def with_value(q):
        # the discrete adjoint (diffrax's steps at TIGHT): half the cost of the default
        # sensitivities here (26 s against 54 s of compilation and solve on this machine); the
        # default reverse mode is checked at ordinary settings by tests/test_sensitivity.py
        value = _response(q, one_joint_y0, "discrete-reverse")
        return value, value

    batch = {**p, "clearance": jnp.asarray(CLEARANCES)}
    axes = {k: (0 if k == "clearance" else None) for k in p}
    mapped, values = jax.jit(jax.vmap(jax.jacrev(with_value, has_aux=True), in_axes=(axes,)))(batch)
    jitted = jax.jit(f)
    return dict(
        value=jitted(p),
        reverse=jax.tree_util.tree_map(lambda x: x[0], mapped),
        mapped=mapped,
        mapped_values=values,
        # diffrax's forward mode at TIGHT (the error-controlled sensitivities, the default, are
        # checked at the default settings by tests/test_sensitivity.py and by the eager jvp below)
        forward=jax.jit(jax.jacfwd(lambda q: _response(q, one_joint_y0, "discrete-forward")))(p),
        f=jitted,
        response=f,
        p=p,
    )


@pytest.mark.parametrize("name", list(ONE_JOINT))
def test_one_joint_reverse_forward_and_central_differences_agree(one_joint_derivatives, name):
    """jax.jacrev (member 0 of the fixture's vmapped Jacobian) and jax.jacfwd of the whole
    simulation agree with each other and with central differences that have converged (two steps
    a decade apart agree)."""
    d = one_joint_derivatives
    p, f = d["p"], d["f"]
    direction = {k: jnp.asarray(1.0 if k == name else 0.0) for k in p}
    steps = [r * abs(float(p[name])) for r in FD_RELATIVE_STEPS]
    if name == "journal_speed":  # 0 m/s, and bounded: see JOURNAL_SPEED_STEPS
        steps = JOURNAL_SPEED_STEPS
    fds = [np.asarray(central_difference_jvp(f, p, direction, eps=h)) for h in steps]
    reverse, forward = np.asarray(d["reverse"][name]), np.asarray(d["forward"][name])
    size = np.max(np.abs(fds[-1]))
    print(f"d/d {name}: reverse {reverse}, forward {forward}, FD {fds}")
    assert size > 0
    assert np.max(np.abs(fds[0] - fds[1])) <= MODES_RTOL * size  # the central difference converged
    assert np.max(np.abs(reverse - forward)) <= MODES_RTOL * size
    assert np.max(np.abs(forward - fds[-1])) <= MODES_RTOL * size
    assert np.max(np.abs(reverse - fds[-1])) <= MODES_RTOL * size


@pytest.mark.slow  # one more compilation (~35 s); jvp at the defaults: tests/test_sensitivity.py
def test_one_joint_jvp_unchanged(one_joint_derivatives, one_joint_y0):
    """An eager ``jax.jvp`` needs no option: simulate sees the forward-mode tracers and takes the
    error-controlled forward sensitivities (default ``adjoint="auto"``), which agree with the
    fixture's forward column (diffrax's forward mode at the same tight settings)."""
    d = one_joint_derivatives
    tangent = {k: jnp.asarray(1.0 if k == "clearance" else 0.0) for k in d["p"]}
    value, jvp = jax.jvp(lambda q: _response(q, one_joint_y0), (d["p"],), (tangent,))
    assert _close(value, d["value"])  # jitted; relative to the largest entry (slider x, ~0.17 m)
    assert _close(jvp, d["forward"]["clearance"], rtol=MODES_RTOL)


@pytest.mark.slow  # traces a whole solve (~30 s) for a message
def test_jvp_with_reverse_adjoint_names_the_forward_option(one_joint_y0):
    """jax.jvp through simulate(adjoint="reverse"): the error says what to pass. (With the default
    "auto", a jvp applied outside a jax.jit of the caller goes through a rule that serves both
    modes: tests/test_sensitivity.py, ``test_transformation_outside_a_jit``.)"""

    def slider_x(c):
        mechanism = _one_joint({**ONE_JOINT, "clearance": c})
        return jaxclear.simulate(
            mechanism, WINDOW, num_points=3, solver=TIGHT, adjoint="reverse"
        ).q[-1, 6]

    with pytest.raises(TypeError, match="needs adjoint='forward'"):
        jax.jvp(slider_x, (jnp.asarray(5e-4),), (jnp.asarray(1.0),))


def test_one_joint_jit_vmap_jacrev_equals_loop_and_central_differences(one_joint_derivatives):
    """``jit(vmap(jacrev))`` over clearances, one compilation: its values (``has_aux``) equal a
    loop of the jitted solve, and each member's derivative with respect to the clearance agrees
    with converged central differences of that loop at the member's clearance. Member 0 (the
    nominal clearance) is the reverse mode that
    ``test_one_joint_reverse_forward_and_central_differences_agree`` compares, every column, with
    forward mode too. (vmap without jit: ``test_batch_matches_loop`` here; with the clearance
    joint, ``slow``: tests/test_clearance_joint.py's ``test_batch_equals_loop``.)"""
    d = one_joint_derivatives
    direction = {k: jnp.asarray(1.0 if k == "clearance" else 0.0) for k in d["p"]}
    for k, c in enumerate(CLEARANCES.tolist()):
        # Python floats, as in the fixture's parameters: a NumPy scalar (or a step computed from
        # one) is not weakly typed, and the jitted solve would compile twice more (~5 s)
        p = {**d["p"], "clearance": jnp.asarray(c)}
        np.testing.assert_allclose(
            np.asarray(d["mapped_values"][k]), np.asarray(d["f"](p)), rtol=SAME_RTOL
        )
        fds = [
            np.asarray(central_difference_jvp(d["f"], p, direction, eps=r * c))
            for r in FD_RELATIVE_STEPS
        ]
        member = np.asarray(d["mapped"]["clearance"][k])
        size = np.max(np.abs(fds[-1]))
        print(f"clearance {c}: d/dc vmapped reverse {member}, FD {fds}")
        assert size > 0
        assert np.max(np.abs(fds[0] - fds[1])) <= MODES_RTOL * size  # converged
        assert np.max(np.abs(member - fds[-1])) <= MODES_RTOL * size


def test_one_joint_no_recompile_on_new_values(one_joint_derivatives):
    d = one_joint_derivatives
    with count_compilations() as counts:
        d["f"](
            {**d["p"], "clearance": jnp.asarray(4e-4), "slider_mass": jnp.asarray(0.2)}
        ).block_until_ready()
    assert counts[TRACE_EVENT] == 0 and counts[COMPILE_EVENT] == 0


@pytest.mark.slow  # two compilations of its own; the default suite covers both halves, see below
def test_eager_checks_stay_and_traced_failures_are_data():
    """Eagerly a failed solve raises SimulationError; the same call under jit returns the failure
    as data (``succeeded`` False, ``result`` not successful). In the default suite: the eager raise
    by tests/test_errors.py's ``test_simulation_error_gives_time_and_state`` (a starved Tsit5,
    "raise max_steps"), failures as data inside a compiled solve by tests/test_ensemble.py's
    ``test_failed_members_are_recorded_and_kept_out`` (a member that runs out of steps inside the
    jitted, vmapped chunk is recorded, not raised) and tests/test_errors.py's
    ``test_batched_failure_is_reported_per_member``."""
    starved = jaxclear.SolverConfig(method="tsit5", max_steps=5)
    mech = slider_crank(rpm=RPM)
    with pytest.raises(jaxclear.SimulationError, match="raise max_steps"):
        jaxclear.simulate(mech, T1, num_points=11, solver=starved)
    traj = jax.jit(lambda m: jaxclear.simulate(m, T1, num_points=11, solver=starved))(mech)
    assert not bool(traj.succeeded)
    assert int(traj.input_error) == 0
