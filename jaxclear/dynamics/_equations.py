"""Index-1 equations of motion with Baumgarte stabilisation (docs/model.md §1).

    [ M    Φ_qᵀ ] [ q̈ ]   [ Q                 ]
    [ Φ_q  0    ] [ λ  ] = [ γ − 2αΦ̇ − β²Φ    ]

M is diagonal in Cartesian coordinates, so the multipliers come from the small symmetric
positive definite Schur complement S = Φ_q M⁻¹ Φ_qᵀ (docs/model.md §5b):
λ = S⁻¹ (Φ_q M⁻¹ Q − rhs), q̈ = M⁻¹ (Q − Φ_qᵀ λ).
"""

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jaxtyping import Array, Float

from . import _clearance as clearance
from . import _translational as translational
from ._constraints import constraint_jacobian, constraints, gamma
from ._groups import GroupCache, evaluation_groups
from ._outputs import JointOutputs


class Evaluation(eqx.Module):
    """Everything the right-hand side computes at (t, y) (``evaluate``).

    Attributes:
        q, qd, qdd: coordinates, velocities and accelerations (n,).
        multipliers: Lagrange multipliers λ (m,) in ``mechanism.constraint_elements`` row order.
        phi, phi_dot: position and velocity constraint residuals Φ, Φ̇ (m,).
        forces: generalised forces Q (n,): gravity, force elements and clearance contacts.
        states: {force element name: internal state}.
        state_rates: {force element name: internal-state rate}.
    """

    q: Float[Array, " n"]
    qd: Float[Array, " n"]
    qdd: Float[Array, " n"]
    multipliers: Float[Array, " m"]
    phi: Float[Array, " m"]
    phi_dot: Float[Array, " m"]
    forces: Float[Array, " n"]
    states: dict[str, Float[Array, " s"]]
    state_rates: dict[str, Float[Array, " s"]]


def forces_and_caches(
    mechanism, t, q, qd, states: dict, gamma_h=None
) -> tuple[Float[Array, " n"], tuple[GroupCache, ...]]:
    """Q and each evaluation group's cache (in the order of ``evaluation_groups(mechanism)``).

    Q is gravity plus each group's contribution, summed in that order: every force element
    (applied forces, springs), then the clearance contacts (same-kind joints evaluated together,
    ``_batched``). ``gamma_h``: the internal states are an IMEX stage's explicit parts, solved for
    the stage's states (``implicit_stage``; ``AbstractEvaluationGroup.force_and_cache``).
    """
    m = jnp.stack([b.mass for b in mechanism.bodies])
    grav = jnp.concatenate(
        [m[:, None] * mechanism.gravity[None, :], jnp.zeros((len(m), 1))], axis=1
    )
    total = grav.reshape(-1).astype(q.dtype)
    caches = []
    for group in evaluation_groups(mechanism):
        force, cache = group.force_and_cache(mechanism, t, q, qd, states, gamma_h)
        total = total + force
        caches.append(cache)
    return total, tuple(caches)


def solve_accelerations(mechanism, t, q, qd, forces):
    """q̈ and λ from the Baumgarte-stabilised index-1 system.

    Returns:
        (q̈, λ, Φ, Φ̇): accelerations (n,), multipliers (m,), position and velocity residuals (m,).
    """
    inv_mass = 1.0 / mechanism.mass_diagonal
    if mechanism.num_constraints == 0:
        empty = jnp.zeros((0,), dtype=q.dtype)
        return inv_mass * forces, empty, empty, empty
    phi = constraints(mechanism, q, t)
    phi_q = constraint_jacobian(mechanism, q, t)
    gam, phi_dot = gamma(mechanism, q, qd, t)
    alpha, beta = mechanism.baumgarte_alpha, mechanism.baumgarte_beta
    rhs = gam - 2.0 * alpha * phi_dot - beta**2 * phi
    a = phi_q * inv_mass[None, :]
    # Tiny matrices: elementwise products and sums fuse in XLA and beat dot/LAPACK calls on CPU
    # (measured on the slider-crank: 8.2 -> 6.0 µs per evaluation of this function).
    schur = jnp.sum(a[:, None, :] * phi_q[None, :, :], axis=-1)
    lam = spd_solve(schur, jnp.sum(a * forces[None, :], axis=-1) - rhs)
    qdd = inv_mass * (forces - jnp.sum(phi_q * lam[:, None], axis=0))
    return qdd, lam, phi, phi_dot


