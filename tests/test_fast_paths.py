"""The speed-ups must not change the model: batched clearance joints, the Gauss–Jordan Schur solve,
the IMEX stage solvers (``DiagonalNewton``, ``AffineKenCarp``) with their contract on the stiff
rates, and Lawson–Tsit5's offset form of the impact memory (its toy problems: tests/test_lawson.py)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

import jaxclear
from jaxclear.contact import Hybrid, LankaraniNikravesh
from jaxclear.dynamics import _clearance as clearance
from jaxclear.dynamics._batched import groups
from jaxclear.dynamics._equations import (
    memory_offset_shift,
    solve_accelerations,
    spd_solve,
    stiff_vector_field,
    vector_field,
)
from jaxclear.friction import FRICTION_LAWS, LuGre, ModifiedCoulomb, friction_law_from_name
from jaxclear.mechanisms import slider_crank
from jaxclear.solve._root_finder import DiagonalNewton

RNG = np.random.default_rng(7)
_vector_field = eqx.filter_jit(vector_field)
"""The vector fields below are compared jitted: one compilation each costs less CPU than running
them op by op (eager dispatch compiles every primitive apart)."""
Z_DENSE_TOLERANCE = 3e-10  # m, LuGre z through KenCarp5's dense output (see its test)
REFERENCE = jaxclear.SolverConfig(method="dopri8", rtol=1e-11, atol=1e-14)
"""The converged reference of the solves below. Solves of one mechanism with the same solver
settings and number of output points share one compilation (end times are traced), so the
reference runs of each mechanism use one point count (``LUGRE_POINTS``, ``ONE_JOINT_POINTS``)."""
LUGRE_POINTS = 51
ONE_JOINT_POINTS = 61
EXTREMES = False
"""Every solve here but the default call (``solver="auto"`` in
``test_default_solver_follows_the_converged_solution_through_the_first_contacts``) leaves
``Trajectory.extremes`` out: only trajectories are compared, which the extremes tracking does not
change, and a compilation takes about 40 % less CPU without it (measured 9.8 -> 5.9 s for a Dopri8
solve, 31 -> 21 s for the reverse-mode gradient through KenCarp5). Reverse mode through the
extremes tracking is checked by tests/test_transforms.py's one-joint Jacobians."""


def _perturbed_state(mech, scale=2e-4):
    """An assembled state with journals moved off-centre and random velocities and internal states."""
    y = np.array(jaxclear.assemble(mech, 0.0))
    n = mech.num_coordinates
    y[:n] += scale * RNG.standard_normal(n)
    y[n : 2 * n] += 0.5 * RNG.standard_normal(n)
    y[2 * n :] = 1e-6 * RNG.standard_normal(y.shape[0] - 2 * n)
    return jnp.asarray(y)


@eqx.filter_jit
def _unbatched_rates(mech, t, y):
    """dy/dt with every clearance joint through its own mechanism-level functions (no vmap)."""
    assert not mech.forces
    q, qd, states = mech.split_state(y)
    total = jnp.zeros_like(q)
    for c in mech.clearance_joints:
        total = total + clearance.generalized_force(c, mech.index, q, qd, states[c.name])
    qdd = solve_accelerations(mech, t, q, qd, total)[0]
    rates = [
        clearance.state_derivative(c, mech.index, q, qd, qdd, states[c.name])
        for c in mech.clearance_joints
    ]
    return jnp.concatenate([qd, qdd, *rates])


@pytest.mark.parametrize("friction", ["lugre", "modified-coulomb"])
def test_batched_joints_equal_one_by_one(friction):
    mech = slider_crank(
        clearance_joints="O,A,B", clearance=5e-4, friction_law=friction_law_from_name(friction)
    )
    assert [len(g) for g in groups(mech)] == [3]
    for _ in range(3):
        y = _perturbed_state(mech)
        batched = np.asarray(_vector_field(0.001, y, mech))
        single = np.asarray(_unbatched_rates(mech, 0.001, y))
        np.testing.assert_allclose(batched, single, rtol=1e-12, atol=1e-9 * np.max(np.abs(single)))
        assert np.max(np.abs(single[9:18])) > 1.0  # contact forces are acting


