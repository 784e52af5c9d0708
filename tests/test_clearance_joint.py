"""Revolute clearance joint in the slider–crank: limits, energy, gradients, batching, bad input.

One static configuration (clearance at B, Lankarani–Nikravesh with an explicit stiffness, no
friction, Tsit5) is compiled once per module and shared: clearance, stiffness and restitution are
array leaves, so changing them does not recompile.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear import ClearanceJoint
from jaxclear.analysis import drive_work, kinetic_energy
from jaxclear.contact import ContactGeometry, Hybrid, LankaraniNikravesh, Smoothing
from jaxclear.dynamics import _clearance as clearance
from jaxclear.friction import LuGre, NoFriction
from jaxclear.mechanisms import slider_crank
from jaxclear.solve import assemble

RPM = 5000.0
OMEGA = RPM * 2 * np.pi / 60
PERIOD = 2 * np.pi / OMEGA
HERTZ_K = float(ContactGeometry(0.01, 0.0095).hertz_stiffness)
NUM_POINTS = 4001  # one output grid for the whole module: a new length would recompile
SOLVER = jaxclear.SolverConfig(method="tsit5", rtol=1e-8, atol=1e-11, max_steps=400_000)
EXTREMES = False
"""The solves here leave ``Trajectory.extremes`` out: the checks read the trajectory, which the
extremes tracking does not change, and a compilation takes about 40 % less CPU without it
(measured 9.4 -> 5.7 s for a Tsit5 solve of this joint). tests/test_signals.py shares the
setting (and so the compiled solve, in a worker that ran both modules)."""


def build(clearance, stiffness, restitution):
    return slider_crank(
        rpm=RPM,
        clearance_joints="B",
        clearance=clearance,
        contact_law=LankaraniNikravesh(stiffness=stiffness, restitution=restitution),
        friction_law=NoFriction(),
    )


def run(clearance, stiffness=HERTZ_K, restitution=0.9, revolutions=1.0):
    return jaxclear.simulate(
        build(clearance, stiffness, restitution),
        revolutions * PERIOD,
        num_points=NUM_POINTS,
        solver=SOLVER,
        extremes=EXTREMES,
    )


def closed_form_slider(t, crank=0.05, rod=0.12):
    th = OMEGA * t
    root = np.sqrt(rod**2 - (crank * np.sin(th)) ** 2)
    x = crank * np.cos(th) + root
    return x


# --- clearance -> 0 with stiff contact recovers the ideal joint ------------------------------------
LIMIT_CASES = [(1e-4, 1.0), (1e-5, 10.0), (1e-6, 100.0)]  # (clearance m, stiffness / Hertz K)
LIMIT_POSITION_TOL = 5e-6  # m: journal offset c + δ ≈ 1 µm + 0.6 µm at the tightest case


@pytest.fixture(scope="module")
def limit_runs():
    return [run(c, k * HERTZ_K, restitution=0.5) for c, k in LIMIT_CASES]


def test_small_clearance_approaches_ideal(limit_runs):
    errors, accel_errors = [], []
    for traj in limit_runs:
        t = np.asarray(traj.t)
        x = np.asarray(traj.coordinates("slider")[:, 0])
        errors.append(np.max(np.abs(x - closed_form_slider(t))))
        a = np.asarray(traj.accelerations("slider")[:, 0])
        a_ideal = np.gradient(np.gradient(closed_form_slider(t), t), t)
        inner = slice(5, -5)  # np.gradient is one-sided at the ends
        accel_errors.append(
            np.sqrt(np.mean((a - a_ideal)[inner] ** 2)) / np.sqrt(np.mean(a_ideal[inner] ** 2))
        )
    print("max |x - x_ideal| per case (m):", errors, "relative RMS accel error:", accel_errors)
    assert all(e1 > e2 for e1, e2 in zip(errors, errors[1:])), errors
    assert errors[-1] < LIMIT_POSITION_TOL
    assert accel_errors[-1] < accel_errors[0]


# --- energy: frictionless, elastic contact conserves energy up to the drive's work -------------------
ENERGY_REL_TOL = (
    2e-3  # of the peak kinetic energy; the trapezoid drive work on a 4000-point grid dominates
)


@pytest.fixture(scope="module")
def elastic_run():
    mech = slider_crank(
        rpm=RPM,
        clearance_joints="B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(stiffness=HERTZ_K, restitution=1.0),
        friction_law=NoFriction(),
    )
    return jaxclear.simulate(
        mech, 0.5 * PERIOD, num_points=NUM_POINTS, solver=SOLVER, extremes=EXTREMES
    )


def test_elastic_frictionless_energy_balance(elastic_run):
    traj = elastic_run
    pen = np.asarray(traj.clearance["B"]["penetration"])
    assert np.any(pen > 0), "the run must contain impacts for the balance to mean anything"
    free = pen < 0  # contact potential energy is zero in free flight
    kinetic = np.asarray(kinetic_energy(traj))
    balance = kinetic - kinetic[0] - drive_work(traj)
    scale = kinetic.max()
    worst = np.max(np.abs(balance[free])) / scale
    print(f"energy balance error in free flight: {worst:.2e} of peak kinetic energy {scale:.2f} J")
    assert worst < ENERGY_REL_TOL


# --- finite gradients at e = 0, δ = 0, v_T = 0 --------------------------------------------------------
@pytest.mark.parametrize(
    "law", [LankaraniNikravesh(), Hybrid()], ids=["lankarani-nikravesh", "hybrid"]
)
def test_finite_jacobians_at_singular_points(law):
    mech = slider_crank(clearance_joints="B", contact_law=law, friction_law=LuGre())
    y0 = assemble(mech)
    joint = mech.clearance_joints[0]
    n = mech.num_coordinates
    q, qd = y0[:n], y0[n : 2 * n]
    state = y0[2 * n :]
    c = float(joint.geometry.clearance)
    slider = 3 * mech.index("slider")

    def force(q, qd, state):
        return clearance.generalized_force(joint, mech.index, q, qd, state)

    cases = {
        "centred (e = 0)": q,
        "touching (δ = 0)": q.at[slider].add(c),
        "penetrating, no slip": q.at[slider].add(c + 1e-6),
    }
    jacobians = jax.jit(jax.jacfwd(force, argnums=(0, 1, 2)))  # compiled once: cheaper than eager
    for label, qq in cases.items():
        for jac in jacobians(qq, qd * 0.0, state):
            assert np.all(np.isfinite(np.asarray(jac))), label


# --- gradient through a simulation against central finite differences -------------------------------
GRAD_HORIZON = (
    0.05 * PERIOD
)  # short: contains the first impact (≈75 µm) but not the chaotic long run
GRAD_SOLVER = jaxclear.SolverConfig(method="tsit5", rtol=1e-11, atol=1e-14, max_steps=100_000)
GRAD_FD_STEP = (
    1e-7  # m: central differences of the adaptive solve agree to 2e-6 for h = 1e-6 .. 1e-8
)
GRAD_REL_TOL = (
    2e-3  # measured 7e-4: the discrete adjoint does not differentiate step-size selection.
)
# (A fixed-step solve is no better here: steps longer than the 0.1 µm smoothing widths make the
# discrete map wiggle on that scale, and its exact gradient was off by 20 %.)


@pytest.mark.slow  # its own reverse-mode compilation; see the docstring
def test_gradient_wrt_clearance_matches_finite_difference():
    """Reverse mode through a tight frictionless solve vs central differences. The default suite
    checks the same property in tests/test_transforms.py
    (``test_one_joint_reverse_forward_and_central_differences_agree[clearance]``: reverse and forward
    mode vs converged central differences of d ecc_x/dc and d x_slider/dc through the first impact,
    to 1e-3) and tests/test_gradient_settings.py (reverse mode at the gradient settings, 1 ms)."""
    ts = jnp.linspace(0.0, GRAD_HORIZON, 8)

    def final_eccentricity(clearance):
        traj = jaxclear.simulate(
            build(clearance, HERTZ_K, 0.9), GRAD_HORIZON, ts=ts, solver=GRAD_SOLVER
        )
        return traj.clearance["B"]["ecc_x"][-1]

    c0 = 5e-4
    grad = float(jax.grad(final_eccentricity)(c0))
    h = GRAD_FD_STEP
    fd = float((final_eccentricity(c0 + h) - final_eccentricity(c0 - h)) / (2 * h))
    print(f"d ecc_x / d c: grad {grad:.6g}, central difference {fd:.6g}")
    assert np.isfinite(grad)
    assert abs(grad - fd) <= GRAD_REL_TOL * max(abs(fd), 1e-3)


# --- vmap over clearance equals a loop ---------------------------------------------------------------
@pytest.mark.slow  # its own vmapped compilation (12 s of CPU); covered in the default suite, see below
def test_batch_equals_loop(limit_runs):
    """``simulate_batch`` over clearance and stiffness equals the single runs. In the default suite:
    members of vmapped solves of the clearance joint at B equal their single runs in
    tests/test_ensemble.py (``test_members_equal_their_single_runs``,
    ``test_chunks_spread_over_two_devices_give_the_same_members``), eager ``simulate_batch`` equals a
    loop in tests/test_transforms.py (``test_batch_matches_loop``) and ``jit(vmap(jacrev))`` of the
    one-joint slider–crank equals a loop of its jitted solve there
    (``test_one_joint_jit_vmap_jacrev_equals_loop_and_central_differences``)."""
    clearances = jnp.array([c for c, _ in LIMIT_CASES[:2]])
    stiffness = jnp.array([k * HERTZ_K for _, k in LIMIT_CASES[:2]])
    batch = jaxclear.simulate_batch(
        lambda p: build(p[0], p[1], 0.5),
        (clearances, stiffness),
        PERIOD,
        num_points=NUM_POINTS,
        solver=SOLVER,
    )
    assert np.all(np.asarray(batch.succeeded))
    for k in range(2):
        np.testing.assert_allclose(batch.q[k], limit_runs[k].q, rtol=0, atol=1e-9)


BACKEND_COMPILE_EVENT = (
    "/jax/core/compile/backend_compile_duration"  # one event per XLA compilation
)


def test_no_recompile_for_new_clearance(limit_runs):
    compilations = []

    def listener(event, duration, **kwargs):
        if event == BACKEND_COMPILE_EVENT:
            compilations.append(duration)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        run(2e-4, HERTZ_K, 0.5, revolutions=0.1)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert not compilations


# --- bad input ----------------------------------------------------------------------------------------
def _revolute():
    return jaxclear.RevoluteJoint("B", "rod", (0.06, 0.0), "slider", (0.0, 0.0))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(geometry=ContactGeometry(0.01, 0.01)), "journal_radius"),
        (dict(geometry=ContactGeometry(0.01, 0.011)), "journal_radius"),
        (dict(clearance=0.0), "clearance must be > 0"),
        (dict(clearance=-1e-4), "clearance must be > 0"),
        (dict(geometry=ContactGeometry(0.01, 0.0095, bearing_poisson=0.5)), "bearing_poisson"),
        (dict(geometry=ContactGeometry(0.01, 0.0095, journal_poisson=0.0)), "journal_poisson"),
        (dict(geometry=ContactGeometry(0.01, 0.0095, bearing_young=-1.0)), "bearing_young"),
        (dict(smoothing=Smoothing(penetration_width=0.0)), "penetration_width"),
        (dict(smoothing=Smoothing(velocity_width=-1.0)), "velocity_width"),
        (dict(initial_eccentricity=(1e-3, 0.0)), "initial_eccentricity"),
    ],
)
def test_bad_clearance_joint_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ClearanceJoint.replacing(_revolute(), **kwargs)


def test_bad_law_parameters_and_names():
    with pytest.raises(ValueError, match="stiffness"):
        LankaraniNikravesh(stiffness=-1.0)
    with pytest.raises(ValueError, match="restitution"):
        LankaraniNikravesh(restitution=1.5)
    with pytest.raises(ValueError, match="restitution"):
        LankaraniNikravesh(restitution=0.0)
    with pytest.raises(ValueError, match="m1|gauss"):
        Hybrid(num_gauss_points=0)
    with pytest.raises(ValueError, match="m2|elements"):
        Hybrid(num_elements=0)
    with pytest.raises(ValueError, match="unknown|Unknown"):
        jaxclear.contact.contact_law_from_name("hertzian")
    with pytest.raises(ValueError, match="unknown|Unknown"):
        jaxclear.friction.friction_law_from_name("stribeck")
    with pytest.raises(jaxclear.ModelError, match="among O, A, B"):
        slider_crank(clearance_joints="C")
    with pytest.raises(TypeError, match="unknown option"):
        slider_crank(clearance_joints="B", clearence=1e-4)


def test_clearance_joint_outputs_and_tree_at():
    mech = build(5e-4, HERTZ_K, 0.9)
    # clearance is an array leaf reachable by eqx.tree_at (what identification differentiates)
    leaf = eqx.tree_at(lambda m: m.clearance_joints[0].geometry.journal_radius, mech, 0.0099)
    assert float(leaf.clearance_joints[0].geometry.clearance) == pytest.approx(1e-4)
    assert mech.degrees_of_freedom == 2


# --- which body carries the pin ----------------------------------------------------------------------
SWAP_HORIZON = (
    0.05 * PERIOD
)  # contains the first impact at B (≈75 µs) and the contact phase after it
SWAP_ECCENTRICITY_TOL = 1e-9  # m: the two descriptions differ only in rounding (clearance 5e-4 m)
SWAP_FORCE_REL_TOL = 1e-6  # of the peak normal force, same reason


def test_journal_body_choice_mirrors_the_joint():
    """Pin on the rod at B instead of on the slider: the same physical joint seen from the other side.

    With a point contact law and no friction the force acts along the line of centres, so moving
    the pin to the other body changes only the sign of the eccentricity vector; motion, penetration
    and normal force are the same at the same instant.
    """
    ts = jnp.linspace(0.0, SWAP_HORIZON, NUM_POINTS)
    runs = {}
    for journal in ("slider", "rod"):
        mech = slider_crank(
            rpm=RPM,
            clearance_joints={"B": {"journal_body": journal}},
            clearance=5e-4,
            contact_law=LankaraniNikravesh(stiffness=HERTZ_K, restitution=0.9),
            friction_law=NoFriction(),
        )
        joint = mech.clearance_joints[0]
        assert joint.journal_body == journal
        assert joint.bearing_body == ({"slider", "rod"} - {journal}).pop()
        runs[journal] = jaxclear.simulate(
            mech, SWAP_HORIZON, ts=ts, solver=SOLVER, extremes=EXTREMES
        )
    default, swapped = runs["slider"].clearance["B"], runs["rod"].clearance["B"]
    assert np.max(np.asarray(default["penetration"])) > 0, "the window must contain an impact"
    for key in ("ecc_x", "ecc_y"):
        np.testing.assert_allclose(
            swapped[key], -np.asarray(default[key]), rtol=0, atol=SWAP_ECCENTRICITY_TOL
        )
    peak = float(np.max(np.asarray(default["normal_force"])))
    np.testing.assert_allclose(
        swapped["normal_force"], default["normal_force"], rtol=0, atol=SWAP_FORCE_REL_TOL * peak
    )
    np.testing.assert_allclose(runs["rod"].q, runs["slider"].q, rtol=0, atol=SWAP_ECCENTRICITY_TOL)


def test_bad_journal_body():
    with pytest.raises(jaxclear.ModelError, match=r"journal_body='crank'.*'rod' or 'slider'"):
        ClearanceJoint.replacing(_revolute(), journal_body="crank")
    with pytest.raises(jaxclear.ModelError, match="journal_body"):
        slider_crank(clearance_joints={"B": {"journal_body": "crank"}})
    with pytest.raises(TypeError, match="unknown option"):
        slider_crank(clearance_joints={"B": {"journal": "rod"}})
    assert jaxclear.ClearanceJoint is ClearanceJoint


PENETRATION = 2e-6  # m into the wall: a contact force of order 1e2 N with the Hertz stiffness


def test_journal_body_choice_gives_the_same_generalized_force():
    """At one instant with the journal pressed into the wall, the pin on the rod or on the slider
    gives the same generalised contact force on every body (point law, no friction: the force acts
    along the line of centres) and eccentricities of opposite sign."""
    mechs = [
        slider_crank(
            clearance_joints={"B": {"journal_body": journal}},
            contact_law=LankaraniNikravesh(stiffness=HERTZ_K, restitution=0.9),
            friction_law=NoFriction(),
        )
        for journal in ("slider", "rod")
    ]
    y0 = assemble(mechs[0])
    n = mechs[0].num_coordinates
    q, qd, state = y0[:n], y0[n : 2 * n], y0[2 * n :]
    slider, rod = 3 * mechs[0].index("slider"), 3 * mechs[0].index("rod")
    q = q.at[slider + 1].add(5e-4 + PENETRATION)  # slider (default journal) pushed up by c + δ
    qd = qd.at[slider + 1].set(0.3)  # approaching the wall
    state = state.at[0].set(0.3)  # impact memory: the approach speed
    forces, kins = [], []
    for mech in mechs:
        joint = mech.clearance_joints[0]
        forces.append(np.asarray(clearance.generalized_force(joint, mech.index, q, qd, state)))
        kins.append(clearance.kinematics(joint, mech.index, q, qd))
    default, swapped = kins
    np.testing.assert_allclose(
        swapped.eccentricity_vector, -default.eccentricity_vector, rtol=1e-12
    )
    np.testing.assert_allclose(swapped.penetration, default.penetration, rtol=1e-9)
    np.testing.assert_allclose(default.penetration, PENETRATION, rtol=1e-6)
    np.testing.assert_allclose(swapped.penetration_rate, default.penetration_rate, rtol=1e-12)
    assert forces[0][slider + 1] < -1.0  # the wall pushes the slider back down
    np.testing.assert_allclose(
        forces[1], forces[0], rtol=1e-9, atol=1e-9 * np.max(np.abs(forces[0]))
    )
    assert np.all(forces[0][: 3 * mechs[0].index("crank") + 3] == 0.0) and forces[0][rod + 1] > 1.0


def test_clearance_outputs_attribute_and_mapping_access():
    mech = slider_crank(clearance_joints="B", friction_law=LuGre())
    y0 = assemble(mech)
    n = mech.num_coordinates
    joint = mech.clearance_joints[0]
    out = clearance.outputs(joint, mech.index, y0[:n], y0[n : 2 * n], y0[2 * n :])
    assert isinstance(out, jaxclear.dynamics.ClearanceOutputs)
    assert out.keys()[-1] == "friction_state" and "friction_state" in out and len(out) == 10
    assert out["normal_force"] is out.normal_force
    assert dict(out.items())["ecc_x"] is out.ecc_x and list(out) == list(out.keys())
    frictionless = clearance.outputs(
        dataclasses.replace(joint, friction_law=NoFriction()),
        mech.index,
        y0[:n],
        y0[n : 2 * n],
        y0[2 * n : 2 * n + 1],
    )
    assert "friction_state" not in frictionless and frictionless.friction_state is None
    with pytest.raises(KeyError, match="'friction_state' is not an output.*normal_force"):
        frictionless["friction_state"]
