"""Consistent initial positions and velocities by Newton iteration (docs/model.md §1, Initial conditions).

Positions: Newton–Raphson on Φ(q, t0) = 0 with least-norm (pseudo-inverse) steps from the bodies'
initial guesses, so under-constrained mechanisms move as little as possible. Clearance joints take
part as ideal revolute joints whose journal sits at the given initial eccentricity (centred by
default). Velocities: the least-norm correction of the guessed q̇ that satisfies Φ_q q̇ = −Φ_t.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core._errors import AssemblyError
from .._core._executable_cache import stored_jit
from . import _clearance as clearance
from . import _translational as translational
from ._constraints import constraints

NEWTON_ITERATIONS = 40
POSITION_TOLERANCE = 1e-10  # m (or rad): far below any clearance of interest (>= 1 µm)
RANK_TOLERANCE = 1e-9  # relative singular value below which constraints count as redundant
VELOCITY_CORRECTIONS = 2  # see assemble_state
STEP_LENGTHS = np.array([1.0, 0.5, 0.25, 0.125, 0.0625])  # damped Newton step lengths tried


def assembly_constraints(mechanism, q, t):
    """Φ plus the clearance joints' assembly rows (journal at its initial eccentricity; slider at its
    initial tilt and lateral offset in a translational clearance joint's guide)."""
    rows = [constraints(mechanism, q, t)]
    rows += [
        clearance.assembly_constraint(joint, mechanism.index, q, t)
        for joint in mechanism.clearance_joints
    ]
    rows += [
        translational.assembly_constraint(joint, mechanism.index, q, t)
        for joint in mechanism.translational_clearance_joints
    ]
    return jnp.concatenate(rows)


def assembly_labels(mechanism) -> list[str]:
    """A label per row of ``assembly_constraints``: ``"<joint name> [row k]"``."""
    labels = []
    for c in mechanism.constraint_elements:
        labels += [f"{type(c).__name__} {c.name!r} row {k}" for k in range(c.num_equations)]
    for joint in mechanism.clearance_joints:
        labels += [
            f"{type(joint).__name__} {joint.name!r} (journal at its initial eccentricity) row {k}"
            for k in range(clearance.ASSEMBLY_EQUATIONS)
        ]
    for joint in mechanism.translational_clearance_joints:
        labels += [
            f"{type(joint).__name__} {joint.name!r} (slider at its initial tilt and offset) row {k}"
            for k in range(translational.ASSEMBLY_EQUATIONS)
        ]
    return labels


def _least_norm_solve(jac, rhs):
    """Least-norm x with J x ≈ rhs: x = Jᵀ (J Jᵀ + εI)⁻¹ rhs (ε tiny; keeps redundant rows finite)."""
    if jac.shape[0] == 0:
        return jnp.zeros((jac.shape[1],), dtype=jac.dtype)
    jjt = jac @ jac.T
    eps = RANK_TOLERANCE * (jnp.trace(jjt) / jjt.shape[0] + 1e-30)
    return jac.T @ jnp.linalg.solve(jjt + eps * jnp.eye(jjt.shape[0], dtype=jac.dtype), rhs)


def _newton_positions(mechanism, t0):
    """q with Φ(q, t0) = 0 by damped least-norm Newton from the bodies' initial guesses."""
    q = mechanism.initial_guess()[0]

    def residual(q):
        return jnp.sum(assembly_constraints(mechanism, q, t0) ** 2)

    def step(_, q):
        phi = assembly_constraints(mechanism, q, t0)
        jac = jax.jacfwd(assembly_constraints, argnums=1)(mechanism, q, t0)
        delta = _least_norm_solve(jac, phi)
        # damped Newton: the best of a few step lengths (full step first), never worse than q, so a
        # loop that cannot close settles at its least-squares gap instead of wandering
        candidates = q[None, :] - STEP_LENGTHS[:, None] * delta[None, :]
        norms = jax.vmap(residual)(candidates)
        best = jnp.argmin(norms)
        return jnp.where(norms[best] < residual(q), candidates[best], q)

    return jax.lax.fori_loop(0, NEWTON_ITERATIONS, step, q)


@eqx.filter_custom_jvp
def assembled_positions(mechanism, t0):
    """The assembled q0 (``_newton_positions``), differentiated by the implicit function theorem.

    Differentiating the Newton loop itself gives the tangent of the iterates it happened to take:
    the damped step's choice of length and its "never worse" test freeze q, and with it the
    tangent, at the last accepted step, so dq0/dθ depended on rounding (on the benchmark
    slider–crank, d q0 / d(a joint point) came out 1.0 or 0.5 for the same parameters 1e-18
    apart, and along a body's initial guess, whose true effect on a determined mechanism is nil,
    0.5 instead of ~0; the sensitivity solve then spent 16x the steps integrating that noise).
    At the solution Φ(θ, q0, t0) = 0, so

        Φ_q dq0 = −(Φ_θ dθ + Φ_t dt0),   dq0 = −Φ_q⁺ (Φ_θ dθ + Φ_t dt0) + (I − Φ_q⁺ Φ_q) dg,

    with Φ_q⁺ the least-norm solve of the Newton steps and dg the tangent of the initial guess:
    the least-norm steps leave the guess's component in the null space of Φ_q where it was (for a
    determined mechanism Φ_q has full column rank and that term vanishes).
    """
    return _newton_positions(mechanism, t0)


