"""Tsit5 in Lawson (integrating-factor) form for a stiff diagonal decay: a custom diffrax solver.

The impact-memory offset u = m − δ̇ of each clearance joint obeys u̇ = −w(δ) k_m u + (w − 1) dδ̇/dt
(``dynamics._impact_memory``): in free flight (w = 1) a pure decay at k_m ≈ 1e6 1/s with no forcing.
An explicit Runge–Kutta method is stable there only for steps h < ~3.5/k_m (~3.5 µs), which is what
limits Tsit5's step count on the one-joint slider–crank (benchmarks/memory_rate_study.py). Writing

    y' = L y + N(t, y),   L = diag(ℓ) frozen at the step start (ℓ = −w k_m on memory rows, else 0),

Lawson's method applies an explicit tableau (a, b, c) to v(t) = exp(−(t − t0) L) y:

    Y_i = e^{c_i hL} y0 + h Σ_j a_ij e^{(c_i − c_j) hL} N_j,      N_j = f(Y_j) − L Y_j,
    y1  = e^{hL} y0     + h Σ_j b_j  e^{(1 − c_j) hL} N_j,

with the error estimate and the dense output built the same way from b_error and Tsit5's
continuous extension b_j(θ). On rows where ℓ = 0 it is Tsit5 exactly (same tableau, from
diffrax/_solver/tsit5.py); on memory rows in free flight N = 0 and the decay is taken exactly at
any step size. Where w changes inside a step (at contact onset and separation), the frozen ℓ
leaves a remainder (ℓ(t) − ℓ0) u in N, which the error estimate sees: steps shrink there, as
they must anyway to resolve the contact. (Lawson methods lose accuracy on stiff rows with a large
forcing, e.g. LuGre's z at its quasi-steady value; those are left out of L, see ``memory_rows``.)

Reference: J. D. Lawson, "Generalized Runge–Kutta processes for stable systems with large
Lipschitz constants", SIAM J. Numer. Anal. 4 (1967) 372–380; Ch. Tsitouras, Comput. Math. Appl.
62 (2011) 770–775 (the tableau and its interpolant).
"""

from collections.abc import Callable
from typing import Any, ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

_TABLEAU = diffrax.Tsit5.tableau
_A = tuple(np.asarray(row) for row in _TABLEAU.a_lower)  # stages 2..7; stage 7 row = b (FSAL)
_C = np.concatenate([[0.0], np.asarray(_TABLEAU.c)])  # nodes of stages 1..7
_B_ERROR = np.asarray(_TABLEAU.b_error)
_STAGES = 7
_A_FULL = np.zeros((_STAGES, _STAGES))
for _i, _row in enumerate(_A, start=1):
    _A_FULL[_i, : len(_row)] = _row
MAX_DENSE_EXPONENT = 50.0
"""Cap on (c_j − θ) h|ℓ| in the dense output, where the integrating factor grows: it only keeps
exp finite (0 · inf would give NaN on rows where N = 0); steps with h|ℓ| near the cap carry N ≈ 0."""


def _tsit5_dense_weights(theta):
    """Tsit5's continuous extension b_j(θ), j = 1..7 (diffrax/_solver/tsit5.py, Tsitouras 2011)."""
    t = theta
    return jnp.stack(
        [
            -1.0530884977290216
            * t
            * (t - 1.3299890189751412)
            * (t**2 - 1.4364028541716351 * t + 0.7139816917074209),
            0.1017 * t**2 * (t**2 - 2.1966568338249754 * t + 1.2949852507374631),
            2.490627285651252793 * t**2 * (t**2 - 2.38535645472061657 * t + 1.57803468208092486),
            -16.54810288924490272 * (t - 1.21712927295533244) * (t - 0.61620406037800089) * t**2,
            47.37952196281928122 * (t - 1.203071208372362603) * (t - 0.658047292653547382) * t**2,
            -34.87065786149660974 * (t - 1.2) * (t - 0.666666666666666667) * t**2,
            2.5 * (t - 1) * (t - 0.6) * t**2,
        ]
    )


