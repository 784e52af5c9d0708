"""Benchmark slider–crank with ideal joints (docs/model.md §6) against closed-form kinematics and kinetics.

Everything the package output is compared with is computed here in NumPy from the geometry of
docs/model.md §6, independently of ``jaxclear``: the slider position x_B = r cos θ + √(l² − r² sin² θ)
and its exact time derivatives, the coordinates of every body, the Newton–Euler joint reactions
and the input torque from the kinetic-energy balance τ ω = dT/dt.
"""

import numpy as np
import pytest
from helpers import NUM_POINTS

import jaxclear
from jaxclear.mechanisms import slider_crank

# docs/model.md §6 geometry and inertia (crank, rod, slider).
R, L = 0.05, 0.12  # m
MASS = (0.30, 0.21, 0.14)  # kg
INERTIA = (1.0e-4, 2.5e-4, 1.0e-4)  # kg m²
RPM = 5000.0
OMEGA = RPM * 2.0 * np.pi / 60.0  # rad/s
PERIOD = 2.0 * np.pi / OMEGA  # s
T1 = 2.0 * PERIOD  # two revolutions

RTOL = jaxclear.PRESETS["fast"].rtol  # 1e-6: error-control tolerance of the Tsit5 preset
# Scales of each quantity: errors are asserted relative to them.
POSITION_SCALE = R + L  # m, largest coordinate
VELOCITY_SCALE = R * OMEGA  # m/s, crank-pin speed (26 m/s)
ACCELERATION_SCALE = R * OMEGA**2  # m/s², crank-pin centripetal acceleration (13.7 km/s²)
ERROR_FACTOR = 10.0
"""Allowed global error in units of rtol × scale. A tolerance-proportional controller keeps the
local error below rtol; over the ~50 steps of two revolutions (and with Baumgarte pulling the
positions back onto Φ = 0) the global error stays a small multiple of it. Measured: 1–3."""
ANGLE_TOL = ERROR_FACTOR * RTOL  # rad
POSITION_TOL = ERROR_FACTOR * RTOL * POSITION_SCALE
VELOCITY_TOL = ERROR_FACTOR * RTOL * VELOCITY_SCALE
ACCELERATION_TOL = ERROR_FACTOR * RTOL * ACCELERATION_SCALE
FORCE_TOL_REL = ERROR_FACTOR * RTOL
"""Reactions and torque are linear in the accelerations: same relative error as them, taken
relative to the largest value of each signal."""

ENERGY_DIFF_STEP = 1e-5  # rad: central difference of T(θ); truncation ~h² T'''/6 ≈ 1e-9 N m


# --------------------------------------------------------------------------------------------
# Closed form, independent of the package
# --------------------------------------------------------------------------------------------
def closed_form(theta):
    """Coordinates q, velocities q̇ and accelerations q̈ (N, 9) at crank angles θ = ω t.

    Bodies in the order crank, rod, slider; each (x, y, φ) of its centre of mass. The crank's CM is
    at r/2, the rod's at its mid-point, the slider at B; rod angle ψ = −asin(r sin θ / l).
    """
    th = np.asarray(theta, dtype=float)
    s, c = np.sin(th), np.cos(th)
    w = OMEGA
    S = np.sqrt(L**2 - R**2 * s**2)
    # slider x and its θ-derivatives
    xb = R * c + S
    dxb = -R * s - R**2 * s * c / S
    ddxb = -R * c - R**2 * (c**2 - s**2) / S - R**4 * s**2 * c**2 / S**3
    # rod angle and its θ-derivatives
    psi = -np.arcsin(R * s / L)
    dpsi = -R * c / S
    ddpsi = R * s / S - R**3 * s * c**2 / S**3
    zero = np.zeros_like(th)
    q = np.stack(
        [R * c / 2, R * s / 2, th, (R * c + xb) / 2, R * s / 2, psi, xb, zero, zero], axis=-1
    )
    qd = w * np.stack(
        [
            -R * s / 2,
            R * c / 2,
            np.ones_like(th),
            (-R * s + dxb) / 2,
            R * c / 2,
            dpsi,
            dxb,
            zero,
            zero,
        ],
        axis=-1,
    )
    qdd = w**2 * np.stack(
        [-R * c / 2, -R * s / 2, zero, (-R * c + ddxb) / 2, -R * s / 2, ddpsi, ddxb, zero, zero],
        axis=-1,
    )
    return q, qd, qdd


