"""KenCarp3/4/5 for an affine diagonal stiff part, with closed-form stage solves: custom diffrax solvers.

The IMEX split of jaxclear (``dynamics._equations``) has a stiff part that is zero on the q, q̇ rows
and, on the internal-state rows (impact memory, LuGre z), affine and diagonal in those states with
coefficients that depend on q and q̇ only: f_I(y) = a(q, q̇) + ℓ(q, q̇) ∘ s. That is the contract
``tests/test_fast_paths.py`` checks for every friction law. Each implicit stage equation of an
ESDIRK/IMEX method,

    Y_i = P_i + h γ f_I(Y_i),    P_i = y0 + h Σ_{j<i} (a^E_ij f^E_j + a^I_ij f^I_j),

then has its q, q̇ rows equal to those of P_i and its internal rows in closed form,

    s_i = (P_i,s + h γ a) / (1 − h γ ℓ),   with a, ℓ from one evaluation of f_I at P_i (primal and
                                          one Jacobian–vector product along the internal rows).

This is what ``DiagonalNewton(affine=True)`` computes inside diffrax's ``KenCarp5`` through
optimistix's root-finding loop. Done directly, a stage is one call of a ``stage`` function that
solves for s_i and evaluates f and f_I at Y_i in one pass over the model
(``dynamics._equations.implicit_stage``: the joints' kinematics serve the stiff coefficients and
the forces; f^E = f − f^I), and the stages run in one ``fori_loop`` so the model is compiled
once. Same tableaus (Kennedy & Carpenter 2003: ARK3(2)4L[2]SA, ARK4(3)6L[2]SA, ARK5(4)8L[2]SA, taken from diffrax's ``KenCarp3/4/5``), same error estimates and dense output: a
step agrees with diffrax's KenCarp + ``DiagonalNewton(affine=True)`` to rounding
(tests/test_imex_affine.py).

Reference: C. A. Kennedy, M. H. Carpenter, "Additive Runge–Kutta schemes for convection–diffusion–
reaction equations", Appl. Numer. Math. 44 (2003) 139–181.
"""

from collections.abc import Callable
from typing import ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


class _Tableau:
    """Explicit and implicit coefficients of one diffrax KenCarp method as full NumPy matrices."""

    def __init__(self, method):
        explicit, implicit = method.tableau.tableaus
        self.stages = len(explicit.a_lower) + 1
        self.gamma = float(implicit.a_diagonal[1])
        self.c = np.concatenate([[0.0], np.asarray(explicit.c)])
        self.a_explicit, self.a_implicit = (self._full(t) for t in (explicit, implicit))
        self.b, self.b_error = np.asarray(explicit.b_sol), np.asarray(explicit.b_error)
        # one set of weights for both parts (checked), so y1 = y0 + Σ b_j (k^E_j + k^I_j)
        assert np.allclose(self.b, implicit.b_sol) and np.allclose(self.b_error, implicit.b_error)
        assert implicit.a_diagonal[0] == 0 and np.all(implicit.a_diagonal[1:] == self.gamma)
        self.order = method().order(None)
        self.interpolation = method.interpolation_cls
        # the dense output is y0 + Σ_j θ p_j(θ) k_j (diffrax's KenCarpInterpolation, p_j the rows
        # of ``coeffs``); its derivative at the step's midpoint is Σ_j D_j k_j / h with
        # D_j = p_j(½) + ½ p_j'(½) (``ExtremesTracking``)
        coeffs = np.asarray(method.interpolation_cls.coeffs)
        self.midpoint_derivative = np.array(
            [np.polyval(row, 0.5) + 0.5 * np.polyval(np.polyder(row), 0.5) for row in coeffs]
        )

    def _full(self, tableau):
        a = np.zeros((self.stages, self.stages))
        for i, row in enumerate(tableau.a_lower, start=1):
            a[i, : len(row)] = row
        return a


TABLEAUS = {
    3: _Tableau(diffrax.KenCarp3),
    4: _Tableau(diffrax.KenCarp4),
    5: _Tableau(diffrax.KenCarp5),
}


class _AffineKenCarpInterpolation(diffrax.AbstractLocalInterpolation):
    """diffrax's KenCarp dense output for the method's ``variant`` (3, 4 or 5)."""

    t0: jax.Array
    t1: jax.Array
    inner: diffrax.AbstractLocalInterpolation

    def __init__(self, *, t0, t1, y0, y1, k, variant):
        # pyright reads diffrax's `AbstractVar` t0/t1 as class variables (pyright#4965)
        self.t0, self.t1 = t0, t1  # pyright: ignore[reportIncompatibleVariableOverride]
        self.inner = TABLEAUS[variant].interpolation(t0=t0, t1=t1, y0=y0, y1=y1, k=k)

    def evaluate(self, t0, t1=None, left=True):
        return self.inner.evaluate(t0, t1, left)