def test_grouping_keeps_different_laws_apart():
    # B with another restitution (array value): same group; A with another law class or static
    # option: own group.
    mech = slider_crank(
        clearance_joints={
            "O": dict(contact_law=Hybrid(num_elements=16)),
            "A": dict(contact_law=Hybrid(num_elements=8)),
            "B": dict(contact_law=Hybrid(num_elements=16, restitution=0.5)),
        },
        clearance=5e-4,
    )
    assert sorted(tuple(e.name for e in g) for g in groups(mech)) == [("A",), ("O", "B")]
    mech2 = slider_crank(
        clearance_joints={"O": dict(contact_law=LankaraniNikravesh()), "A": {}, "B": {}},
        clearance=5e-4,
    )
    assert sorted(tuple(e.name for e in g) for g in groups(mech2)) == [("A", "B"), ("O",)]
    y = _perturbed_state(mech)
    np.testing.assert_allclose(
        np.asarray(_vector_field(0.0, y, mech)),
        np.asarray(_unbatched_rates(mech, 0.0, y)),
        rtol=1e-12,
        atol=1e-6,
    )


def test_gauss_jordan_solve_matches_numpy():
    for m in (1, 2, 3, 7, 12, 13):
        a = RNG.standard_normal((m, m + 3))
        s = a @ a.T + 1e-3 * np.eye(m)
        b = RNG.standard_normal(m)
        np.testing.assert_allclose(
            np.asarray(spd_solve(jnp.asarray(s), jnp.asarray(b))),
            np.linalg.solve(s, b),
            rtol=1e-9,
            atol=1e-12,
        )


@pytest.mark.parametrize("offset", [False, True], ids=["memory", "memory-offset"])
@pytest.mark.parametrize("friction", list(FRICTION_LAWS))
def test_stiff_rates_are_affine_and_diagonal_in_the_internal_states(friction, offset):
    """The contract DiagonalNewton(affine=True) and Lawson–Tsit5's decay rates rely on, for every
    friction law with the memory in both forms."""
    mech = slider_crank(
        clearance_joints="O,A,B", clearance=5e-4, friction_law=friction_law_from_name(friction)
    )
    mech = mech.with_memory_offset(offset)
    n = 2 * mech.num_coordinates
    jacobian = eqx.filter_jit(jax.jacfwd(lambda z, m: stiff_vector_field(0.0, z, m)))
    for _ in range(2):
        y = _perturbed_state(mech)
        jac = np.asarray(jacobian(y, mech))
        assert np.all(jac[:n] == 0.0)  # q, q̇ rows of the stiff part are zero
        block = jac[n:, n:]
        np.testing.assert_array_equal(
            block, np.diag(np.diag(block))
        )  # diagonal in the internal states
        # affine: the Jacobian does not depend on the internal states
        y2 = y.at[n:].set(1e-3 * jnp.asarray(RNG.standard_normal(y.shape[0] - n)))
        jac2 = np.asarray(jacobian(y2, mech))
        np.testing.assert_allclose(jac2[n:, n:], block, rtol=1e-12, atol=0.0)


def _stage_residual(mech, y_partial, h):
    """r(f) = f − f_I(y_partial + h f), the f-space stage equation of diffrax's IMEX solvers."""
    return lambda f, args: f - stiff_vector_field(0.0, y_partial + h * f, mech)