UNROLLED_SOLVE_MAX = 9
"""Constraint count up to which the solve is unrolled at trace time. Per solve inside a compiled
loop, one core (``taskset -c 1 python benchmarks/spd_solve.py``), unrolled vs LAPACK Cholesky:
3 rows 0.10 vs 0.73 µs, 7 rows 0.58 vs 0.96 µs, 9 rows 1.81 vs 1.47 µs; vmapped over 8 lanes,
9 rows 0.74 vs 0.65 µs and 12 rows 2.45 vs 0.85 µs. 9 rows are unrolled although they cost
14–23 % more: that covers the ideal slider–crank and four-bar, so that their refilled ensemble
programs call no LAPACK routine in the step loop and may run on several CPU devices at once
(``jaxclear.studies._engine.concurrent_refill``)."""


def spd_solve(matrix, rhs, unrolled: bool | None = None):
    """Solve S x = b for a small symmetric positive definite S.

    ``unrolled``: ``None`` (default) picks by size, ``True``/``False`` forces one of the two
    ways (for benchmarks/spd_solve.py). Up to ``UNROLLED_SOLVE_MAX`` rows: Gauss–Jordan
    elimination without pivoting on [S | b] (stable for SPD matrices, like Cholesky), unrolled so that each elimination step is one
    elementwise update of the whole augmented array. XLA fuses each step into a single kernel,
    where an unrolled Cholesky with per-entry updates needed ~4 kernels per row (measured on the
    one-joint slider–crank, 82 → 43 kernels per right-hand side, 4.7 → 3.6 µs). LAPACK Cholesky above.
    """
    m = matrix.shape[0]
    if unrolled is None:
        unrolled = m <= UNROLLED_SOLVE_MAX
    if not unrolled:
        return jsl.cho_solve(jsl.cho_factor(matrix), rhs)
    aug = jnp.concatenate([matrix, rhs[:, None]], axis=1)
    rows = jnp.arange(m)[:, None]
    for j in range(m):
        pivot_row = aug[j] / aug[j, j]
        aug = jnp.where(rows == j, pivot_row[None, :], aug - aug[:, j : j + 1] * pivot_row[None, :])
    return aug[:, m]


def evaluate(mechanism, t, y) -> Evaluation:
    """Everything the right-hand side computes at (t, y): an ``Evaluation``."""
    q, qd, states = mechanism.split_state(y)
    return evaluate_with_caches(mechanism, t, q, qd, states)[0]


def evaluate_with_caches(
    mechanism, t, q, qd, states, gamma_h=None
) -> tuple[Evaluation, tuple[GroupCache, ...]]:
    """(``Evaluation``, the evaluation groups' caches); ``gamma_h``: see ``forces_and_caches``."""
    groups = evaluation_groups(mechanism)
    forces, caches = forces_and_caches(mechanism, t, q, qd, states, gamma_h)
    if gamma_h is not None:  # the stage's internal states, solved in forces_and_caches
        states = dict(states)
        for group, cache in zip(groups, caches):
            assert cache.stage is not None
            states.update(group.per_element(cache.stage[0]))
    qdd, lam, phi, phi_dot = solve_accelerations(mechanism, t, q, qd, forces)
    rates = {}
    for group, cache in zip(groups, caches):
        rates.update(group.state_rates(mechanism, cache, t, q, qd, qdd, states))
    evaluation = Evaluation(
        q=q,
        qd=qd,
        qdd=qdd,
        multipliers=lam,
        phi=phi,
        phi_dot=phi_dot,
        forces=forces,
        states=states,
        state_rates=rates,
    )
    return evaluation, caches


def state_rows(mechanism, head, per_element: dict, dtype) -> Float[Array, " N"]:
    """A state-shaped vector: the ``head`` arrays (q and q̇ rows), then each force element's
    entry of ``per_element`` in state order."""
    parts = [*head] + [per_element[e.name] for e in mechanism.force_elements]
    return jnp.concatenate([jnp.reshape(p, (-1,)).astype(dtype) for p in parts])


def vector_field(t, y, mechanism) -> Float[Array, " N"]:
    """dy/dt for diffrax: (q̇, q̈, internal state rates)."""
    out = evaluate(mechanism, t, y)
    return state_rows(mechanism, (out.qd, out.qdd), out.state_rates, y.dtype)