class AffineKenCarp(diffrax.AbstractAdaptiveSolver):
    """KenCarp3/4/5 with closed-form stage solves for an affine diagonal stiff part.

    Attributes:
        stage: ``stage(t, P, γh, args) -> (Y, f(Y), f_I(Y))``: Y has the first ``num_explicit``
            rows of P and solves Y = P + γh f_I(Y) on the others, where the stiff part f_I is zero
            on the first rows and affine and diagonal in the others (not checked here; see the
            module docstring); f is the full vector field (``dynamics._equations.implicit_stage``).
        num_explicit: number of leading rows (q, q̇) that the stiff part leaves alone.
        variant: 3, 4 or 5 (KenCarp3, KenCarp4, KenCarp5).

    ``terms`` is the full vector field f = f^E + f^I (an ``ODETerm``, used for ``func``); the state
    a 1-D array.
    """

    stage: Callable = eqx.field(static=True)
    num_explicit: int = eqx.field(static=True)
    variant: int = eqx.field(static=True, default=5)
    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar = _AffineKenCarpInterpolation

    def order(self, terms):
        return TABLEAUS[self.variant].order

    def init(self, terms, t0, t1, y0, args):
        return None

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del solver_state, made_jump
        tab = TABLEAUS[self.variant]
        h = t1 - t0
        dtype = y0.dtype
        a_e, a_i, c = (jnp.asarray(x, dtype) for x in (tab.a_explicit, tab.a_implicit, tab.c))
        n = y0.shape[0]

        def stage(i, carry):
            ks_e, ks_i = carry
            partial = y0 + jnp.sum(a_e[i][:, None] * ks_e + a_i[i][:, None] * ks_i, axis=0)
            gamma_h = jnp.where(i == 0, 0.0, tab.gamma) * h  # stage 1 is explicit (a^I_11 = 0)
            _, f, f_implicit = self.stage(t0 + c[i] * h, partial, gamma_h, args)
            f_explicit = f - f_implicit
            return ks_e.at[i].set(h * f_explicit), ks_i.at[i].set(h * f_implicit)

        zeros = jnp.zeros((tab.stages, n), dtype)
        ks_e, ks_i = jax.lax.fori_loop(0, tab.stages, stage, (zeros, zeros))
        b, b_error = jnp.asarray(tab.b, dtype), jnp.asarray(tab.b_error, dtype)
        k = ks_e + ks_i
        y1 = y0 + jnp.sum(b[:, None] * k, axis=0)
        y_error = jnp.sum(b_error[:, None] * k, axis=0)
        dense_info = dict(y0=y0, y1=y1, k=(ks_e, ks_i), variant=self.variant)
        return y1, y_error, dense_info, None, diffrax.RESULTS.successful

    def observed_step(self, observed, t0, t1, y0, args):
        """``step`` with the observations riding along the stages
        (``jaxclear.solve._extremes.ExtremesTracking``): ``observed(t, P, γh, args) ->
        ((Y, f(Y), f_I(Y)), v)`` is ``stage`` with the flat observation v at Y from the same
        evaluation. Returns (y1, y_error, dense_info, v at each stage (stages, m)); y's
        arithmetic is that of ``step``, in the same loop (the first stage, explicit and at
        (t0, y0), is evaluated in the loop as there: made apart, e.g. at the end of the step
        before to be carried over, it rounded the impact memory's rate differently, and y left
        the plain solve's after ~4–7 ms on the one-joint slider–crank)."""
        tab = TABLEAUS[self.variant]
        h = t1 - t0
        dtype = y0.dtype
        a_e, a_i, c = (jnp.asarray(x, dtype) for x in (tab.a_explicit, tab.a_implicit, tab.c))
        n = y0.shape[0]
        size = jax.eval_shape(lambda: observed(t0, y0, h, args)[1]).shape

        def stage(i, carry):
            ks_e, ks_i, vs = carry
            partial = y0 + jnp.sum(a_e[i][:, None] * ks_e + a_i[i][:, None] * ks_i, axis=0)
            gamma_h = jnp.where(i == 0, 0.0, tab.gamma) * h  # stage 1 is explicit (a^I_11 = 0)
            (_, f, f_implicit), v = observed(t0 + c[i] * h, partial, gamma_h, args)
            f_explicit = f - f_implicit
            return ks_e.at[i].set(h * f_explicit), ks_i.at[i].set(h * f_implicit), vs.at[i].set(v)

        zeros = jnp.zeros((tab.stages, n), dtype)
        vs = jnp.zeros((tab.stages,) + size, dtype)
        ks_e, ks_i, vs = jax.lax.fori_loop(0, tab.stages, stage, (zeros, zeros, vs))
        b, b_error = jnp.asarray(tab.b, dtype), jnp.asarray(tab.b_error, dtype)
        k = ks_e + ks_i
        y1 = y0 + jnp.sum(b[:, None] * k, axis=0)
        y_error = jnp.sum(b_error[:, None] * k, axis=0)
        dense_info = dict(y0=y0, y1=y1, k=(ks_e, ks_i), variant=self.variant)
        return y1, y_error, dense_info, vs