@pytest.mark.parametrize("affine", [True, False])
def test_diagonal_newton_solves_the_stage_equation(affine):
    mech = slider_crank(clearance_joints="O,A,B", clearance=5e-4, friction_law=LuGre())
    n = 2 * mech.num_coordinates
    y_partial = _perturbed_state(mech)
    fn = _stage_residual(mech, y_partial, 1e-5)  # h·rate ≈ 1e2: stiff
    start = jnp.asarray(RNG.standard_normal(y_partial.shape[0]))  # explicit rows wrong on purpose
    solver = DiagonalNewton(rtol=1e-10, atol=1e-12, num_explicit=n, affine=affine)
    sol = optx.root_find(fn, solver, start, max_steps=10, throw=False)
    assert sol.result == optx.RESULTS.successful
    assert int(sol.stats["num_steps"]) == (1 if affine else 2)
    residual = np.asarray(fn(sol.value, None))
    assert np.max(np.abs(residual)) < 1e-9 * max(1.0, float(np.max(np.abs(np.asarray(sol.value)))))
    assert np.all(np.asarray(sol.value)[:n] == 0.0)


def test_diagonal_newton_general_mode_is_safe_on_coupled_rows():
    # Coupled rows break the diagonal assumption: the one-step (affine) mode stops at a wrong point
    # (the contract test above guards the stiff rates against that); the general mode says it
    # failed instead of returning that point.
    a = jnp.array([[1.0, 0.0, 0.0], [0.0, 2.0, 5.0], [0.0, 5.0, 2.0]])
    b = jnp.array([0.0, 1.0, 0.0])
    fn = lambda f, args: a @ f - b  # noqa: E731
    general = DiagonalNewton(rtol=1e-10, atol=1e-12, num_explicit=1, affine=False)
    sol = optx.root_find(fn, general, jnp.zeros(3), max_steps=100, throw=False)
    assert sol.result == optx.RESULTS.nonlinear_divergence
    one_step = DiagonalNewton(rtol=1e-10, atol=1e-12, num_explicit=1, affine=True)
    wrong = optx.root_find(fn, one_step, jnp.zeros(3), max_steps=100, throw=False)
    assert np.max(np.abs(np.asarray(fn(wrong.value, None)))) > 0.1


@pytest.fixture(scope="module")
def lugre_runs():
    """B joint with LuGre over the first 0.5 ms (first contact, with a stick phase), IMEX with
    closed-form stage solves (AffineKenCarp) vs Dopri8. Tight tolerances: at rtol 1e-6 both
    explicit and IMEX solvers miss the stick phase (see tests/test_solver_accuracy.py)."""
    mech = slider_crank(
        clearance_joints="B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=LuGre(),
    )
    ts = np.linspace(0.0, 0.5e-3, LUGRE_POINTS)
    imex = jaxclear.simulate(
        mech,
        0.5e-3,
        ts=ts,
        solver=jaxclear.SolverConfig(method="kencarp5", rtol=1e-9, atol=1e-12),
        extremes=EXTREMES,
    )
    ref = jaxclear.simulate(mech, 0.5e-3, ts=ts, solver=REFERENCE, extremes=EXTREMES)
    return imex, ref


def test_imex_matches_explicit_reference(lugre_runs):
    imex, ref = lugre_runs
    assert imex.stats()["succeeded"] and ref.stats()["succeeded"]
    ecc = lambda tr: np.stack([np.asarray(tr.clearance["B"][k]) for k in ("ecc_x", "ecc_y")], -1)  # noqa: E731
    assert (
        np.max(np.abs(np.asarray(ref.clearance["B"]["normal_force"]))) > 100.0
    )  # contact happened
    np.testing.assert_allclose(ecc(imex), ecc(ref), atol=1e-9)  # m, of a 5e-4 m clearance
    # z (~5e-7 m) at the saved times comes from KenCarp5's dense output, a polynomial through a
    # step in which z may relax at h·σ0|v|/g ≫ 1: measured max differences 1.4e-10 m (closed-form
    # stage solves) and < 1e-10 m (diffrax's KenCarp5 + DiagonalNewton), from step sequences that
    # differ at rounding level.
    np.testing.assert_allclose(
        np.asarray(imex.clearance["B"]["friction_state"]),
        np.asarray(ref.clearance["B"]["friction_state"]),
        atol=Z_DENSE_TOLERANCE,
    )


