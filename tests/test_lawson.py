"""``LawsonTsit5`` (jaxclear/solve/_lawson.py): Tsit5 on plain rows, exact integrating factor on decay rows.

Toy problems with known solutions: the solver is checked apart from the mechanism model (on the
mechanism, with the offset form of the impact memory: tests/test_fast_paths.py).
"""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxclear.solve._lawson import LawsonTsit5

RATE = 1e6  # 1/s: the impact-memory relaxation rate k_m of the benchmark (docs/model.md §5)


def oscillator_with_decay(t, y, args):
    """x'' = −x (plain rows 0, 1) and u' = −ℓ u (row 2), ℓ = args."""
    return jnp.stack([y[1], -y[0], -args * y[2]])


def decay_rate(t, y, args):
    return -jnp.reshape(args, (1,))


def solve(term, solver, y0, args, t1, ts, rtol=1e-8, max_steps=100_000):
    # t1 and the tolerances as arrays: diffeqsolve's filter_jit keeps Python floats static, so each
    # new value would compile again
    return diffrax.diffeqsolve(
        term,
        solver,
        0.0,
        jnp.asarray(t1, dtype=float),
        None,
        y0,
        args=args,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(
            rtol=jnp.asarray(rtol, dtype=float), atol=jnp.asarray(rtol * 1e-3, dtype=float)
        ),
        max_steps=max_steps,
    )


def test_without_decay_rows_it_is_tsit5():
    """rows = (): the same tableau, controller and interpolant as diffrax's Tsit5."""
    term = diffrax.ODETerm(lambda t, y, args: jnp.stack([y[1], -jnp.sin(y[0]) - 0.1 * y[1]]))
    y0 = jnp.array([2.0, 0.0])
    ts = jnp.linspace(0.0, 10.0, 37)
    ours = solve(term, LawsonTsit5(decay_rate, ()), y0, None, 10.0, ts)
    ref = solve(term, diffrax.Tsit5(), y0, None, 10.0, ts)
    assert int(ours.stats["num_steps"]) == int(ref.stats["num_steps"])
    np.testing.assert_allclose(ours.ys, ref.ys, rtol=0, atol=1e-12)


def test_decay_row_is_taken_exactly_at_any_step():
    """u' = −1e6 u beside a slow oscillator: explicit Tsit5 is stable only for h < ~3.5 µs (≥ 3e6
    steps over 10 s); Lawson follows the oscillator's accuracy and gives exp(−ℓt) exactly, also in
    the dense output between steps."""
    term = diffrax.ODETerm(oscillator_with_decay)
    y0 = jnp.array([1.0, 0.0, 1.0])
    ts = jnp.array([0.0, 1e-7, 5e-7, 2e-6, 1.0, 10.0])
    sol = solve(term, LawsonTsit5(decay_rate, (2,)), y0, jnp.asarray(RATE), 10.0, ts)
    assert int(sol.stats["num_steps"]) < 200
    np.testing.assert_allclose(
        sol.ys[:, 2], np.exp(-RATE * np.asarray(ts)), rtol=1e-12, atol=1e-300
    )
    np.testing.assert_allclose(sol.ys[:, 0], np.cos(np.asarray(ts)), atol=1e-7)


def forced(t, y, args):
    """u' = −λ (u − sin t): a decay row with forcing, where Lawson's frozen factor is not exact."""
    return jnp.stack([-args * (y[0] - jnp.sin(t))])


def forced_exact(t, lam, u0=0.0):
    steady = (lam**2 * np.sin(t) - lam * np.cos(t)) / (lam**2 + 1.0)
    return steady + (u0 + lam / (lam**2 + 1.0)) * np.exp(-lam * t)


def test_forcing_on_a_decay_row_converges_with_the_tolerance():
    lam = 1e3
    ts = jnp.linspace(0.0, 3.0, 31)
    errors = []
    for rtol in (1e-5, 1e-8):
        sol = solve(
            diffrax.ODETerm(forced),
            LawsonTsit5(decay_rate, (0,)),
            jnp.array([0.0]),
            jnp.asarray(lam),
            3.0,
            ts,
            rtol=rtol,
        )
        errors.append(
            float(np.max(np.abs(np.asarray(sol.ys[:, 0]) - forced_exact(np.asarray(ts), lam))))
        )
    assert errors[0] < 1e-4
    assert errors[1] < 1e-2 * errors[0]


