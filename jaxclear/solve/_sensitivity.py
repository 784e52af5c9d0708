"""Forward sensitivities with error control: the derivative of the solution, not of the steps.

diffrax differentiates the steps it took: its step-size controller sees the state's error only,
so near a contact onset, where the tangent has a time scale of its own, nothing bounds the
tangent's truncation error and a derivative at rtol 1e-6 can be off by any factor
(docs/differentiation.md, "Why"). Here the state y (N,) and its tangents S (p, N) along p
directions of the parameters are integrated as one system (the simultaneous corrector method
of forward sensitivity analysis, SUNDIALS CVODES ``CV_SIMULTANEOUS``),

    ẏ = f(t, y, θ),    Ṡ_k = ∂f/∂y S_k + ∂f/∂θ V_k,    S_k(t0) = dy0/dθ V_k,

with the Jacobian products taken inside the vector field (``jax.linearize``, then one
vectorised product per direction), by the same solver and tableau as the state, and the
step-size controller's norm covering the tangents as CVODES does with ``errconS``: the error
is max(‖e_y‖, max_k ‖e_S_k‖) in the weighted RMS norm, each tangent weighted with
rtol·|S_k| + atol·ρ_k, where ρ_k = max_i |V_k,i| / |θ_i| is the direction's size relative to the
parameters' nominal magnitudes (CVODES's atolS = atol / p̄ for unit directions; |θ_i| = 1 where
θ_i = 0). Every solver of ``SolverConfig`` runs it:

- explicit Runge–Kutta methods on the augmented vector field as they are;
- Lawson–Tsit5 with the same decay rate on each tangent's memory rows (the linear part of the
  tangent equation there is the state's: ℓ s);
- the IMEX methods (``AffineKenCarp``) with the linearisation of the closed-form stage solve,
  which solves the linearised stage equation exactly (the stiff part of the tangent equation is
  the linearisation of the stiff part);
- the implicit Kvaerno methods with their Newton (chord) iteration on the augmented system.

The extremes (peaks, RMS: ``ExtremesTracking``) carry their tangents too: each step's update is
linearised, so a peak's derivative is that of the sample that holds the peak.

``simulate`` uses this path for ``jax.jvp``/``jax.jacfwd`` (``differentiable_simulate``, a
``jax.custom_jvp``: one direction per jvp) and for ``jax.grad``/``jax.vjp``/``jax.jacrev`` (a
``jax.custom_vjp`` whose forward pass integrates one tangent per perturbed scalar, p at once, and
whose backward pass contracts them with the cotangent: cost ∝ 1 + c·p, not a continuous adjoint).

References: A. C. Hindmarsh et al., "SUNDIALS", ACM TOMS 31 (2005) 363–396, and the CVODES user
guide, "Forward sensitivity analysis" (error control ``errconS``, tolerances ``atolS``); M.
Caracotsios, W. E. Stewart, Comput. Chem. Eng. 9 (1985) 359–365 (the staggered/simultaneous
corrector); H. G. Bock, internal numerical differentiation (1981).
"""

import dataclasses

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core._executable_cache import stored_jit
from ..dynamics._assembly import assemble_state
from ..dynamics._equations import (
    implicit_stage,
    memory_decay_rates,
    memory_offset_shift,
    vector_field,
)
from ..dynamics._equations import initial_state as dynamics_initial_state
from ._extremes import AbstractWrappingSolver, Tracker
from ._observables import ASSEMBLY_TOLERANCE, input_error, make_trajectory, observe
from ._solver import SolverConfig


def _partition(tree):
    return eqx.partition(tree, eqx.is_inexact_array)


def _tangents(fn, mechanism, y, S, V):
    """``fn(y, mechanism)`` and its tangents (p, ...) along (S_k, V_k): one linearisation, then one
    vectorised product for the p directions."""
    dynamic, static = _partition(mechanism)
    out, linear = jax.linearize(lambda y, d: fn(y, eqx.combine(d, static)), y, dynamic)
    return out, jax.vmap(linear)(S, V)


def _split(Y, size):
    return Y[:size], jnp.reshape(Y[size:], (-1, size))


def _join(y, S):
    return jnp.concatenate([y, jnp.reshape(S, (-1,))])


class Augmented(eqx.Module):
    """``args`` of the augmented solve: the mechanism and the p parameter directions V (a pytree
    like the mechanism's inexact leaves, each with a leading axis p)."""

    mechanism: eqx.Module
    directions: object


def augmented_field(t, Y, args: Augmented):
    """(f, ∂f/∂y S_k + ∂f/∂θ V_k) for the flat augmented state [y, S_1, ..., S_p]."""
    size = args.mechanism.state_size
    y, S = _split(Y, size)
    f, dS = _tangents(lambda y, m: vector_field(t, y, m), args.mechanism, y, S, args.directions)
    return _join(f, dS)


def _augmented_decay(p):
    def decay(t, Y, args: Augmented):
        y = Y[: args.mechanism.state_size]
        return jnp.tile(memory_decay_rates(t, y, args.mechanism), p + 1)

    return decay


