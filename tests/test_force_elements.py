"""Applied forces and torques, spring–dampers, function drivers, and clearance in the four-bar.

Each mechanism here is tiny, so its compile is cheap; each is checked against a closed form.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import without_runtime_type_checks

import jaxclear
from jaxclear.analysis import kinetic_energy, potential_energy
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import NoFriction
from jaxclear.mechanisms import four_bar

SOLVER = jaxclear.SolverConfig(method="tsit5", rtol=1e-10, atol=1e-12)
NUM_POINTS = 401
ENERGY_TOL = 1e-8  # J of 1 J: rtol 1e-10 integration (measured drift 2e-10 J)
EXTREMES = False
"""The solves compared with closed forms leave ``Trajectory.extremes`` out: the checks read the
trajectory, which the extremes tracking does not change, and each compilation takes about a third
less CPU without it. ``test_force_element_hook_defaults`` keeps the default call (the tracking
evaluates the element's forces at every step)."""


def slider_on_spring(stiffness, damping, force=0.0, mass=2.0):
    """A block on a frictionless x guide tied to the origin by a spring–damper."""
    return jaxclear.Mechanism(
        bodies=(jaxclear.Body("block", mass, 0.01, position=(0.1, 0.0, 0.0)),),
        joints=(jaxclear.TranslationalJoint("guide", "block", (0.0, 0.0), "ground", (0.0, 0.0)),),
        forces=(
            jaxclear.SpringDamper(
                "spring",
                "ground",
                (0.0, 0.0),
                "block",
                (0.0, 0.0),
                stiffness,
                damping,
                free_length=0.05,
            ),
            jaxclear.AppliedForce("push", "block", (0.0, 0.0), (force, 0.0)),
        ),
        gravity=(0.0, -9.81),
    )


def test_spring_mass_oscillation_matches_closed_form():
    k, m = 800.0, 2.0
    mech = slider_on_spring(k, 0.0, mass=m)
    omega = np.sqrt(k / m)
    t1 = 2 * 2 * np.pi / omega
    traj = jaxclear.simulate(mech, t1, num_points=NUM_POINTS, solver=SOLVER, extremes=EXTREMES)
    t = np.asarray(traj.t)
    x = np.asarray(traj.coordinates("block")[:, 0])
    expected = 0.05 + 0.05 * np.cos(omega * t)  # released from x = 0.1 at rest, free length 0.05
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-8)
    # undamped: kinetic + spring potential (½ k (x0 - l0)² = 1 J) is conserved
    energy = np.asarray(kinetic_energy(traj) + potential_energy(traj))
    assert abs(energy[0] - 0.5 * k * 0.05**2) < 1e-12
    assert np.max(np.abs(energy - energy[0])) < ENERGY_TOL


def test_spring_damper_decay_and_static_force():
    k, c, m, f = 800.0, 8.0, 2.0, 4.0
    mech = slider_on_spring(k, c, force=f, mass=m)
    traj = jaxclear.simulate(mech, 3.0, num_points=NUM_POINTS, solver=SOLVER, extremes=EXTREMES)
    x = np.asarray(traj.coordinates("block")[:, 0])
    # damped oscillation about the equilibrium where the spring balances the push, k (x - l0) = f; decrement of the damped oscillation: amplitude ratio per period = exp(-zeta omega_n T_d)
    zeta = c / (2 * np.sqrt(k * m))
    omega_d = np.sqrt(k / m) * np.sqrt(1 - zeta**2)
    t = np.asarray(traj.t)
    x_eq = 0.05 + f / k
    amplitude_0 = 0.1 - x_eq
    expected = x_eq + amplitude_0 * np.exp(-zeta * np.sqrt(k / m) * t) * (
        np.cos(omega_d * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(omega_d * t)
    )
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-8)


def pendulum(torque=0.0):
    length, mass = 0.4, 1.5
    return jaxclear.Mechanism(
        bodies=(jaxclear.Body("bar", mass, mass * length**2 / 12, position=(0.2, 0.0, 0.0)),),
        joints=(jaxclear.RevoluteJoint("pivot", "ground", (0.0, 0.0), "bar", (-length / 2, 0.0)),),
        forces=(jaxclear.AppliedTorque("motor", "bar", torque),),
    )


def test_applied_torque_holds_pendulum_level():
    # torque m g L/2 balances gravity with the bar horizontal
    mech = pendulum(torque=1.5 * 9.81 * 0.2)
    traj = jaxclear.simulate(mech, 0.5, num_points=NUM_POINTS, solver=SOLVER, extremes=EXTREMES)
    assert np.max(np.abs(np.asarray(traj.coordinates("bar")[:, 2]))) < 1e-9


def test_function_driver_prescribes_angle_and_relative_driver():
    amplitude, omega = 0.3, 20.0
    mech = pendulum()
    driver = jaxclear.FunctionDriver(
        "bar", lambda t, p: p[0] * jnp.sin(p[1] * t), jnp.array([amplitude, omega])
    )
    mech = jaxclear.Mechanism(bodies=mech.bodies, joints=mech.joints, driver=driver)
    traj = jaxclear.simulate(mech, 1.0, num_points=NUM_POINTS, solver=SOLVER, extremes=EXTREMES)
    t = np.asarray(traj.t)
    np.testing.assert_allclose(
        np.asarray(traj.coordinates("bar")[:, 2]), amplitude * np.sin(omega * t), atol=1e-9
    )
    # torque = J_O φ̈ + m g (L/2) cos φ  (J_O about the pivot)
    j_o = 1.5 * 0.4**2 / 3
    phi = amplitude * np.sin(omega * t)
    phidd = -amplitude * omega**2 * np.sin(omega * t)
    expected = j_o * phidd + 1.5 * 9.81 * 0.2 * np.cos(phi)
    np.testing.assert_allclose(
        np.asarray(traj.input_torque), expected, rtol=0, atol=1e-6 * np.max(np.abs(expected))
    )