def test_state_dependent_rate_matches_a_tight_reference():
    """ℓ(y) = −λ(1 + x²) changes within each step (frozen at the step start): the error estimate
    must still hold the step to the tolerance. Reference: Kvaerno5 at rtol 1e-11."""

    def field(t, y, lam):
        return jnp.stack([y[1], -y[0], -lam * (1.0 + y[0] ** 2) * y[2] + jnp.cos(3 * t)])

    def rate(t, y, lam):
        return jnp.reshape(-lam * (1.0 + y[0] ** 2), (1,))

    lam = jnp.asarray(1e4)
    y0 = jnp.array([1.0, 0.0, 0.5])
    ts = jnp.linspace(0.0, 2.0, 21)
    ours = solve(diffrax.ODETerm(field), LawsonTsit5(rate, (2,)), y0, lam, 2.0, ts, rtol=1e-8)
    ref = solve(diffrax.ODETerm(field), diffrax.Kvaerno5(), y0, lam, 2.0, ts, rtol=1e-11)
    np.testing.assert_allclose(ours.ys, ref.ys, rtol=0, atol=1e-8)


MEMBERS = {"lam": np.array([2e5, 1e6, 3e6, 1e3, 1e3]), "t1": np.array([2e-6, 2e-6, 2e-6, 1.0, 2.0])}
"""The vmapped members of the two gradient tests below, in one batch (one compilation): three rates
ending at 2 µs, and two members ending at 1 s and 2 s, long after the others."""


@pytest.fixture(scope="module")
def vmapped_jacobian():
    """d(u(t1), x(t1)) / d(ℓ, t1) of each member by ``jit(vmap(jacrev))``."""
    term = diffrax.ODETerm(oscillator_with_decay)
    y0 = jnp.array([1.0, 0.0, 1.0])

    def ends(lam, t1):
        ts = jnp.linspace(0.0, 1.0, 5) * t1
        ys = solve(term, LawsonTsit5(decay_rate, (2,)), y0, lam, t1, ts).ys
        return jnp.stack([ys[-1, 2], ys[-1, 0]])

    jacobian = jax.jit(jax.vmap(jax.jacrev(ends, argnums=(0, 1))))
    by_lam, by_t1 = jacobian(jnp.asarray(MEMBERS["lam"]), jnp.asarray(MEMBERS["t1"]))
    return np.asarray(by_lam), np.asarray(by_t1)  # (member, output u or x)


def test_gradient_and_vmap_through_the_solver(vmapped_jacobian):
    """Reverse-mode gradient of u(t1) with respect to ℓ against the analytic one, under vmap."""
    by_lam, _ = vmapped_jacobian
    lams, t1 = MEMBERS["lam"][:3], MEMBERS["t1"][:3]
    np.testing.assert_allclose(by_lam[:3, 0], -t1 * np.exp(-lams * t1), rtol=1e-9)


def test_vmapped_gradient_is_finite_when_members_finish_apart(vmapped_jacobian):
    """Members with different end times: the ones done first make zero-length steps while the
    others run; the dense output must not put a NaN into the gradient (it did: 0/0 in θ)."""
    by_lam, by_t1 = vmapped_jacobian
    assert np.all(np.isfinite(by_lam)) and np.all(np.isfinite(by_t1))
    # x = cos t, so d x(t1) / d t1 = -sin t1
    np.testing.assert_allclose(by_t1[3:, 1], -np.sin(MEMBERS["t1"][3:]), rtol=1e-6)


def test_configuration_errors_name_the_fix():
    import jaxclear

    with pytest.raises(ValueError, match="needs decay= and memory_rows="):
        jaxclear.SolverConfig(method="lawson-tsit5").make_solver()
    with pytest.raises(ValueError, match="memory_speed must be a positive number"):
        jaxclear.SolverConfig(method="lawson-tsit5", memory_speed=0.0)
