"""Four-bar linkage (``jaxclear.mechanisms.four_bar``): closed-form positions and energy balances.

The reference position solution is written here (Freudenstein's equation for the rocker angle,
branch chosen geometrically), independently of the package's assembly guess.
"""

import numpy as np
import pytest
from helpers import NUM_POINTS

import jaxclear
from jaxclear.mechanisms import four_bar

# four_bar() defaults
D, A, B, C = 0.30, 0.10, 0.30, 0.25  # ground, crank, coupler, rocker lengths, m
MASS = (0.2, 0.5, 0.4)  # crank, coupler, rocker, kg
LENGTH = (A, B, C)
INERTIA = tuple(m * ell**2 / 12 for m, ell in zip(MASS, LENGTH))  # uniform slender links
THETA0 = np.pi / 3  # rad
RPM = 60.0
OMEGA = RPM * 2 * np.pi / 60  # rad/s
G = 9.81  # m/s²

T_DRIVEN = 1.0  # s: one crank revolution at 60 rpm
T_FREE = 3.0  # s: the free linkage swings through several full crank turns

RTOL = jaxclear.PRESETS["fast"].rtol  # 1e-6
ERROR_FACTOR = 10.0
"""Global error allowed, in units of rtol × the quantity's scale (the local error is controlled
to rtol; a few tens of steps accumulate a small multiple of it)."""
ANGLE_TOL = ERROR_FACTOR * RTOL  # rad
POSITION_TOL = ERROR_FACTOR * RTOL * (D + B)  # m


def closed_form_positions(theta):
    """q (N, 9) of crank, coupler, rocker (x, y, φ of each CM) at crank angles θ.

    Rocker angle ψ from the loop closure |B − A| = b with A = a(cos θ, sin θ),
    B = O4 + c(cos ψ, sin ψ): K1 cos ψ + K2 sin ψ + K3 = 0 (Freudenstein), whose two roots are
    the open and crossed branches. ``four_bar`` assembles the branch with B to the left of the
    direction A → O4 (cross product > 0).
    """
    th = np.asarray(theta, dtype=float)
    ax, ay = A * np.cos(th), A * np.sin(th)
    k1 = 2 * C * (D - ax)
    k2 = -2 * C * ay
    k3 = A**2 + C**2 + D**2 - B**2 - 2 * A * D * np.cos(th)
    base = np.arctan2(k2, k1)
    half = np.arccos(-k3 / np.hypot(k1, k2))
    roots = np.stack([base + half, base - half])
    bx, by = D + C * np.cos(roots), C * np.sin(roots)
    left = (D - ax) * (by - ay) - (0.0 - ay) * (bx - ax) > 0
    assert np.all(left[0] != left[1])  # exactly one root per angle on each side
    psi = np.where(left[0], roots[0], roots[1])
    bx, by = D + C * np.cos(psi), C * np.sin(psi)
    coupler = np.arctan2(by - ay, bx - ax)
    return np.stack(
        [ax / 2, ay / 2, th, (ax + bx) / 2, (ay + by) / 2, coupler, (D + bx) / 2, by / 2, psi],
        axis=-1,
    )


def mechanical_energy(q, qd):
    """Kinetic plus gravitational potential energy, J (gravity 9.81 m/s² along −y)."""
    m = np.array(
        [MASS[0], MASS[0], INERTIA[0], MASS[1], MASS[1], INERTIA[1], MASS[2], MASS[2], INERTIA[2]]
    )
    kinetic = 0.5 * np.sum(m * qd**2, axis=-1)
    potential = G * (MASS[0] * q[:, 1] + MASS[1] * q[:, 4] + MASS[2] * q[:, 7])
    return kinetic, potential


def _wrap(a):
    return np.angle(np.exp(1j * a))


@pytest.fixture(scope="module")
def driven():
    mech = four_bar()
    return jaxclear.simulate(mech, T_DRIVEN, num_points=NUM_POINTS, solver="fast")


@pytest.fixture(scope="module")
def free():
    mech = four_bar(rpm=None)
    return jaxclear.simulate(mech, T_FREE, num_points=NUM_POINTS, solver="fast")