def test_auto_solver_choice():
    """``auto``: IMEX when a friction law has internal states (LuGre), Tsit5 otherwise."""
    assert jaxclear.recommended_solver(slider_crank()).method == "tsit5"
    assert (
        jaxclear.recommended_solver(slider_crank(clearance_joints="B", friction_law=LuGre())).method
        == "kencarp4"
    )
    coulomb = slider_crank(
        clearance_joints="O,A,B", friction_law=friction_law_from_name("modified-coulomb")
    )
    assert jaxclear.recommended_solver(coulomb).method == "tsit5"
    with pytest.raises(ValueError, match="solver 'auto' needs the mechanism"):
        jaxclear.solve.solver_config("auto")


@pytest.fixture(scope="module")
def one_joint():
    """The one-joint benchmark case: B, Lankarani–Nikravesh, modified Coulomb μ = 0.01."""
    return slider_crank(
        clearance_joints="B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(0.01),
    )


FIRST_CONTACTS = 1.5e-3  # s: free flight, first impacts, sliding
LAWSON = jaxclear.SolverConfig(method="lawson-tsit5", rtol=1e-7, atol=1e-10)


@pytest.fixture(scope="module")
def first_contacts_reference(one_joint):
    ts = np.linspace(0.0, FIRST_CONTACTS, ONE_JOINT_POINTS)
    return jaxclear.simulate(one_joint, FIRST_CONTACTS, ts=ts, solver=REFERENCE, extremes=EXTREMES)


@pytest.mark.parametrize("solver", ["auto", "lawson-tsit5"])
def test_default_solver_follows_the_converged_solution_through_the_first_contacts(
    solver, one_joint, first_contacts_reference
):
    """The defaults (``auto`` = Tsit5 with the PI controller, rtol 1e-6), and Lawson–Tsit5 at rtol
    1e-7, on the one-joint benchmark case (B, Lankarani–Nikravesh, modified Coulomb μ = 0.01): the
    first 1.5 ms (free flight, first impacts, sliding) stay within 0.2 µm of Dopri8 at rtol 1e-11.
    ``benchmarks/first_contact_accuracy.py --spread`` (rtol × 0.8 … 1.25, atol = rtol/1000)
    measured Tsit5 at 1e-6 0.042–0.13 µm and Lawson–Tsit5 at 1e-7 0.0019–0.017 µm (at 1e-6 it
    was up to 0.44 µm: it takes the accuracy the tolerance allows)."""
    ts = np.linspace(0.0, FIRST_CONTACTS, ONE_JOINT_POINTS)
    if solver == "auto":  # the default call, as users make it
        fast = jaxclear.simulate(one_joint, FIRST_CONTACTS, ts=ts)
    else:
        fast = jaxclear.simulate(one_joint, FIRST_CONTACTS, ts=ts, solver=LAWSON, extremes=EXTREMES)
    b, r = fast.clearance["B"], first_contacts_reference.clearance["B"]
    assert float(np.max(np.asarray(r["normal_force"]))) > 1e3  # impacts happened
    dist = np.hypot(
        np.asarray(b["ecc_x"]) - np.asarray(r["ecc_x"]),
        np.asarray(b["ecc_y"]) - np.asarray(r["ecc_y"]),
    )
    print(f"{solver}: max orbit distance from Dopri8 over 1.5 ms {np.max(dist) * 1e6:.4f} µm")
    assert np.max(dist) < 2e-7