def kinetic_energy(theta):
    """T(θ) = ½ Σ (m v² + J φ̇²) of the three bodies from the closed-form velocities, J."""
    _, qd, _ = closed_form(theta)
    m = np.array(
        [MASS[0], MASS[0], INERTIA[0], MASS[1], MASS[1], INERTIA[1], MASS[2], MASS[2], INERTIA[2]]
    )
    return 0.5 * np.sum(m * qd**2, axis=-1)


def energy_torque(theta):
    """Input torque from τ ω = dT/dt = ω dT/dθ (no gravity, no other forces): τ = dT/dθ."""
    h = ENERGY_DIFF_STEP
    return (kinetic_energy(theta + h) - kinetic_energy(theta - h)) / (2 * h)


def newton_euler(theta):
    """Joint forces and motor torque by Newton–Euler on each body, from the closed-form motion.

    Unknowns: F_O (ground on crank at O), F_A (crank on rod at A), F_B (rod on slider at B), the
    guide's normal force N on the slider and the motor torque τ on the crank. Equations: crank
    (x, y, moment about its CM), rod (x, y, moment), slider (x, y).

    Returns:
        dict with F_O, F_A, F_B (N, 2) and tau (N,).
    """
    q, _, qdd = closed_form(theta)
    n = q.shape[0]
    r1, r2, r3 = q[:, 0:2], q[:, 3:5], q[:, 6:8]
    a = R * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], axis=-1)  # crank pin A; O is the origin
    b = r3

    def cross_coeffs(d):  # coefficients of (F_x, F_y) in the planar cross product d × F
        return np.stack([-d[:, 1], d[:, 0]], axis=-1)

    mat = np.zeros((n, 8, 8))
    rhs = np.zeros((n, 8))
    # unknown order: F_O (0, 1), F_A (2, 3), F_B (4, 5), N (6), tau (7)
    # crank: m1 a1 = F_O - F_A ; J1 α1 = (O - r1) × F_O - (A - r1) × F_A + τ
    mat[:, 0, [0, 2]] = [1, -1]
    mat[:, 1, [1, 3]] = [1, -1]
    mat[:, 2, 0:2] = cross_coeffs(-r1)
    mat[:, 2, 2:4] = -cross_coeffs(a - r1)
    mat[:, 2, 7] = 1
    rhs[:, 0:3] = np.stack(
        [MASS[0] * qdd[:, 0], MASS[0] * qdd[:, 1], INERTIA[0] * qdd[:, 2]], axis=-1
    )
    # rod: m2 a2 = F_A - F_B ; J2 α2 = (A - r2) × F_A - (B - r2) × F_B
    mat[:, 3, [2, 4]] = [1, -1]
    mat[:, 4, [3, 5]] = [1, -1]
    mat[:, 5, 2:4] = cross_coeffs(a - r2)
    mat[:, 5, 4:6] = -cross_coeffs(b - r2)
    rhs[:, 3:6] = np.stack(
        [MASS[1] * qdd[:, 3], MASS[1] * qdd[:, 4], INERTIA[1] * qdd[:, 5]], axis=-1
    )
    # slider: m3 a3 = F_B + (0, N)  (its moment equation holds the guide's reaction moment, unused)
    mat[:, 6, 4] = 1
    mat[:, 7, [5, 6]] = [1, 1]
    rhs[:, 6:8] = np.stack([MASS[2] * qdd[:, 6], MASS[2] * qdd[:, 7]], axis=-1)
    x = np.linalg.solve(mat, rhs[..., None])[..., 0]
    return {"F_O": x[:, 0:2], "F_A": x[:, 2:4], "F_B": x[:, 4:6], "tau": x[:, 7]}


# --------------------------------------------------------------------------------------------
# One simulation for the whole module
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def traj():
    mech = slider_crank(rpm=RPM, gravity=False)
    ts = np.linspace(0.0, T1, NUM_POINTS)  # 2000 points per revolution: 0.18° spacing
    return jaxclear.simulate(mech, T1, ts=ts, solver="fast")