def _set_rows(full, rows, values):
    """``full`` with ``full[rows] = values`` (rows: static tuple of indices)."""
    if not rows:
        return full
    start = rows[0]
    if rows == tuple(range(start, start + len(rows))):
        return jax.lax.dynamic_update_slice(full, values, (start,))
    return full.at[np.asarray(rows)].set(values)


def _get_rows(full, rows):
    start = rows[0]
    if rows == tuple(range(start, start + len(rows))):
        return full[start : start + len(rows)]
    return full[np.asarray(rows)]


class LawsonInterpolation(diffrax.AbstractLocalInterpolation):
    """Dense output of ``LawsonTsit5``: Tsit5's interpolant y0 + Σ_j b_j(θ) h f_j on the plain
    rows, and e^{θhℓ} y0 + Σ_j b_j(θ) e^{(θ − c_j)hℓ} h N_j on the decay rows."""

    t0: jax.Array
    t1: jax.Array
    y0: jax.Array
    k: jax.Array  # (7, N): h f_j
    hl: jax.Array  # (R,): h ℓ on the decay rows
    k_rows: jax.Array  # (7, R): h N_j on the decay rows
    rows: tuple = eqx.field(static=True)

    def __init__(self, *, t0, t1, y0, y1, k, hl, k_rows, rows):
        del y1  # diffrax passes it; the interpolant does not need it
        # pyright reads diffrax's `AbstractVar` t0/t1 as class variables (pyright#4965)
        self.t0, self.t1 = t0, t1  # pyright: ignore[reportIncompatibleVariableOverride]
        self.y0, self.k, self.hl, self.k_rows, self.rows = y0, k, hl, k_rows, rows

    def evaluate(self, t0, t1=None, left=True):
        del left
        if t1 is not None:
            return self.evaluate(t1) - self.evaluate(t0)
        theta = _rescale(self.t0, t0, self.t1)
        weights = _tsit5_dense_weights(theta)
        plain = self.y0 + jnp.sum(weights[:, None] * self.k, axis=0)
        if not self.rows:
            return plain
        exponents = jnp.minimum(
            (theta - jnp.asarray(_C))[:, None] * self.hl[None, :], MAX_DENSE_EXPONENT
        )
        decayed = jnp.exp(theta * self.hl) * _get_rows(self.y0, self.rows) + jnp.sum(
            weights[:, None] * jnp.exp(exponents) * self.k_rows, axis=0
        )
        return _set_rows(plain, self.rows, decayed)


def _rescale(t0, t, t1):
    """(t − t0) / (t1 − t0), 0 on a zero-length step, with a NaN-free derivative there (double
    ``where``, as diffrax's ``linear_rescale``): vmapped solves make zero-length steps for members
    that have finished, and a NaN in the discarded branch would reach the gradient."""
    empty = t1 == t0
    span = jnp.where(empty, 1.0, t1 - t0)
    return jnp.where(empty, 0.0, (t - t0) / span)