def augmented_stage(t, P, gamma_h, args: Augmented):
    """The IMEX stage of the augmented system: the closed-form stage solve of the state and its
    linearisation along each direction (the exact solution of the linearised stage equation)."""
    size = args.mechanism.state_size
    y, S = _split(P, size)
    (Y, f, stiff), (dY, df, dstiff) = _tangents(
        lambda y, m: implicit_stage(t, y, gamma_h, m), args.mechanism, y, S, args.directions
    )
    return _join(Y, dY), _join(f, df), _join(stiff, dstiff)


_FIELD = eqx.filter_jit(augmented_field)
_STAGE = eqx.filter_jit(augmented_stage)


def tangent_norm(size: int, p: int, with_tangents: bool = True):
    """The controller's norm of a scaled augmented error: max of the state's RMS and each
    tangent's (``with_tangents=False``: the state's alone, diffrax's behaviour, for checks)."""

    def norm(x):
        if isinstance(x, tuple | list):  # diffrax also takes norms of (y, f) pairs at the start
            return jnp.max(jnp.stack([norm(part) for part in x]))
        rows = jnp.reshape(x, (p + 1, size))
        rms = jnp.sqrt(jnp.mean(rows**2, axis=1))
        return jnp.max(rms) if with_tangents else rms[0]

    return norm


class TangentTracking(AbstractWrappingSolver):
    """``ExtremesTracking`` for the augmented solve: the tracker of the state and its tangents
    (the linearised update of each step, per direction)."""

    solver: diffrax.AbstractSolver
    start: jax.Array
    size: int = eqx.field(static=True)
    max_events: int = eqx.field(static=True, default=0)

    def _observe(self, t, Y, args):
        y, S = _split(Y, self.size)
        return _tangents(lambda y, m: observe(t, y, m), args.mechanism, y, S, args.directions)

    def init(self, terms, t0, t1, y0, args):
        obs, dobs = self._observe(t0, y0, args)
        floats, linear, rest = jax.linearize(
            lambda o: _partition(Tracker.first(self.start, t0, o, self.max_events)),
            obs,
            has_aux=True,
        )
        tracker = eqx.combine(floats, rest)
        return self.solver.init(terms, t0, t1, y0, args), (tracker, jax.vmap(linear)(dobs))

    @staticmethod
    def _update(tracker, dtracker, t, obs, dobs):
        """The tracker after a sample, and its tangents (the linearised update)."""
        floats, rest = _partition(tracker)
        new_floats, linear, new_rest = jax.linearize(
            lambda f, o: _partition(eqx.combine(f, rest).update(t, o)), floats, obs, has_aux=True
        )
        return eqx.combine(new_floats, new_rest), jax.vmap(linear)(dtracker, dobs)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        inner, (tracker, dtracker) = solver_state
        y1, y_error, dense_info, inner, result = self.solver.step(
            terms, t0, t1, y0, args, inner, made_jump
        )
        t_mid = 0.5 * (t0 + t1)
        y_mid = self.solver.interpolation_cls(t0=t0, t1=t1, **dense_info).evaluate(t_mid)
        for t, Y in ((t_mid, y_mid), (t1, y1)):
            obs, dobs = self._observe(t, Y, args)
            tracker, dtracker = self._update(tracker, dtracker, t, obs, dobs)
        return y1, y_error, dense_info, (inner, (tracker, dtracker)), result


def _direction_scales(dynamic, y0, V, dy0):
    """ρ_k = max_i |V_k,i| / |θ_i| over the parameters and the initial state (|θ_i| = 1 where
    θ_i = 0), 1 for a zero direction: the tangents' absolute tolerance is atol·ρ_k."""

    def ratio(theta, v):
        nominal = jnp.where(theta == 0, 1.0, jnp.abs(theta))
        return jnp.max(jnp.reshape(jnp.abs(v) / nominal[None], (v.shape[0], -1)), axis=1)

    parts = [
        ratio(t, v)
        for t, v in zip(jax.tree_util.tree_leaves(dynamic), jax.tree_util.tree_leaves(V))
    ]
    if y0 is not None and dy0 is not None:
        parts.append(ratio(y0, dy0))
    rho = jnp.max(jnp.stack(parts), axis=0) if parts else jnp.ones((1,))
    return jnp.where(rho > 0, rho, 1.0)


def _relabel(directions, mechanism):
    """``directions`` (made for ``mechanism``'s inexact leaves) on another mechanism with the same
    leaves but other static fields (``with_memory_offset``)."""
    dynamic, _ = _partition(mechanism)
    leaves = jax.tree_util.tree_leaves(directions)
    treedef = jax.tree_util.tree_structure(dynamic)
    if treedef.num_leaves != len(leaves):
        raise AssertionError("the offset mechanism has other leaves than the mechanism")
    return jax.tree_util.tree_unflatten(treedef, leaves)