@assembled_positions.def_jvp
def _assembled_positions_jvp(primals, tangents):
    mechanism, t0 = primals
    d_mechanism, d_t0 = tangents
    q = _newton_positions(mechanism, t0)
    dynamic, static = eqx.partition(mechanism, eqx.is_inexact_array)
    d_dynamic = jax.tree_util.tree_map(
        lambda x, d: jnp.zeros_like(x) if d is None else d, dynamic, d_mechanism
    )
    d_t0 = jnp.zeros_like(t0) if d_t0 is None else d_t0
    jac = jax.jacfwd(assembly_constraints, argnums=1)(mechanism, q, t0)
    _, d_phi = jax.jvp(
        lambda d, t: assembly_constraints(eqx.combine(d, static), q, t),
        (dynamic, t0),
        (d_dynamic, d_t0),
    )
    _, d_guess = jax.jvp(
        lambda d: eqx.combine(d, static).initial_guess()[0], (dynamic,), (d_dynamic,)
    )
    dq = d_guess - _least_norm_solve(jac, d_phi + jac @ d_guess)
    return q, dq


def assemble_state(mechanism, t0=0.0):
    """Pure JAX assembly (jit/vmap/grad friendly; q0's derivatives from the implicit function
    theorem, ``assembled_positions``).

    Returns:
        (q0, qd0, position_residual, velocity_residual): residuals are max-abs norms.
    """
    t0 = jnp.asarray(t0, dtype=float)
    qd = mechanism.initial_guess()[1]
    q = assembled_positions(mechanism, t0)
    phi = assembly_constraints(mechanism, q, t0)
    jac = jax.jacfwd(assembly_constraints, argnums=1)(mechanism, q, t0)
    phi_t = jax.jacfwd(assembly_constraints, argnums=2)(mechanism, q, t0)
    # two least-norm corrections: the first leaves O(RANK_TOLERANCE) of the velocity residual
    # (measured 2.7e-6 m/s on the benchmark slider-crank), the second removes it
    for _ in range(VELOCITY_CORRECTIONS):
        qd = qd - _least_norm_solve(jac, jac @ qd + phi_t)
    return (
        q,
        qd,
        jnp.max(jnp.abs(phi), initial=0.0),
        jnp.max(jnp.abs(jac @ qd + phi_t), initial=0.0),
    )


@stored_jit
def _assembly_diagnostics(mechanism, t0):
    """``assemble_state`` and, at its q, Φ and Φ_q for ``check_assembly``: one compiled call
    (evaluated op by op instead, the diagnostics compiled ~100 small programs, ~2 s per process)."""
    q, qd, pos_res, _ = assemble_state(mechanism, t0)
    jac = jax.jacfwd(assembly_constraints, argnums=1)(mechanism, q, t0)
    return q, qd, pos_res, jac, assembly_constraints(mechanism, q, t0)


def check_assembly(mechanism, t0=0.0):
    """Eager assembly with diagnostics: raises ``AssemblyError`` naming the failing constraint.

    Returns:
        (q0, qd0) as JAX arrays.

    Raises:
        AssemblyError: redundant/singular constraints (names the rows involved), or a geometry
            that does not close (names the worst constraint and its residual).
    """
    q, qd, pos_res, jac, phi = _assembly_diagnostics(mechanism, jnp.asarray(t0, float))
    labels = assembly_labels(mechanism)
    jac, phi = np.asarray(jac), np.asarray(phi)
    if jac.shape[0] > jac.shape[1]:
        raise AssemblyError(
            f"Mechanism has {jac.shape[0]} constraint equations for {jac.shape[1]} coordinates "
            "(over-constrained): remove a joint or the driver."
        )
    if not np.all(np.isfinite(phi)):
        raise AssemblyError(
            "Assembly produced non-finite coordinates: check the bodies' initial positions."
        )
    if jac.shape[0]:
        worst = int(np.argmax(np.abs(phi)))
        if abs(phi[worst]) > POSITION_TOLERANCE * 1e3 or not float(pos_res) < 1e-7:
            raise AssemblyError(
                f"Mechanism cannot be assembled: {labels[worst]} is off by {phi[worst]:.6g} m (or rad) at the "
                f"closest (least-squares) configuration, residual norm {np.linalg.norm(phi):.6g} over all rows. Check link lengths and joint points (does the "
                "loop close?) and the bodies' initial position guesses."
            )
        u, s, _ = np.linalg.svd(jac)
        if s[-1] < RANK_TOLERANCE * max(s[0], 1.0):
            null = u[:, -1]
            involved = [labels[k] for k in np.argsort(-np.abs(null)) if abs(null[k]) > 1e-3][:6]
            raise AssemblyError(
                "Constraints are redundant or singular at the assembled position (Φ_q loses rank, "
                f"smallest singular value {s[-1]:.3g}); involved: {', '.join(involved)}. Remove a redundant "
                "joint (e.g. use a translational joint or clearance joint instead) or move the initial "
                "guess away from a singular (dead-centre) configuration."
            )
    return q, qd