def test_memory_forms_give_the_same_trajectory(one_joint):
    """The offset form u = m − δ̇ that Lawson–Tsit5 integrates is the same model as the absolute form
    (dynamics/_impact_memory.py): over the first impacts (0.6 ms) at tight tolerance the orbits and
    the latched impact velocities agree, and states convert back and forth exactly. (The absolute
    run reuses the compiled reference solve above.)"""
    mech = one_joint
    ts = np.linspace(0.0, 6e-4, ONE_JOINT_POINTS)
    absolute = jaxclear.simulate(mech, 6e-4, ts=ts, solver=REFERENCE, extremes=EXTREMES)
    offset = jaxclear.simulate(
        mech.with_memory_offset(), 6e-4, ts=ts, solver=REFERENCE, extremes=EXTREMES
    )
    assert (
        float(np.max(np.asarray(absolute.clearance["B"]["normal_force"]))) > 1e3
    )  # impacts happened
    for key, atol in (("ecc_x", 1e-10), ("ecc_y", 1e-10), ("impact_velocity", 1e-6)):
        np.testing.assert_allclose(
            np.asarray(offset.clearance["B"][key]),
            np.asarray(absolute.clearance["B"][key]),
            rtol=0,
            atol=atol,
        )
    y = absolute.y_final
    u = y - memory_offset_shift(mech, y)
    assert float(u[-1]) != float(y[-1])
    np.testing.assert_allclose(u + memory_offset_shift(mech, u), y, rtol=0, atol=1e-15)


def test_lawson_run_returns_the_absolute_memory(one_joint):
    """Lawson–Tsit5 solves the offset form inside; the trajectory holds m (= δ̇ in free flight).
    (The settings of the first-contact test above: one compilation.)"""
    ts = np.linspace(0.0, 1e-4, ONE_JOINT_POINTS)  # free flight from the centred start
    tr = jaxclear.simulate(one_joint, 1e-4, ts=ts, solver=LAWSON, extremes=EXTREMES)
    b = tr.clearance["B"]
    assert float(np.max(np.abs(np.asarray(b["penetration_rate"])))) > 1.0  # m/s: it moves
    np.testing.assert_allclose(
        np.asarray(b["impact_velocity"]), np.asarray(b["penetration_rate"]), rtol=0, atol=1e-9
    )
    np.testing.assert_allclose(
        np.asarray(tr.internal_state[:, 0]), np.asarray(b["penetration_rate"]), rtol=0, atol=1e-9
    )


def test_gradient_through_the_imex_solver():
    """d(ecc_x at 0.25 ms)/dc with LuGre through KenCarp5 + DiagonalNewton (what ``auto`` picks): the
    implicit-function gradient of the stage solves agrees with converged central differences of the
    Dopri8 reference (measured 0.88285 vs 0.88600, 0.36 %; the IMEX solution's own difference
    quotient is noisier because its step sequence changes with c)."""
    ts = np.linspace(0.0, 2.5e-4, 11)

    def build(c):
        return slider_crank(
            clearance_joints="B",
            clearance=c,
            contact_law=LankaraniNikravesh(restitution=0.9),
            friction_law=LuGre(),
        )

    y0 = jaxclear.assemble(build(5e-4))

    def ecc(c, solver, ts=ts):
        traj = jaxclear.simulate(build(c), 2.5e-4, ts=ts, y0=y0, solver=solver, extremes=EXTREMES)
        return traj.clearance["B"]["ecc_x"][-1]

    grad = float(jax.jit(jax.grad(lambda c: ecc(c, "imex")))(5e-4))  # jitted: less to compile
    # converged central differences of the reference (the compiled solve of lugre_runs): two steps
    # a decade apart agree (measured 0.8859981 at both; a tight Tsit5 solution gave 0.886000 and
    # 0.885998); a difference quotient at the default rtol 1e-6 moved by 1.4 % when the assembled
    # start state changed by 3e-6 m/s
    grid = np.linspace(0.0, 2.5e-4, LUGRE_POINTS)
    fds = [
        (float(ecc(5e-4 + h, REFERENCE, grid)) - float(ecc(5e-4 - h, REFERENCE, grid))) / (2 * h)
        for h in (1e-7, 1e-8)
    ]
    assert abs(fds[0] - fds[1]) < 1e-4 * abs(fds[0])
    fd = fds[1]
    assert abs(fd) > 0.5  # the contact has moved the journal
    assert abs(grad - fd) < 5e-3 * abs(fd)  # measured 0.36 %