def sensitivity_core(
    mechanism,
    ts,
    t0,
    t1,
    y0,
    stats_start,
    directions,
    dy0,
    config: SolverConfig,
    progress: bool,
    track_extremes: bool,
    max_events: int = 0,
):
    """The ``Trajectory`` of a solve and its tangents along p directions, error-controlled.

    Args:
        mechanism, ts, t0, t1, y0, stats_start, config, progress, track_extremes, max_events: as
            in ``_simulate._simulate_core`` (``y0`` ``None``: assembled, and differentiated).
        directions: tangents of the mechanism's inexact leaves, each with a leading axis p.
        dy0: tangents of ``y0`` (p, N), or ``None`` (zero, or ``y0`` assembled).

    Returns:
        (trajectory, tangents): a ``Trajectory`` and a ``Trajectory`` of tangents whose array
        leaves have a leading axis p (float0 for integer leaves).
    """
    dynamic, static = _partition(mechanism)
    p = (
        jax.tree_util.tree_leaves(directions)[0].shape[0]
        if jax.tree_util.tree_leaves(directions)
        else dy0.shape[0]
    )
    size = mechanism.state_size
    assembled_ok = jnp.asarray(True)
    if y0 is None:

        def start_state(d):
            m = eqx.combine(d, static)
            q0, qd0, residual, _ = assemble_state(m, t0)
            return dynamics_initial_state(m, q0, qd0), residual

        y0, linear, residual = jax.linearize(start_state, dynamic, has_aux=True)
        S0 = jax.vmap(linear)(directions)
        assembled_ok = residual < ASSEMBLY_TOLERANCE
        rho = _direction_scales(dynamic, None, directions, None)
    else:
        S0 = jnp.zeros((p, size), y0.dtype) if dy0 is None else dy0
        rho = _direction_scales(dynamic, y0, directions, S0)
    error = input_error(mechanism, y0, assembled_ok)

    offset = config.exponential and bool(np.any(mechanism.memory_rows))
    if offset:
        solve_mechanism = mechanism.with_memory_offset()
        shift, dshift = _tangents(
            lambda y, m: memory_offset_shift(m, y), mechanism, y0, S0, directions
        )
        y_start, S_start = y0 - shift, S0 - dshift
        solve_directions = _relabel(directions, solve_mechanism)
    else:
        solve_mechanism, y_start, S_start, solve_directions = mechanism, y0, S0, directions
    args = Augmented(solve_mechanism, solve_directions)

    mask = np.tile(np.asarray(mechanism.memory_rows, dtype=bool), p + 1)
    solver = config.make_solver(
        num_explicit=2 * mechanism.num_coordinates,
        decay=_augmented_decay(p),
        memory_rows=mask,
        stage=_STAGE,
    )
    controller = config.make_controller(memory_rows=mechanism.memory_rows if offset else None)
    atol = jnp.broadcast_to(jnp.asarray(controller.atol, dtype=float), (size,))
    atol = jnp.concatenate([atol, jnp.reshape(atol[None, :] * rho[:, None], (-1,))])
    controller = dataclasses.replace(
        controller, atol=atol, norm=tangent_norm(size, p, config.sensitivity_error_control)
    )
    saveat = diffrax.SaveAt(
        subs=[diffrax.SubSaveAt(ts=ts), diffrax.SubSaveAt(t1=True)], solver_state=track_extremes
    )
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(_FIELD),
        TangentTracking(solver, jnp.asarray(stats_start, dtype=float), size, max_events)
        if track_extremes
        else solver,
        t0,
        t1,
        config.dt0,
        _join(y_start, S_start),
        args=args,
        saveat=saveat,
        stepsize_controller=controller,
        max_steps=config.max_steps,
        throw=False,
        progress_meter=diffrax.TqdmProgressMeter() if progress else diffrax.NoProgressMeter(),
    )
    Ys, Y_final = sol.ys[0], sol.ys[1][-1]  # pyright: ignore[reportOptionalSubscript]
    ys, Ss = Ys[:, :size], jnp.reshape(Ys[:, size:], (Ys.shape[0], p, size))
    y_final, S_final = _split(Y_final, size)
    if offset:
        back = jax.vmap(
            lambda y, S: _tangents(
                lambda y, m: memory_offset_shift(m, y), mechanism, y, S, directions
            )
        )
        shift, dshift = back(ys, Ss)
        ys, Ss = ys + shift, Ss + dshift
        shift, dshift = _tangents(
            lambda y, m: memory_offset_shift(m, y), mechanism, y_final, S_final, directions
        )
        y_final, S_final = y_final + shift, S_final + dshift
    t_final = sol.ts[1][-1]  # pyright: ignore[reportOptionalSubscript]
    if track_extremes:
        tracker, dtracker = sol.solver_state[1]  # pyright: ignore[reportOptionalSubscript]
        floats, rest = _partition(tracker)
    else:
        floats = dtracker = rest = None

    def finish(d, ys, y_final, floats):
        extremes = eqx.combine(floats, rest).extremes() if track_extremes else None
        return make_trajectory(
            eqx.combine(d, static), ts, ys, y_final, extremes, sol.stats, sol.result, error, t_final
        )

    traj, linear = jax.linearize(finish, dynamic, ys, y_final, floats)
    tangents = jax.vmap(linear)(directions, jnp.moveaxis(Ss, 1, 0), S_final, dtracker)
    return traj, tangents


SENSITIVITY_CORE = stored_jit(sensitivity_core)
