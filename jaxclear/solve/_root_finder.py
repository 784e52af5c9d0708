"""Newton iteration for the implicit stages of the IMEX split, using its structure [ours].

In the IMEX split (``dynamics._equations.stiff_vector_field``) only the internal states are
implicit: the stiff part has zero rows for q and q̇, and each internal state's stiff rate depends
on the state itself only, linearly (impact memory: w(δ) k_m (δ̇ − m); LuGre: v − σ0|v| z / g(v)),
with coefficients that depend on q and q̇. The Jacobian of a stage equation
r(f) = f − f_I(y_partial + a h f) is therefore identity on the q, q̇ rows and diagonal on the
internal-state block (plus coupling to q, q̇ that vanishes once the q, q̇ rows are solved, which
the first iteration does exactly). One Jacobian-vector product with the internal-state indicator
as tangent gives that diagonal at the cost of one evaluation, instead of the dense Jacobian and
LU factorisation of ``diffrax.VeryChord``; the iteration converges in two steps for this linear
structure, or in one step when the start has its q, q̇ rows at their exact value (zero) and the
rates are affine in the internal states (``affine=True``: measured on case c of
benchmarks/bench_clearance.py, 64 → 51 µs per KenCarp5 step). ``SolverConfig`` now uses the same
closed form without the root-finding loop (``jaxclear.solve._imex.AffineKenCarp``, 38–42 µs per step);
this root finder remains for diffrax's KenCarp when no stiff function is passed to
``make_solver``. With ``affine=False`` convergence is tested as in ``VeryChord`` (a stiff part
that breaks the assumptions is then reported as a failed solve, not silently accepted).
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx


class _State(eqx.Module):
    diffsize: jax.Array
    diffsize_prev: jax.Array
    step: jax.Array


class DiagonalNewton(optx.AbstractRootFinder):
    """Newton's method with the exact diagonal of the Jacobian, for flat array unknowns.

    Attributes:
        rtol, atol: tolerances on the Newton update (as ``diffrax.VeryChord``).
        num_explicit: number of leading components whose residual is ``y − const`` (the q, q̇
            rows of an IMEX stage equation in f-space); their Jacobian diagonal is 1.
        kappa: early-convergence factor (as ``VeryChord``).
        affine: the stiff rates are affine in the implicit unknowns (the contract of
            ``stiff_state_derivative``, checked by tests/test_fast_paths.py): one Newton step from a
            start whose explicit rows are exact (zero) is then the solution, and the iteration
            stops after it (failing only on non-finite values). ``False``: iterate and test
            convergence as ``VeryChord`` does (two evaluations per stage at least).
    """

    rtol: float
    atol: float
    num_explicit: int = eqx.field(static=True)
    norm: Callable = optx.rms_norm
    kappa: float = 1e-2
    affine: bool = eqx.field(static=True, default=False)

    def init(self, fn, y, args, options, f_struct, aux_struct, tags) -> _State:
        del fn, y, args, options, f_struct, aux_struct, tags
        return _State(diffsize=jnp.array(jnp.inf), diffsize_prev=jnp.array(1.0), step=jnp.array(0))

    def step(self, fn, y, args, options, state: _State, tags) -> tuple[Any, _State, Any]:
        del options, tags
        implicit = jnp.arange(y.shape[0]) >= self.num_explicit
        y = jnp.where(implicit, y, 0.0)  # the exact solution of the explicit rows
        (fx, aux), (diag, _) = jax.jvp(lambda z: fn(z, args), (y,), (implicit.astype(y.dtype),))
        diag = jnp.where(implicit, diag, 1.0)
        diff = fx / diag
        new_y = y - diff
        diffsize = self.norm(diff / (self.atol + self.rtol * jnp.abs(new_y)))
        return (
            new_y,
            _State(diffsize=diffsize, diffsize_prev=state.diffsize, step=state.step + 1),
            aux,
        )

    def terminate(self, fn, y, args, options, state: _State, tags):
        del fn, y, args, options, tags
        if self.affine:
            done = state.step >= 1
            return done, optx.RESULTS.where(
                done & ~jnp.isfinite(state.diffsize),
                optx.RESULTS.nonlinear_divergence,
                optx.RESULTS.successful,
            )
        at_least_two = state.step >= 2
        rate = state.diffsize / state.diffsize_prev
        factor = state.diffsize * rate / (1 - rate)
        small = state.diffsize < 10 ** (2 - jnp.finfo(state.diffsize.dtype).precision)
        diverged = ~jnp.isfinite(rate) | (rate > 2)
        converged = (factor > 0) & (factor < self.kappa)
        terminate = at_least_two & (small | diverged | converged)
        result = optx.RESULTS.where(
            at_least_two & ~small & (diverged | ~converged),
            optx.RESULTS.nonlinear_divergence,
            optx.RESULTS.successful,
        )
        return terminate, result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return y, aux, {}
