"""Lubricated revolute clearance joint (docs/model.md §3b): the film's closed forms against an
independent quadrature of Reynolds' equation, Ocvirk's steady-load relation, the Petroff torque
against Petroff's law, a pure squeeze drop against SciPy, the blend to dry contact, gradients,
and the benchmark slider–crank."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import root

import jaxclear
from jaxclear.contact import ContactGeometry, ContactKinematics, Hertz, Smoothing, film_force
from jaxclear.dynamics import evaluate, initial_state
from jaxclear.friction import friction_law_from_name

MU, LENGTH, RADIUS, CLEARANCE = 0.4, 0.01, 0.0095, 5e-4
"""Film of the journal tests: SAE-40-like oil (Pa s), the benchmark pin (m)."""

QUADRATURE_RTOL = 1e-6
"""Closed forms vs trapezoidal quadrature on 2e5 points of a periodic/smooth integrand (the
quadrature itself is good to ~1e-9 here; the margin covers the kink at the film's ends)."""


# --- (i) closed forms against a quadrature of Reynolds' pressure, in the inertial frame -----------
def _film_quadrature(theory, ecc, rate, omega_j, omega_b, n=200_001):
    """Force on the journal from Reynolds' equation written in the fixed frame, by NumPy quadrature.

    Independent of the library's derivation: h(α) = c − e⃗·u(α), u = (cos α, sin α); the film
    is generated where G(α) = (ω_J + ω_B) ∂h/∂α + 2 ∂h/∂t < 0 (∂h/∂t = −ė⃗·u at fixed α).
    Short bearing: p = −3μ (L²/4 − z²) G/h³ clipped at 0 (only where positive), integrated over
    z in closed form (L³/6). Long bearing: h³ p' = 6μR² (∫G dα + K) with p = 0 at both ends of
    the region G < 0, K from that condition. F = −R ∫ p u dα (× L for the long bearing).
    """
    alpha = np.linspace(0.0, 2.0 * np.pi, n)
    u = np.stack([np.cos(alpha), np.sin(alpha)])
    h = CLEARANCE - ecc @ u
    dh_da = -ecc @ np.stack([-np.sin(alpha), np.cos(alpha)])
    dh_dt = -rate @ u
    g = (omega_j + omega_b) * dh_da + 2.0 * dh_dt
    if theory == "short":
        p = np.maximum(-3.0 * MU * g / h**3, 0.0) * LENGTH**3 / 6.0
        return -RADIUS * np.trapezoid(p * u, alpha, axis=1)
    # G = g_c cos α + g_s sin α is negative on one half circle, (β + π/2, β + 3π/2)
    w = omega_j + omega_b
    beta = np.arctan2(w * ecc[0] - 2.0 * rate[1], -w * ecc[1] - 2.0 * rate[0])
    phi = np.linspace(beta + 0.5 * np.pi, beta + 1.5 * np.pi, n)
    uu = np.stack([np.cos(phi), np.sin(phi)])
    hh = CLEARANCE - ecc @ uu
    gg = w * (-ecc @ np.stack([-np.sin(phi), np.cos(phi)])) + 2.0 * (-rate @ uu)
    assert np.all(gg <= 1e-12 * np.abs(gg).max())
    big_g = np.concatenate([[0.0], np.cumsum(0.5 * (gg[1:] + gg[:-1]) * np.diff(phi))])
    k_const = -np.trapezoid(big_g / hh**3, phi) / np.trapezoid(1.0 / hh**3, phi)
    dp = 6.0 * MU * RADIUS**2 * (big_g + k_const) / hh**3
    p = np.concatenate([[0.0], np.cumsum(0.5 * (dp[1:] + dp[:-1]) * np.diff(phi))])
    assert p.min() > -1e-6 * p.max(), "the long-bearing film must have no suction"
    return -RADIUS * LENGTH * np.trapezoid(p * uu, phi, axis=1)


def _lubrication(theory="short", **kw):
    return jaxclear.Lubrication(MU, LENGTH, theory=theory, **kw)


@eqx.filter_jit
def _film(lubrication, ecc, rate, omega_j, omega_b):
    return film_force(lubrication, ecc, rate, omega_j, omega_b, RADIUS, CLEARANCE)


def _library_film(theory, ecc, rate, omega_j, omega_b):
    f = _film(_lubrication(theory), jnp.asarray(ecc), jnp.asarray(rate), omega_j, omega_b)
    return np.asarray(f.force)


@pytest.mark.parametrize("theory", ["short", "long"])
def test_closed_forms_match_reynolds_quadrature(theory):
    rng = np.random.default_rng(26)
    for _ in range(6):
        eps = rng.uniform(0.0, 0.85)
        angle = rng.uniform(0, 2 * np.pi)
        ecc = eps * CLEARANCE * np.array([np.cos(angle), np.sin(angle)])
        rate = rng.normal(size=2) * 0.05  # m/s: squeeze and whirl of either sign
        omega_j, omega_b = rng.normal(size=2) * 300.0
        got = _library_film(theory, ecc, rate, omega_j, omega_b)
        want = _film_quadrature(theory, ecc, rate, omega_j, omega_b)
        np.testing.assert_allclose(got, want, rtol=QUADRATURE_RTOL, atol=1e-9 * np.abs(want).max())


def test_long_bearing_reduces_to_sommerfeld_half_film():
    """Steady load (no squeeze): the classical half-Sommerfeld forces (Pinkus & Sternlicht)."""
    eps, w = 0.6, 400.0
    f = _library_film("long", np.array([eps * CLEARANCE, 0.0]), np.zeros(2), w, 0.0)
    k = MU * RADIUS**3 * LENGTH / CLEARANCE**2
    radial = -12.0 * k * w * eps**2 / ((2 + eps**2) * (1 - eps**2))
    tangential = 6.0 * math.pi * k * w * eps / ((2 + eps**2) * math.sqrt(1 - eps**2))
    np.testing.assert_allclose(f, [radial, tangential], rtol=1e-12)


def test_centred_journal_is_regular():
    """e = 0: the force is the squeeze damper −πK ė⃗/c for any direction, with finite gradients."""
    lub = _lubrication()
    k = MU * RADIUS * LENGTH**3 / (2 * CLEARANCE**2)
    rate = np.array([0.03, -0.04])
    got = _library_film("short", np.zeros(2), rate, 200.0, -50.0)
    np.testing.assert_allclose(got, -math.pi * k * rate / CLEARANCE, rtol=1e-12)

    @jax.jit
    @jax.grad
    def total(ecc_and_rate):
        f = film_force(lub, *ecc_and_rate, 200.0, -50.0, RADIUS, CLEARANCE)
        return jnp.sum(f.force) + f.torque

    for rate in (jnp.zeros(2), jnp.asarray(rate)):
        grads = total((jnp.zeros(2), rate))
        assert all(np.all(np.isfinite(np.asarray(g))) for g in grads)
    # and continuous: a tiny offset changes the force by a tiny amount
    near = _library_film("short", np.array([1e-9, 0.0]), np.asarray(rate), 200.0, -50.0)
    np.testing.assert_allclose(near, got, rtol=1e-5)


# --- (ii) steady load: Ocvirk's attitude angle -----------------------------------------------------
@jax.jit
def _steady_residual(x, load, omega):
    """Film force at e⃗ = x c, journal turning at ``omega``, minus the upward reaction to ``load``."""
    f = film_force(_lubrication(), x * CLEARANCE, jnp.zeros(2), omega, 0.0, RADIUS, CLEARANCE)
    return f.force / load - jnp.array([0.0, 1.0])


_steady_jacobian = jax.jit(jax.jacfwd(_steady_residual))


def _equilibrium(load, omega):
    """Journal position where the film carries ``load`` (downwards): SciPy root of the residual."""
    sol = root(
        lambda x: np.asarray(_steady_residual(x, load, omega)),
        np.array([0.35, -0.35]),
        jac=lambda x: np.asarray(_steady_jacobian(x, load, omega)),
        tol=1e-13,
    )
    assert sol.success and np.max(np.abs(sol.fun)) < 1e-10
    return sol.x * CLEARANCE


@pytest.mark.parametrize("load", [2.0, 10.0, 26.0])
def test_steady_load_satisfies_ocvirk_attitude(load):
    ecc = _equilibrium(load, omega=300.0)
    eps = np.hypot(*ecc) / CLEARANCE
    attitude = math.atan2(abs(ecc[0]), -ecc[1])  # from the load line (−y) to the line of centres
    assert 0.0 < eps < 0.9
    np.testing.assert_allclose(
        math.tan(attitude), math.pi * math.sqrt(1 - eps**2) / (4 * eps), rtol=1e-9
    )
    # the line of centres lies at φ from the load line in the direction of rotation (counter-
    # clockwise here: from −y towards +x), as in Pinkus & Sternlicht
    assert ecc[0] > 0


# --- Petroff's law: the viscous torque of a centred journal -------------------------------------------
def _petroff_torque(omega_rel, load=100.0):
    """Petroff's law in Shigley's form (Shigley & Mischke, *Mechanical Engineering Design*, the
    Petroff equation): f R/c = 2π² S with the Sommerfeld number S = (R/c)² μN/P, N in rev/s and
    P = W/(2RL); the torque is T = fWR (W cancels). In SI: T = 2πμR³Lω/c."""
    n = abs(omega_rel) / (2.0 * math.pi)
    sommerfeld = (RADIUS / CLEARANCE) ** 2 * MU * n / (load / (2.0 * RADIUS * LENGTH))
    friction = 2.0 * math.pi**2 * sommerfeld * CLEARANCE / RADIUS
    return friction * load * RADIUS


def _couette_torque_quadrature(eps, omega_rel, n=4096):
    """Shear of the Couette flow over the full film on the journal, by quadrature: τ = μRω/h with
    h = c(1 + ε cos θ), torque ∫ τ R · L R dθ (the periodic trapezoidal rule is spectrally accurate)."""
    theta = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    h = CLEARANCE * (1.0 + eps * np.cos(theta))
    return np.sum(MU * RADIUS * omega_rel / h * RADIUS * LENGTH * RADIUS) * (2.0 * np.pi / n)


def _torque(lubrication, ecc, omega_j, omega_b):
    f = _film(lubrication, jnp.asarray(ecc, dtype=float), jnp.zeros(2), omega_j, omega_b)
    return float(f.torque)


def test_petroff_torque_of_a_centred_journal():
    """ε → 0: the `petroff` option's torque is Petroff's law, opposing the journal's rotation
    relative to the bearing; off the centre it is the Couette shear over the full film
    (∝ 1/√(1 − ε²)); without the option, and at the wall (film blended out), there is none."""
    lub = _lubrication(petroff=True)
    for omega_j, omega_b in ((300.0, -50.0), (-120.0, 80.0)):
        rel = omega_j - omega_b
        want = -math.copysign(_petroff_torque(rel), rel)
        np.testing.assert_allclose(_torque(lub, [0.0, 0.0], omega_j, omega_b), want, rtol=1e-12)
        np.testing.assert_allclose(
            _torque(lub, [1e-6 * CLEARANCE, 0.0], omega_j, omega_b), want, rtol=1e-11
        )
        assert _torque(_lubrication(), [0.0, 0.0], omega_j, omega_b) == 0.0
        for eps in (0.3, 0.6, 0.85):  # inside ε₀ = 0.9: the film alone
            ecc = eps * CLEARANCE * np.array([0.6, -0.8])
            np.testing.assert_allclose(
                _torque(lub, ecc, omega_j, omega_b),
                -_couette_torque_quadrature(eps, rel),
                rtol=1e-10,
            )
        assert _torque(lub, [1.0001 * CLEARANCE, 0.0], omega_j, omega_b) == 0.0  # in the wall


def test_petroff_torque_reaches_journal_and_bearing():
    """Through the equations of motion (no solve): a centred journal spinning in a free housing,
    no load and no squeeze: the journal is braked and the housing driven by Petroff's torque
    (I α = ∓T), and nothing moves the centres."""
    inertia_h, inertia_j = 3e-3, 1e-3
    housing = jaxclear.Body("housing", 2.0, inertia_h, position=(0.0, 0.0, 0.0))
    journal = jaxclear.Body("journal", JOURNAL_MASS, inertia_j, position=(0.0, 0.0, 0.0))
    joint = jaxclear.ClearanceJoint(
        "J",
        "housing",
        (0.0, 0.0),
        "journal",
        (0.0, 0.0),
        geometry=ContactGeometry(RADIUS + CLEARANCE, RADIUS, length=LENGTH),
        contact_law=Hertz(),
        friction_law=friction_law_from_name("none"),
        lubrication=_lubrication(petroff=True),
    )
    m = jaxclear.Mechanism(bodies=(housing, journal), clearance_joints=(joint,), gravity=(0, 0))
    omega_h, omega_j = -50.0, 300.0
    y = initial_state(m, jnp.zeros(6), jnp.array([0, 0, omega_h, 0, 0, omega_j]))
    qdd = np.asarray(evaluate(m, 0.0, y).qdd)
    torque = _petroff_torque(omega_j - omega_h)
    np.testing.assert_allclose(qdd[[2, 5]], [torque / inertia_h, -torque / inertia_j], rtol=1e-12)
    np.testing.assert_allclose(qdd[[0, 1, 3, 4]], 0.0, atol=1e-12)


# --- one journal in a ground bearing: squeeze drop and dynamic settling --------------------------
JOURNAL_MASS = 0.5
"""kg; light enough that the film, not inertia, sets the squeeze time scale."""


def _journal(speed, load, transition=(0.9, 0.1)):
    body = jaxclear.Body("journal", JOURNAL_MASS, 1e-3, position=(0.0, 0.0, 0.0))
    joint = jaxclear.ClearanceJoint(
        "J",
        "ground",
        (0.0, 0.0),
        "journal",
        (0.0, 0.0),
        geometry=ContactGeometry(RADIUS + CLEARANCE, RADIUS, length=LENGTH),
        contact_law=Hertz(),
        friction_law=friction_law_from_name("none"),
        lubrication=jaxclear.Lubrication(
            MU,
            LENGTH,
            transition_eccentricity=transition[0],
            transition_width=transition[1],
        ),
    )
    return jaxclear.Mechanism(
        bodies=(body,),
        driver=jaxclear.ConstantSpeedDriver(body="journal", speed=speed),
        clearance_joints=(joint,),
        gravity=(0.0, -load / JOURNAL_MASS),
    )


SQUEEZE_LOAD, SQUEEZE_TIME = 5.0, 0.02
"""N, s: the drop reaches ε ≈ 0.73, inside the film-only range (ε₀ = 0.9)."""


def _squeeze_reference(ts):
    """ε(t) of m c ε̈ = W − F(ε, ε̇) with F from SciPy quadrature of the short-bearing squeeze
    pressure over the half film where it is positive (journal falling: cos θ < 0)."""
    k = MU * RADIUS * LENGTH**3 / (2 * CLEARANCE**2)

    def force(eps, eps_rate):
        if eps_rate == 0.0:
            return 0.0
        lo, hi = (np.pi / 2, 3 * np.pi / 2) if eps_rate > 0 else (-np.pi / 2, np.pi / 2)
        integral = quad(lambda th: np.cos(th) ** 2 / (1 + eps * np.cos(th)) ** 3, lo, hi)[0]
        return 2.0 * k * eps_rate * integral

    def rhs(t, y):
        eps, eps_rate = y
        return [eps_rate, (SQUEEZE_LOAD - force(eps, eps_rate)) / (JOURNAL_MASS * CLEARANCE)]

    sol = solve_ivp(rhs, (0.0, ts[-1]), [0.0, 0.0], t_eval=ts, rtol=1e-10, atol=1e-12)
    return sol.y[0]


@pytest.fixture(scope="module")
def squeeze_run():
    mechanism = _journal(0.0, SQUEEZE_LOAD)
    traj = jaxclear.simulate(mechanism, SQUEEZE_TIME, num_points=41, extremes=False)
    return mechanism, traj


def test_pure_squeeze_drop_matches_scipy(squeeze_run):
    _, traj = squeeze_run
    c = traj.clearance["J"]
    eps = np.hypot(c.ecc_x, c.ecc_y) / CLEARANCE
    want = _squeeze_reference(np.asarray(traj.t))
    assert 0.6 < want[-1] < 0.85
    np.testing.assert_allclose(eps, want, atol=2e-4)  # solver rtol 1e-6 on a drop of order 1
    np.testing.assert_allclose(np.asarray(c.ecc_x), 0.0, atol=1e-12)  # straight down
    assert float(np.max(c.normal_force)) == 0.0  # never touches the wall


@pytest.mark.slow  # the gradient's compilation alone takes ~50 s on 2 cores
def test_grad_wrt_viscosity_matches_central_difference(squeeze_run):
    mechanism, _ = squeeze_run

    def final_drop(viscosity):
        m = jaxclear.with_parameters(mechanism, {"J.viscosity": viscosity})
        traj = jaxclear.simulate(m, SQUEEZE_TIME / 4, num_points=41, extremes=False)
        return -traj.clearance["J"].ecc_y[-1] / CLEARANCE

    grad = float(jax.grad(final_drop)(MU))
    step = 1e-4 * MU
    fd = (float(final_drop(MU + step)) - float(final_drop(MU - step))) / (2 * step)
    assert np.isfinite(grad) and grad < 0  # thicker oil, slower drop
    np.testing.assert_allclose(grad, fd, rtol=1e-3)


# --- blend to dry contact ---------------------------------------------------------------------------
def test_total_force_continuous_through_the_switch():
    """Radial force (film + dry law) along a radial approach through ε₀, ε₀ + Δ and the wall:
    halving the grid spacing halves the largest jump between neighbours (a continuous, Lipschitz
    force), the film alone acts below ε₀ and the dry law alone beyond the wall."""
    lub = _lubrication(transition_eccentricity=0.8, transition_width=0.2)
    geometry = ContactGeometry(RADIUS + CLEARANCE, RADIUS, length=LENGTH)
    law, smoothing = Hertz(), Smoothing()
    rate = 0.02  # m/s towards the wall, with the journal turning

    def radial(eps):
        ecc = jnp.stack([eps * CLEARANCE, 0.0])
        film = film_force(lub, ecc, jnp.array([rate, 0.0]), 300.0, 0.0, RADIUS, CLEARANCE)
        kin = ContactKinematics(eps * CLEARANCE - CLEARANCE, rate, rate)
        return film.force[0] - law(kin, geometry, smoothing)[0], film.weight

    eps = jnp.linspace(0.7, 1.0 + 2e-5, 4001)
    force, weight = jax.jit(jax.vmap(radial))(eps)
    force, weight, eps = np.asarray(force), np.asarray(weight), np.asarray(eps)
    fine = np.max(np.abs(np.diff(force)))
    coarse = np.max(np.abs(np.diff(force[::2])))
    assert fine < 0.6 * coarse
    assert np.all(weight[eps <= 0.8] == 1.0)
    assert np.all(weight[eps >= 1.0] == 0.0)


def test_bad_lubrication_is_rejected():
    with pytest.raises(jaxclear.ModelError, match="viscosity"):
        jaxclear.Lubrication(-0.1, LENGTH)
    with pytest.raises(jaxclear.ModelError, match="transition_eccentricity"):
        jaxclear.Lubrication(MU, LENGTH, transition_eccentricity=1.0)
    with pytest.raises(jaxclear.ModelError, match="at most 1"):
        jaxclear.Lubrication(MU, LENGTH, transition_eccentricity=0.95, transition_width=0.1)
    with pytest.raises(jaxclear.ModelError, match="theory"):
        jaxclear.Lubrication(MU, LENGTH, theory="medium")


def test_per_joint_parameter_names():
    m = _benchmark(MU)
    names = jaxclear.parameter_names(m)
    assert {"B.viscosity", "B.lubrication.length", "B.transition_eccentricity"} <= set(names)
    assert jaxclear.parameter_info(m, "B.viscosity").unit == "Pa s"
    m2 = jaxclear.with_parameters(m, {"B.viscosity": 2.0, "B.lubrication.length": 0.02})
    assert float(jaxclear.get_parameter(m2, "B.viscosity")) == 2.0
    assert float(m2.clearance_joints[0].lubrication.length) == 0.02
    assert float(m2.clearance_joints[0].geometry.length) == float(
        m.clearance_joints[0].geometry.length
    )


# --- (iv) benchmark slider–crank at 5000 rpm ---------------------------------------------------------
RPM = 5000.0
REVOLUTION = 60.0 / RPM


def _benchmark(viscosity, joints=("B",), length=0.04):
    m = jaxclear.mechanisms.slider_crank(rpm=RPM, clearance_joints=list(joints))
    for k in range(len(m.clearance_joints)):
        m = eqx.tree_at(
            lambda m, k=k: m.clearance_joints[k].lubrication,
            m,
            jaxclear.Lubrication(viscosity, length),
            is_leaf=lambda x: x is None,
        )
    return m


@pytest.mark.slow
def test_benchmark_slider_crank_lubricated():
    """All three joints lubricated (L = 40 mm): thicker oil keeps the journals nearer the centre
    and the slider acceleration nearer the ideal joints'; the orbit stays inside ε < 1 for the
    thickest; thin oil lets the journals reach the wall (dry contact) without the solve failing."""
    revolutions = 3
    ts = np.linspace(REVOLUTION, revolutions * REVOLUTION, 601)
    ideal = jaxclear.simulate(
        jaxclear.mechanisms.slider_crank(rpm=RPM, clearance_joints=[]), ts[-1], ts=ts
    )
    base = _benchmark(0.4, joints=("O", "A", "B"))
    max_eps, error = [], []
    for viscosity in (0.05, 0.4, 4.0):
        m = jaxclear.with_parameters(base, {f"{j}.viscosity": viscosity for j in ("O", "A", "B")})
        traj = jaxclear.simulate(m, ts[-1], ts=ts, solver="imex")
        eps = max(
            float(np.max(np.hypot(c.ecc_x, c.ecc_y))) / CLEARANCE for c in traj.clearance.values()
        )
        max_eps.append(eps)
        error.append(float(np.sqrt(np.mean((traj.qdd[:, 6] - ideal.qdd[:, 6]) ** 2))))
    assert max_eps[0] > max_eps[1] > max_eps[2]
    assert max_eps[2] < 1.0
    assert error[0] > error[1] > error[2]