class LawsonTsit5(diffrax.AbstractAdaptiveSolver):
    """Tsitouras 5(4) in Lawson form for ``y' = diag(ℓ(t, y)) y + N`` with ℓ frozen per step.

    Attributes:
        decay: ``decay(t, y, args) -> ℓ`` on the decay rows only (shape ``(len(rows),)``, ≤ 0),
            the exact diagonal of the linear part there: the rest is treated explicitly.
        rows: static indices of the decay rows in y; every other row is integrated by plain Tsit5.

    The state is a single 1-D array y, or a pair (y, w) (``ExtremesTracking``, the observations
    riding along the stages): then ``terms.vf(t, (y, w), args)`` returns (dy/dt, dw/dt), dw/dt
    does not depend on w, and w is integrated by plain Tsit5 (its decay rate is 0); y's
    arithmetic is the same as without w (``decay`` sees y alone). FSAL: one vector-field
    evaluation per stage 2..7 and one ``decay`` evaluation per step. The exponentials are taken
    on the decay rows only: most rows have ℓ = 0, and exponentials over the whole state made the
    step markedly slower.
    """

    decay: Callable = eqx.field(static=True)
    rows: tuple = eqx.field(static=True)
    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar = LawsonInterpolation

    def order(self, terms):
        return 5

    def init(self, terms, t0, t1, y0, args):
        return terms.vf(t0, y0, args)

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        f0 = solver_state
        if made_jump is not False:
            f0 = jax.lax.cond(made_jump, lambda: terms.vf(t0, y0, args), lambda: f0)
        riding = isinstance(y0, tuple)  # (y, w): see the class
        w0: Any = None
        g0: Any = None
        if riding:
            (y0, w0), (f0, g0) = y0, f0
        h = t1 - t0
        rows = self.rows
        dtype = y0.dtype
        a_full, c, b_error = (jnp.asarray(x, dtype) for x in (_A_FULL, _C, _B_ERROR))
        hl = h * self.decay(t0, y0, args) if rows else jnp.zeros((0,), dtype)
        y0_rows = _get_rows(y0, rows) if rows else jnp.zeros((0,), dtype)
        # ks[j] = h f_j on every row (Tsit5 on the plain rows); k_rows[j] = h N_j on the decay rows
        ks = jnp.zeros((_STAGES,) + y0.shape, dtype).at[0].set(h * f0)
        k_rows = (
            jnp.zeros((_STAGES, len(rows)), dtype)
            .at[0]
            .set(h * _get_rows(f0, rows) - hl * y0_rows if rows else 0.0)
        )

        def stage(i, carry):
            # One stage per iteration: the vector field is compiled once, not seven times (XLA
            # compile time 5.2 -> ~2 s on the one-joint slider-crank).
            (ks, k_rows, _, _), riders = carry[:4], carry[4:]
            a, ci = a_full[i], c[i]
            y_stage = y0 + jnp.sum(a[:, None] * ks, axis=0)
            decayed = y0_rows
            if rows:
                # exp((c_i - c_j) h l) for j < i; later stages have a_ij = 0 (exponent capped at 0)
                factors = jnp.exp(jnp.minimum((ci - c)[:, None] * hl[None, :], 0.0))
                decayed = jnp.exp(ci * hl) * y0_rows + jnp.sum(
                    a[:, None] * factors * k_rows, axis=0
                )
                y_stage = _set_rows(y_stage, rows, decayed)
            if riding:
                ks_w, _ = riders
                # dw/dt does not depend on w: its stages need not be formed
                f, g = terms.vf(t0 + ci * h, (y_stage, w0), args)
                riders = (ks_w.at[i].set(h * g), g)
            else:
                f = terms.vf(t0 + ci * h, y_stage, args)
            ks = ks.at[i].set(h * f)
            if rows:
                k_rows = k_rows.at[i].set(h * _get_rows(f, rows) - hl * decayed)
            return (ks, k_rows, y_stage, f) + riders

        carry = (ks, k_rows, y0, f0)
        if riding:
            carry += (jnp.zeros((_STAGES,) + w0.shape, w0.dtype).at[0].set(h * g0), g0)
        ks, k_rows, y1, f_last, *riders = jax.lax.fori_loop(1, _STAGES, stage, carry)
        # y1 is stage 7, at c = 1 with weights b (first same as last)
        y_error = jnp.sum(b_error[:, None] * ks, axis=0)
        if rows:
            factors = jnp.exp((1.0 - c)[:, None] * hl[None, :])
            y_error = _set_rows(y_error, rows, jnp.sum(b_error[:, None] * factors * k_rows, axis=0))
        dense_info = dict(y0=y0, y1=y1, k=ks, hl=hl, k_rows=k_rows, rows=rows)
        if riding:
            ks_w, g_last = riders
            w1 = w0 + jnp.sum(a_full[-1][:, None] * ks_w, axis=0)  # stage 7's weights are b
            w_error = jnp.sum(b_error[:, None] * ks_w, axis=0)
            dense_info.update(y0=(y0, w0), y1=(y1, w1), k=(ks, ks_w))
            return (
                (y1, w1),
                (y_error, w_error),
                dense_info,
                (f_last, g_last),
                diffrax.RESULTS.successful,
            )
        return y1, y_error, dense_info, f_last, diffrax.RESULTS.successful