def implicit_stage(t, partial, gamma_h, mechanism):
    """An implicit stage of an IMEX method in one evaluation: (y, f(y), f_I(y)).

    y has the q, q̇ rows of ``partial`` and internal rows solving y = partial + γh f_I(y) (closed
    form: f_I, the stiff part, is affine and diagonal in the internal states with coefficients
    from q, q̇ only); f is the full vector field, f_I its stiff part, both at y. Each clearance
    joint's kinematics are computed once for both. (``AffineKenCarp`` used to evaluate the stiff
    part, with a Jacobian–vector product, and the full field apart: on the three-joint LuGre
    benchmark, one core, a KenCarp5 step took 50.8 µs, and 35.5 µs with the stiff evaluation
    replaced by constants in a local copy.)
    """
    return implicit_stage_and_evaluation(t, partial, gamma_h, mechanism)[0]


def implicit_stage_and_evaluation(
    t, partial, gamma_h, mechanism
) -> tuple[tuple[Any, Any, Any], Evaluation, tuple[GroupCache, ...]]:
    """``implicit_stage``'s (y, f(y), f_I(y)), with the ``Evaluation`` at y and the evaluation
    groups' caches it came from (the same operations): what an observation at the stage needs
    (``jaxclear.solve._observables.field_and_observation`` with ``gamma_h``)."""
    q, qd, states = mechanism.split_state(partial)
    out, caches = evaluate_with_caches(mechanism, t, q, qd, states, gamma_h)
    stiff = {}
    for group, cache in zip(evaluation_groups(mechanism), caches):
        assert cache.stage is not None  # solved in forces_and_caches with gamma_h
        stiff.update(group.per_element(cache.stage[1]))
    zeros = jnp.zeros((2 * mechanism.num_coordinates,), partial.dtype)
    stage = (
        state_rows(mechanism, (q, qd), out.states, partial.dtype),
        state_rows(mechanism, (out.qd, out.qdd), out.state_rates, partial.dtype),
        state_rows(mechanism, (zeros,), stiff, partial.dtype),
    )
    return stage, out, caches


def stiff_vector_field(t, y, mechanism) -> Float[Array, " N"]:
    """The stiff part of dy/dt (internal states only), integrated implicitly by IMEX solvers."""
    q, qd, states = mechanism.split_state(y)
    n = mechanism.num_coordinates
    rates = {}
    for group in evaluation_groups(mechanism):
        rates.update(group.stiff_rates(mechanism, t, q, qd, states))
    return state_rows(mechanism, (jnp.zeros((2 * n,), y.dtype),), rates, y.dtype)


def nonstiff_vector_field(t, y, mechanism) -> Float[Array, " N"]:
    """dy/dt minus its stiff part: the explicit part of an IMEX split."""
    return vector_field(t, y, mechanism) - stiff_vector_field(t, y, mechanism)


def memory_decay_rates(t, y, mechanism) -> Float[Array, " N"]:
    """ℓ: the diagonal decay rate −w(δ) k_m (1/s) of each impact-memory offset row, in the order of
    ``np.flatnonzero(mechanism.memory_rows)``.

    The stiff part is affine and diagonal in the internal states (tests/test_fast_paths.py checks
    the contract), so one Jacobian–vector product along the memory rows gives the diagonal.
    Used by ``jaxclear.solve._lawson.LawsonTsit5``.
    """
    mask = jnp.asarray(mechanism.memory_rows, y.dtype)
    _, rates = jax.jvp(lambda x: stiff_vector_field(t, x, mechanism), (y,), (mask,))
    return rates[np.flatnonzero(mechanism.memory_rows)]


def memory_offset_shift(mechanism, y) -> Float[Array, " N"]:
    """δ̇ of each clearance joint on its memory row, zero elsewhere: a state converts between the
    memory forms as y_offset = y_absolute − shift, y_absolute = y_offset + shift (q, q̇ and other
    rows are the same in both, so ``y`` may be either)."""
    q, qd, _ = mechanism.split_state(y)
    shift = jnp.zeros_like(y)
    slices = mechanism.state_slices
    for joint in mechanism.clearance_joints:
        rate = clearance.kinematics(joint, mechanism.index, q, qd).penetration_rate
        for r in joint.memory_state_rows:
            shift = shift.at[slices[joint.name].start + r].set(rate)
    for joint in mechanism.translational_clearance_joints:
        rates = translational.memory_shift(joint, mechanism.index, q, qd)
        for k, r in enumerate(joint.memory_state_rows):
            shift = shift.at[slices[joint.name].start + r].set(rates[k])
    return shift