def ideal_rocker_angle(t, rpm=60.0, initial_angle=np.pi / 3):
    """Rocker angle of the ideal driven four-bar (``four_bar`` defaults: ground 0.30, crank 0.10,
    coupler 0.30, rocker 0.25 m, open branch), rad: B where the circles about A (radius coupler)
    and O4 (radius rocker) meet; kinematic, so no simulation is needed."""
    d, a, b, c = 0.30, 0.10, 0.30, 0.25
    th = initial_angle + rpm * 2 * np.pi / 60 * t
    ax, ay = a * np.cos(th), a * np.sin(th)
    dx, dy = d - ax, -ay
    dist = np.hypot(dx, dy)
    along = (b**2 - c**2 + dist**2) / (2 * dist)
    h = np.sqrt(b**2 - along**2)
    bx = ax + (along * dx - h * dy) / dist
    by = ay + (along * dy + h * dx) / dist
    return np.arctan2(by, bx - d)


def test_four_bar_with_clearance_stays_near_ideal():
    law = LankaraniNikravesh()
    loose = four_bar(
        clearance_joints="B", clearance=1e-4, contact_law=law, friction_law=NoFriction()
    )
    traj = jaxclear.simulate(loose, 1.0, num_points=NUM_POINTS, solver="fast", extremes=EXTREMES)
    out = traj.clearance["B"]
    ecc = np.hypot(np.asarray(out["ecc_x"]), np.asarray(out["ecc_y"]))
    assert ecc.max() < 1e-4 + 20e-6  # inside the clearance circle up to a small penetration
    rocker = np.asarray(traj.coordinates("rocker")[:, 2])
    ideal = ideal_rocker_angle(np.asarray(traj.t))
    assert np.ptp(ideal) > 0.5  # rad: the rocker swings
    off = np.angle(np.exp(1j * (rocker - ideal)))  # wrapped to (-pi, pi]
    assert np.max(np.abs(off)) < 5e-3  # rad, c / link ≈ 4e-4


@pytest.mark.parametrize("bad", [dict(stiffness=-1.0), dict(damping=-0.1), dict(free_length=-0.2)])
def test_spring_damper_rejects_negative_parameters(bad):
    args = dict(stiffness=1.0, damping=0.0, free_length=0.0) | bad
    with pytest.raises(jaxclear.ModelError, match=next(iter(bad))):
        jaxclear.SpringDamper("s", "ground", (0.0, 0.0), "block", (0.0, 0.0), **args)


def _block():
    return jaxclear.Body("block", 1.0, 0.01, position=(0.1, 0.0, 0.0))


def test_mechanism_checks_element_bodies_and_kinds():
    spring = jaxclear.SpringDamper("s", "ground", (0.0, 0.0), "blok", (0.0, 0.0), stiffness=1.0)
    assert spring.bodies == ("ground", "blok")
    with pytest.raises(
        jaxclear.ModelError, match=r"SpringDamper 's': body 'blok' is not a body.*'block'"
    ):
        jaxclear.Mechanism(bodies=(_block(),), forces=(spring,))
    pin = jaxclear.ClearanceJoint.replacing(
        jaxclear.RevoluteJoint("P", "ground", (0.1, 0.0), "block", (0.0, 0.0))
    )
    with pytest.raises(TypeError):  # the annotation, when jaxtyping's runtime checks are on
        jaxclear.Mechanism(bodies=(_block(),), forces=(pin,))
    with without_runtime_type_checks():  # the message users get (no runtime checker)
        with pytest.raises(
            TypeError,
            match="forces holds a ClearanceJoint.*clearance joints go in clearance_joints",
        ):
            jaxclear.Mechanism(bodies=(_block(),), forces=(pin,))
        with pytest.raises(TypeError, match="clearance_joints holds a SpringDamper"):
            jaxclear.Mechanism(bodies=(_block(),), clearance_joints=(spring,))


class _Push(jaxclear.AbstractForceElement):
    """A force element that declares only what it must: the other hooks keep their defaults."""

    name: str = eqx.field(static=True, default="push")

    @property
    def bodies(self):
        return ("block",)

    def generalized_force(self, index, q, qd, t, state):
        return jnp.zeros_like(q).at[3 * index("block")].set(2.0)


def test_force_element_hook_defaults():
    mech = jaxclear.Mechanism(bodies=(_block(),), forces=(_Push(),), gravity=(0.0, 0.0))
    assert mech.state_size == 6 and not np.any(mech.memory_rows)
    q = jnp.asarray([0.1, 0.0, 0.0])
    push = mech.forces[0]
    assert push.initial_state(mech.index, q, q).shape == (0,)
    assert float(push.potential_energy(mech.index, q)) == 0.0
    traj = jaxclear.simulate(mech, 0.5, num_points=3, solver=SOLVER)
    np.testing.assert_allclose(np.asarray(traj.qdd[:, 0]), 2.0, rtol=1e-12)  # F / m
    with pytest.raises(TypeError, match="abstract"):

        class _NoBodies(jaxclear.AbstractForceElement):
            name: str = "x"

            def generalized_force(self, index, q, qd, t, state):
                return jnp.zeros_like(q)

        _NoBodies()