@pytest.fixture(scope="module")
def reference(traj):
    theta = OMEGA * np.asarray(traj.t)
    q, qd, qdd = closed_form(theta)
    ne = newton_euler(theta)
    return dict(
        theta=theta, q=q, qd=qd, qdd=qdd, tau=energy_torque(theta), tau_ne=ne.pop("tau"), **ne
    )


def _wrap(a):
    return np.angle(np.exp(1j * a))


def test_solve_succeeds(traj):
    assert bool(traj.succeeded)
    assert float(traj.t_final) == pytest.approx(T1, rel=1e-12)
    assert traj.q.shape == (NUM_POINTS, 9)


def test_positions_match_closed_form(traj, reference):
    q, ref = np.asarray(traj.q), reference["q"]
    angles = [2, 5, 8]
    lengths = [0, 1, 3, 4, 6, 7]
    pos_err = np.max(np.abs(q[:, lengths] - ref[:, lengths]))
    ang_err = np.max(np.abs(_wrap(q[:, angles] - ref[:, angles])))
    xb_err = np.max(np.abs(q[:, 6] - ref[:, 6]))
    print(
        f"max |x_B - closed form| = {xb_err:.3g} m; all CM coordinates {pos_err:.3g} m; angles {ang_err:.3g} rad"
    )
    assert xb_err < POSITION_TOL
    assert pos_err < POSITION_TOL
    assert ang_err < ANGLE_TOL


def test_velocities_match_closed_form(traj, reference):
    qd, ref = np.asarray(traj.qd), reference["qd"]
    err = np.abs(qd - ref)
    lin = [0, 1, 3, 4, 6, 7]
    ang = [2, 5, 8]
    print(
        f"max |v_B - closed form| = {err[:, 6].max():.3g} m/s; all linear {err[:, lin].max():.3g} m/s; "
        f"angular {err[:, ang].max():.3g} rad/s"
    )
    assert err[:, lin].max() < VELOCITY_TOL
    assert err[:, ang].max() < VELOCITY_TOL / R  # angular rates: speed scale / crank length


def test_accelerations_match_closed_form(traj, reference):
    qdd, ref = np.asarray(traj.qdd), reference["qdd"]
    err = np.abs(qdd - ref)
    lin = [0, 1, 3, 4, 6, 7]
    ang = [2, 5, 8]
    print(
        f"max |a_B - closed form| = {err[:, 6].max():.3g} m/s²; all linear {err[:, lin].max():.3g} m/s²; "
        f"angular {err[:, ang].max():.3g} rad/s²"
    )
    assert err[:, lin].max() < ACCELERATION_TOL
    assert err[:, ang].max() < ACCELERATION_TOL / R


def test_input_torque_from_energy_balance(traj, reference):
    """τ ω = dT/dt with no gravity: fixes the sign (motor power positive when it speeds the
    mechanism up) and the value of ``Trajectory.input_torque``."""
    tau, ref = np.asarray(traj.input_torque), reference["tau"]
    err = np.max(np.abs(tau - ref))
    scale = np.max(np.abs(ref))
    print(f"max |τ - dT/dθ| = {err:.3g} N m (peak {scale:.5g} N m)")
    assert err < FORCE_TOL_REL * scale
    # power and kinetic-energy rate agree in sign wherever the power is not negligible
    power = tau * OMEGA
    t_rate = OMEGA * ref
    big = np.abs(t_rate) > 0.01 * np.max(np.abs(t_rate))
    assert np.all(np.sign(power[big]) == np.sign(t_rate[big]))


def test_joint_reactions_match_newton_euler(traj, reference):
    """``joint_force(j)`` is the force body_j exerts on body_i: O is (ground, crank), A is (crank,
    rod), B is (rod, slider); Newton–Euler gives the forces on crank, rod, slider."""
    expected = {"O": -reference["F_O"], "A": -reference["F_A"], "B": -reference["F_B"]}
    for joint, ref in expected.items():
        got = np.asarray(traj.joint_force(joint))
        scale = np.max(np.linalg.norm(ref, axis=-1))
        err = np.max(np.abs(got - ref))
        print(f"joint {joint}: max |F - Newton-Euler| = {err:.3g} N (peak {scale:.5g} N)")
        assert err < FORCE_TOL_REL * scale
        mag = np.asarray(traj.joint_force_magnitude(joint))
        np.testing.assert_allclose(mag, np.linalg.norm(got, axis=-1), rtol=1e-12)
    tau_ne = reference["tau_ne"]
    err = np.max(np.abs(np.asarray(traj.input_torque) - tau_ne))
    print(f"max |τ - Newton-Euler τ| = {err:.3g} N m")
    assert err < FORCE_TOL_REL * np.max(np.abs(tau_ne))