def test_mechanism_inertia_is_slender_rod():
    mech = four_bar()
    np.testing.assert_allclose([float(b.inertia) for b in mech.bodies], INERTIA, rtol=1e-14)
    np.testing.assert_allclose([float(b.mass) for b in mech.bodies], MASS, rtol=1e-14)


def test_positions_match_closed_form(driven):
    assert bool(driven.succeeded)
    theta = THETA0 + OMEGA * np.asarray(driven.t)
    ref = closed_form_positions(theta)
    q = np.asarray(driven.q)
    angles, lengths = [2, 5, 8], [0, 1, 3, 4, 6, 7]
    ang_err = np.abs(_wrap(q[:, angles] - ref[:, angles])).max(axis=0)
    pos_err = np.abs(q[:, lengths] - ref[:, lengths]).max()
    print(
        f"max error vs closed form: crank {ang_err[0]:.3g} rad, coupler {ang_err[1]:.3g} rad, "
        f"rocker {ang_err[2]:.3g} rad, CM positions {pos_err:.3g} m"
    )
    assert ang_err.max() < ANGLE_TOL
    assert pos_err < POSITION_TOL
    # the rocker actually rocks: it is a Grashof crank-rocker (s + l < p + q)
    assert np.ptp(q[:, 8]) > 0.3


ENERGY_BALANCE_RTOL = 1e-5
"""Drive work vs Δ(T + V), relative to the largest |ΔE|. Trapezoid on 4000 intervals of a smooth
power signal: error ~ h²/12 · max|P''| · T ≈ 1e-7 relative; the remainder comes from the
solver's torque and velocities, ~rtol = 1e-6 relative each (measured total: 6e-7)."""


def test_drive_work_equals_energy_change(driven):
    t = np.asarray(driven.t)
    q, qd = np.asarray(driven.q), np.asarray(driven.qd)
    power = np.asarray(driven.input_torque) * OMEGA  # the crank turns at constant ω
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    kinetic, potential = mechanical_energy(q, qd)
    energy = kinetic + potential
    delta = energy - energy[0]
    err = np.max(np.abs(work - delta))
    scale = np.max(np.abs(delta))
    print(
        f"drive work vs Δ(T+V): max error {err:.3g} J over a swing of {scale:.4g} J (relative {err / scale:.3g})"
    )
    assert scale > 0.1  # the check is not vacuous
    assert err < ENERGY_BALANCE_RTOL * scale


ENERGY_DRIFT_RTOL = 1e-4
"""|E(t) − E(0)| of the free linkage relative to the largest kinetic energy: the explicit solver
at rtol 1e-6 drifts ~rtol per step over ~300 steps; Baumgarte stabilisation only acts on the
~1e-8 constraint residual (measured: 6e-6)."""


def test_free_four_bar_conserves_energy(free):
    assert bool(free.succeeded)
    q, qd = np.asarray(free.q), np.asarray(free.qd)
    kinetic, potential = mechanical_energy(q, qd)
    energy = kinetic + potential
    drift = np.max(np.abs(energy - energy[0]))
    scale = np.max(kinetic)
    print(
        f"free four-bar: max |E - E0| = {drift:.3g} J, max kinetic energy {scale:.4g} J (relative {drift / scale:.3g})"
    )
    assert np.abs(qd[0]).max() < 1e-12  # released from rest
    assert scale > 0.1  # it moves
    assert drift < ENERGY_DRIFT_RTOL * scale
    # no driver: zero input torque, and the constraints keep holding
    assert np.all(np.asarray(free.input_torque) == 0.0)
    assert np.asarray(free.constraint_violation).max() < POSITION_TOL


def test_free_four_bar_follows_loop_closure(free):
    """Whatever the free motion, coupler and rocker angles are the closed-form functions of the
    (now unprescribed) crank angle."""
    q = np.asarray(free.q)
    ref = closed_form_positions(q[:, 2])
    err = np.abs(_wrap(q[:, [5, 8]] - ref[:, [5, 8]])).max()
    print(f"free four-bar: coupler/rocker angle vs closed form of the crank angle: {err:.3g} rad")
    assert err < ANGLE_TOL