SLIP_RESOLUTION = 0.3
"""Where a step meets a friction law's slip band in contact it may change the slip velocity by at
most this fraction of the band's resolution u (``AbstractFrictionLaw.slip_transition``).
Measured (docs/differentiation.md, "Slip reversals in contact"): d(slider x)/dc over a revolution
of issue 22's case was −910.0 without the rule, −895.3 at 1, −900.63 at 0.3 and −900.62 at 0.1
(converged central difference −900.1 ± 0.3 %), in 1.017×, 1.027× and 1.057× the steps."""


def _slip_fraction(transition, v0, v1, pen0, pen1):
    """Largest fraction of a step that keeps Δv_T within ``SLIP_RESOLUTION`` u where the step
    meets the band |v_T| <= V in contact (``inf``: no limit)."""
    if transition is None:
        return jnp.asarray(jnp.inf)
    band, width = transition
    resolution = SLIP_RESOLUTION * width
    change = jnp.abs(v1 - v0)
    meets = (jnp.minimum(v0, v1) <= band) & (jnp.maximum(v0, v1) >= -band)
    contact = (pen0 > 0) | (pen1 > 0)
    limited = contact & meets & (change > resolution)
    return jnp.min(jnp.where(limited, resolution / jnp.where(limited, change, 1.0), jnp.inf))


def slip_step_fraction(mechanism, y0, y1) -> Float[Array, ""]:
    """The largest fraction of a step from ``y0`` to ``y1`` (states in either memory form) that
    resolves each friction law's slip reversal: where a clearance joint is in contact at either
    end and its slip velocity meets the band where the force turns over
    (``AbstractFrictionLaw.slip_transition``: |v_T| <= V), the step may change v_T by at most u.
    ``inf`` where nothing limits the step; the sensitivity solve rejects a step whose fraction is
    below 1 (``solve._sensitivity.SlipResolving``)."""
    q0, qd0, _ = mechanism.split_state(y0)
    q1, qd1, _ = mechanism.split_state(y1)
    fractions = [jnp.asarray(jnp.inf)]
    for joint in mechanism.clearance_joints:
        transition = joint.friction_law.slip_transition(joint.smoothing)
        if transition is not None:
            k0 = clearance.kinematics(joint, mechanism.index, q0, qd0)
            k1 = clearance.kinematics(joint, mechanism.index, q1, qd1)
            fractions.append(
                _slip_fraction(
                    transition, k0.slip_velocity, k1.slip_velocity, k0.penetration, k1.penetration
                )
            )
    for joint in mechanism.translational_clearance_joints:
        transition = joint.friction_law.slip_transition(joint.smoothing)
        if transition is not None:
            k0 = translational.kinematics(joint, mechanism.index, q0, qd0)
            k1 = translational.kinematics(joint, mechanism.index, q1, qd1)
            fractions.append(
                _slip_fraction(
                    transition, k0.slip_velocity, k1.slip_velocity, k0.penetration, k1.penetration
                )
            )
    return jnp.min(jnp.stack(fractions))


def initial_state(mechanism, q0, qd0) -> Float[Array, " N"]:
    """Integrator state y0 = (q0, q̇0, internal states) from assembled coordinates."""
    internal = {}
    for group in evaluation_groups(mechanism):
        internal.update(group.initial_states(mechanism, q0, qd0))
    parts = [q0, qd0, *(internal[e.name] for e in mechanism.force_elements)]
    return jnp.concatenate([jnp.reshape(jnp.asarray(p, dtype=float), (-1,)) for p in parts])


def clearance_outputs(mechanism, evaluation: Evaluation) -> dict:
    """{clearance joint name: ``ClearanceOutputs``} at the instant of ``evaluation``, and for each
    translational clearance joint its ``TranslationalClearanceOutputs``."""
    out: dict[str, JointOutputs] = {
        c.name: clearance.outputs(
            c, mechanism.index, evaluation.q, evaluation.qd, evaluation.states[c.name]
        )
        for c in mechanism.clearance_joints
    }
    for c in mechanism.translational_clearance_joints:
        out[c.name] = translational.outputs(
            c, mechanism.index, evaluation.q, evaluation.qd, evaluation.states[c.name]
        )
    return out