# --------------------------------------------------------------------------------------------
# docs/model.md §6 table
# --------------------------------------------------------------------------------------------
MODEL_TABLE = {
    # name: (reference value, half a unit of its last printed digit)
    "slider acceleration min": (-19419.0, 0.5),
    "slider acceleration max": (9696.0, 0.5),
    "peak slider speed": (28.41, 0.005),
    "input torque min": (-138.52, 0.005),
    "input torque max": (138.52, 0.005),
    "O reaction min": (3004.0, 0.5),
    "O reaction max": (8253.0, 0.5),
    "A reaction min": (948.0, 0.5),
    "A reaction max": (6197.0, 0.5),
    "B reaction min": (434.0, 0.5),
    "B reaction max": (2719.0, 0.5),
}
EXTREME_RTOL = 2e-5
"""Extremes on the output grid: a smooth peak sampled every Δθ = 4π/4000 rad is missed by at most
(Δθ)²/8 · |f''/f| ≲ 1e-5 relative; plus the solver's ~1e-6. The table's own rounding is the
half unit added to each entry."""


def _extremes(traj):
    a = np.asarray(traj.accelerations("slider"))[:, 0]
    v = np.asarray(traj.velocities("slider"))[:, 0]
    tau = np.asarray(traj.input_torque)
    out = {
        "slider acceleration min": a.min(),
        "slider acceleration max": a.max(),
        "peak slider speed": np.abs(v).max(),
        "input torque min": tau.min(),
        "input torque max": tau.max(),
    }
    for j in "OAB":
        f = np.asarray(traj.joint_force_magnitude(j))
        out[f"{j} reaction min"], out[f"{j} reaction max"] = f.min(), f.max()
    return out


def test_model_table_extremes(traj):
    found = _extremes(traj)
    for name, (ref, half_unit) in MODEL_TABLE.items():
        print(f"{name}: {found[name]:.6g} (docs/model.md {ref:g})")
    for name, (ref, half_unit) in MODEL_TABLE.items():
        assert abs(found[name] - ref) <= half_unit + EXTREME_RTOL * abs(ref), name


def test_model_table_from_closed_form():
    """The table itself, recomputed here on a very fine grid from the closed form and
    Newton–Euler (guards the reference numbers the previous test relies on)."""
    theta = np.linspace(0.0, 2.0 * np.pi, 20_001)
    _, qd, qdd = closed_form(theta)
    ne = newton_euler(theta)
    found = {
        "slider acceleration min": qdd[:, 6].min(),
        "slider acceleration max": qdd[:, 6].max(),
        "peak slider speed": np.abs(qd[:, 6]).max(),
        "input torque min": ne["tau"].min(),
        "input torque max": ne["tau"].max(),
    }
    for j in "OAB":
        f = np.linalg.norm(ne[f"F_{j}"], axis=-1)
        found[f"{j} reaction min"], found[f"{j} reaction max"] = f.min(), f.max()
    for name, (ref, half_unit) in MODEL_TABLE.items():
        assert abs(found[name] - ref) <= half_unit + 1e-6 * abs(ref), (name, found[name])
    # the two independent torques (energy balance, Newton–Euler) agree
    np.testing.assert_allclose(
        energy_torque(theta), ne["tau"], rtol=0, atol=1e-6 * np.abs(ne["tau"]).max()
    )


def test_constraints_hold(traj):
    viol = np.asarray(traj.constraint_violation)
    print(f"max |Φ| = {viol.max():.3g}, max |Φ̇| = {np.asarray(traj.velocity_violation).max():.3g}")
    assert viol.max() < POSITION_TOL
