"""``AffineKenCarp`` (jaxclear/solve/_imex.py): closed-form IMEX stage solves give diffrax's KenCarp steps.

A step of diffrax's KenCarp3/4/5 with ``DiagonalNewton(affine=True)`` on the split (non-stiff,
stiff) and a step of ``AffineKenCarp`` on the full vector field must agree to rounding, at the end
of the step and in the dense output, on the three-joint slider–crank with LuGre friction (impact
memory and bristle state both stiff).
"""

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.dynamics._equations import nonstiff_vector_field, stiff_vector_field
from jaxclear.friction import LuGre
from jaxclear.mechanisms import slider_crank
from jaxclear.solve._imex import AffineKenCarp
from jaxclear.solve._root_finder import DiagonalNewton
from jaxclear.solve._simulate import _FULL, _STAGE

# diffrax's KenCarp on the split (non-stiff, stiff): the reference for AffineKenCarp
_STIFF = eqx.filter_jit(stiff_vector_field)
_NONSTIFF = eqx.filter_jit(nonstiff_vector_field)

ROUNDING = 1e-12  # absolute, on states of order 1 (m, rad, m/s up to ~30)


@pytest.fixture(scope="module")
def lugre_state():
    mech = slider_crank(
        clearance_joints="O,A,B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=LuGre(),
    )
    y0 = jaxclear.assemble(mech)
    rng = np.random.default_rng(3)
    n2 = 2 * mech.num_coordinates
    y = np.asarray(y0).copy()
    y[:n2] += 1e-4 * rng.standard_normal(n2)  # journals off centre, nonzero slip
    y[n2:] += 1e-7 * rng.standard_normal(y.size - n2)  # internal states off their start values
    return mech, jnp.asarray(y)


def one_step(term, solver, y, mech, h):
    """The state at h/3 (dense output) and at h after one step of ``solver`` from (0, y): the
    solver's own ``init``, ``step`` and interpolation, which is what ``diffeqsolve`` runs for a
    step, compiled without its loop, controller and saving (measured 28 -> 19 s of CPU for the
    module)."""
    # h as an array: filter_jit keeps Python floats static, so a float step would compile each
    # solver once per step size
    return np.asarray(_one_step(term, solver, y, mech, jnp.asarray(h)))


@eqx.filter_jit
def _one_step(term, solver, y, mech, h):
    t0 = jnp.zeros_like(h)
    state = solver.init(term, t0, h, y, mech)
    y1, _, dense_info, _, result = solver.step(term, t0, h, y, mech, state, made_jump=False)
    dense = solver.interpolation_cls(t0=t0, t1=h, **dense_info)
    y1 = eqx.error_if(y1, result != diffrax.RESULTS.successful, "the step failed")
    return jnp.stack([dense.evaluate(h / 3), y1])


@pytest.mark.parametrize("variant", [3, 4, 5])
def test_affine_kencarp_step_equals_diffrax_kencarp_with_diagonal_newton(lugre_state, variant):
    mech, y = lugre_state
    n2 = 2 * mech.num_coordinates
    method = {3: diffrax.KenCarp3, 4: diffrax.KenCarp4, 5: diffrax.KenCarp5}[variant]
    reference = method(root_finder=DiagonalNewton(1e-3, 1e-6, n2, affine=True))
    split = diffrax.MultiTerm(diffrax.ODETerm(_NONSTIFF), diffrax.ODETerm(_STIFF))
    for h in (1e-7, 3e-6):  # the second makes h·rate ≫ 1 for the memory (k_m = 1e6 1/s)
        ours = one_step(diffrax.ODETerm(_FULL), AffineKenCarp(_STAGE, n2, variant), y, mech, h)
        ref = one_step(split, reference, y, mech, h)
        assert np.all(np.isfinite(ours))
        assert np.max(np.abs(ours[1] - y)) > 1e3 * ROUNDING  # the step moved the state
        np.testing.assert_allclose(ours, ref, rtol=0, atol=ROUNDING)


def test_imex_preset_uses_the_closed_form_solver():
    mech = slider_crank(clearance_joints="B", friction_law=LuGre())
    config = jaxclear.recommended_solver(mech)
    solver = config.make_solver(num_explicit=2 * mech.num_coordinates, stage=_STAGE)
    assert isinstance(solver, AffineKenCarp) and solver.variant == 4
    assert isinstance(config.make_solver(num_explicit=2 * mech.num_coordinates), diffrax.KenCarp4)


class _Lag(jaxclear.AbstractForceElement):
    """A force element with a stiff internal state: a horizontal force on the slider that lags
    k_f x_slider with time constant 1/rate, ṡ = rate (k_f x − s) (stiff part: all of it)."""

    name: str = eqx.field(static=True, default="lag")
    rate: float = 2e6
    gain: float = 1e3

    @property
    def bodies(self):
        return ("slider",)

    @property
    def num_states(self):
        return 1

    def generalized_force(self, index, q, qd, t, state):
        return jnp.zeros_like(q).at[3 * index("slider")].set(-state[0])

    def state_derivative(self, index, q, qd, qdd, t, state):
        return self.stiff_state_derivative(index, q, qd, t, state)

    def stiff_state_derivative(self, index, q, qd, t, state):
        return self.rate * (self.gain * q[3 * index("slider")] - state)


def test_stage_solves_force_element_states_too(lugre_state):
    """A force element's stiff state beside the clearance joints' (``implicit_stage`` solves
    those apart from the joints'): the same step as diffrax's KenCarp5 on the split."""
    mech, y = lugre_state
    mech = eqx.tree_at(lambda m: m.forces, mech, (_Lag(),))
    n2 = 2 * mech.num_coordinates
    y = jnp.concatenate([y[:n2], jnp.asarray([25.0]), y[n2:]])  # the lag's state comes first
    assert mech.state_size == y.size
    reference = diffrax.KenCarp5(root_finder=DiagonalNewton(1e-3, 1e-6, n2, affine=True))
    split = diffrax.MultiTerm(diffrax.ODETerm(_NONSTIFF), diffrax.ODETerm(_STIFF))
    for h in (1e-7, 3e-6):
        ours = one_step(diffrax.ODETerm(_FULL), AffineKenCarp(_STAGE, n2, 5), y, mech, h)
        ref = one_step(split, reference, y, mech, h)
        assert abs(ours[1, n2] - 25.0) > 1e-3  # the lag's state moved
        np.testing.assert_allclose(ours, ref, rtol=0, atol=ROUNDING * 1e3)
