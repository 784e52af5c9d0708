"""Forward sensitivities with error control: the derivative of the solution, not of the steps.

diffrax differentiates the steps it took: its step-size controller sees the state's error only,
so near a contact onset, where the tangent has a time scale of its own, nothing bounds the
tangent's truncation error and a derivative at rtol 1e-6 can be off by any factor
(docs/differentiation.md, "Why"). Here the state y (N,) and its tangents S (p, N) along p
directions of the parameters are integrated as one system (the simultaneous corrector method
of forward sensitivity analysis, SUNDIALS CVODES ``CV_SIMULTANEOUS``),

    ẏ = f(t, y, θ),    Ṡ_k = ∂f/∂y S_k + ∂f/∂θ V_k,    S_k(t0) = dy0/dθ V_k,

with the Jacobian products taken inside the vector field (one ``jax.jvp`` for p = 1, else
``jax.linearize`` and one vectorised product for the p directions; along y and the perturbed
parameter leaves only), by the same solver and tableau as the state, and the
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

The augmented solve runs at ``SolverConfig.sensitivity_settings()``: rtol
``sensitivity_rtol``, by default ``min(rtol, 1e-8)``, the absolute tolerances scaled with it, and
method ``sensitivity_method``, by default the solve's own with Tsit5 taken as Lawson–Tsit5 where
the mechanism has impact memories (0.59× the steps at 1e-8, as accurate). At the state's rtol
1e-6 the tangents' global error over a revolution reached 26 % on the one-joint Coulomb case
though the state's stayed below 0.02 % (docs/differentiation.md, "How the derivative's error
follows the tolerance").

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
    slip_step_fraction,
    vector_field,
)
from ..dynamics._equations import initial_state as dynamics_initial_state
from ._extremes import AbstractWrappingSolver, Tracker
from ._observables import ASSEMBLY_TOLERANCE, input_error, make_trajectory, observe
from ._solver import SolverConfig


def _partition(tree):
    return eqx.partition(tree, eqx.is_inexact_array)


def _perturbed(mechanism, directions):
    """The mechanism's inexact leaves that ``directions`` perturbs (a direction that is not
    ``None``), their directions (leading axis p) and ``rebuild(leaves) -> mechanism``: the
    linearisations run along these leaves only (an unperturbed leaf has a zero tangent, which
    would otherwise be carried through every product)."""
    dynamic, static = _partition(mechanism)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    given = treedef.flatten_up_to(directions)
    chosen = [i for i, v in enumerate(given) if v is not None]

    def rebuild(values):
        new = list(leaves)
        for i, value in zip(chosen, values):
            new[i] = value
        return eqx.combine(jax.tree_util.tree_unflatten(treedef, new), static)

    return [leaves[i] for i in chosen], [given[i] for i in chosen], rebuild


def _push_with_aux(fn, primals, tangents):
    """``fn(*primals) = (out, aux)``: out, its tangents along p directions (``tangents``: like
    ``primals``, each leaf with a leading axis p) and aux. One ``jax.jvp`` for p = 1, else one
    linearisation and a vectorised product."""
    if _num_directions(tangents) == 1:  # no vectorised map over a single direction
        first = jax.tree_util.tree_map(lambda x: x[0], tangents)
        out, dout, aux = jax.jvp(fn, primals, first, has_aux=True)
        return out, jax.tree_util.tree_map(lambda x: x[None], dout), aux
    out, linear, aux = jax.linearize(fn, *primals, has_aux=True)
    return out, jax.vmap(linear)(*tangents), aux


def _push(fn, primals, tangents):
    """``fn(*primals)`` and its tangents along p directions (``_push_with_aux``)."""
    out, dout, _ = _push_with_aux(lambda *a: (fn(*a), None), primals, tangents)
    return out, dout


def _num_directions(tangents) -> int:
    return jax.tree_util.tree_leaves(tangents)[0].shape[0]


def _tangents(fn, mechanism, y, S, V):
    """``fn(y, mechanism)`` and its tangents (p, ...) along (S_k, V_k), linearised along y and the
    perturbed leaves only (``V``: directions, ``None`` for an unperturbed leaf)."""
    theta, dtheta, rebuild = _perturbed(mechanism, V)
    return _push(lambda y, theta: fn(y, rebuild(theta)), (y, theta), (S, dtheta))


def _split(Y, size):
    return Y[:size], jnp.reshape(Y[size:], (-1, size))


def _join(y, S):
    return jnp.concatenate([y, jnp.reshape(S, (-1,))])


class Augmented(eqx.Module):
    """``args`` of the augmented solve: the mechanism and the p parameter directions V (a pytree
    like the mechanism's inexact leaves, each with a leading axis p; ``None`` for a leaf that no
    direction perturbs)."""

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


SLIP_STEP_FLOOR = 1e-13
"""s: the shortest step ``SlipResolving`` asks for (below it a step is taken as it is)."""


class SlipResolving(diffrax.AbstractAdaptiveStepSizeController):
    """A step-size controller that also rejects steps jumping a friction law's slip reversal.

    Where a clearance joint in contact reverses its slip, a Coulomb-type friction force turns
    from +μ F_N to −μ F_N across a narrow band of slip velocities, crossed in tens of nanoseconds.
    A step that jumps the band with no stage inside it integrates the state within its tolerance
    (the force is right on either side) but drops the tangents' kick there, the force's jump
    times the crossing instant's derivative; no error estimate sees it, since no stage sampled
    it. This controller rejects a step whose fraction from ``slip_step_fraction`` is below 1 and
    retries it at 0.9 of that fraction (at most the wrapped controller's own proposal); inside
    the band the wrapped controller's error norm, which covers the tangents, takes over.
    The wrapped controller's state is kept as it was at a step rejected here.

    Attributes:
        controller: the wrapped adaptive controller (``PIDController``).
        size: the state's length N (the augmented state is [y, S_1, ..., S_p]).
    """

    controller: diffrax.AbstractAdaptiveStepSizeController
    size: int = eqx.field(static=True)

    @property
    def rtol(self):
        return self.controller.rtol

    @property
    def atol(self):
        return self.controller.atol

    @property
    def norm(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.controller.norm

    def wrap(self, direction):
        return dataclasses.replace(self, controller=self.controller.wrap(direction))

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        return self.controller.init(terms, t0, t1, y0, dt0, args, func, error_order)

    def adapt_step_size(
        self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
    ):
        keep, next_t0, next_t1, jump, state, result = self.controller.adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
        )
        step = t1 - t0
        fraction = slip_step_fraction(args.mechanism, y0[: self.size], y1_candidate[: self.size])
        fraction = jax.lax.stop_gradient(fraction)
        reject = (fraction < 1) & (step > SLIP_STEP_FLOOR)
        retry = t0 + jnp.maximum(0.9 * fraction * step, SLIP_STEP_FLOOR)
        retry = jnp.where(keep, retry, jnp.minimum(retry, next_t1))
        state = jax.tree_util.tree_map(
            lambda old, new: jnp.where(reject, old, new), controller_state, state
        )
        return (
            keep & ~reject,
            jnp.where(reject, t0, next_t0),
            jnp.where(reject, retry, next_t1),
            jump & ~reject,
            state,
            result,
        )


class TangentTracking(AbstractWrappingSolver):
    """``ExtremesTracking`` for the augmented solve: the tracker of the state and its tangents
    (the linearised update of each step, per direction)."""

    solver: diffrax.AbstractSolver
    start: jax.Array
    size: int = eqx.field(static=True)
    max_events: int = eqx.field(static=True, default=0)

    def _observe(self, ts, Ys, args):
        """The observations at the instants ``ts`` (k,) of the states ``Ys`` (k, (p + 1) N) in one
        vectorised evaluation (as ``ExtremesTracking`` does), and their tangents (p, k, ...)."""
        size = self.size
        ys = Ys[:, :size]
        Ss = jnp.moveaxis(jnp.reshape(Ys[:, size:], (Ys.shape[0], -1, size)), 1, 0)
        theta, dtheta, rebuild = _perturbed(args.mechanism, args.directions)

        def both(ys, theta):
            m = rebuild(theta)
            return jax.vmap(lambda t, y: observe(t, y, m))(ts, ys)

        return _push(both, (ys, theta), (Ss, dtheta))

    def init(self, terms, t0, t1, y0, args):
        obs, dobs = self._observe(jnp.reshape(jnp.asarray(t0, dtype=float), (1,)), y0[None], args)
        take = lambda tree, i: jax.tree_util.tree_map(lambda x: x[i], tree)  # noqa: E731
        obs, dobs = take(obs, 0), jax.tree_util.tree_map(lambda x: x[:, 0], dobs)
        floats, dfloats, rest = _push_with_aux(
            lambda o: _partition(Tracker.first(self.start, t0, o, self.max_events)),
            (obs,),
            (dobs,),
        )
        tracker = eqx.combine(floats, rest)
        return self.solver.init(terms, t0, t1, y0, args), (tracker, dfloats)

    @staticmethod
    def _update(tracker, dtracker, t, obs, dobs):
        """The tracker after a sample, and its tangents (the linearised update)."""
        floats, rest = _partition(tracker)
        new_floats, dfloats, new_rest = _push_with_aux(
            lambda f, o: _partition(eqx.combine(f, rest).update(t, o)),
            (floats, obs),
            (dtracker, dobs),
        )
        return eqx.combine(new_floats, new_rest), dfloats

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        inner, (tracker, dtracker) = solver_state
        y1, y_error, dense_info, inner, result = self.solver.step(
            terms, t0, t1, y0, args, inner, made_jump
        )
        t_mid = 0.5 * (t0 + t1)
        y_mid = self.solver.interpolation_cls(t0=t0, t1=t1, **dense_info).evaluate(t_mid)
        times = jnp.stack([jnp.asarray(t_mid, dtype=float), jnp.asarray(t1, dtype=float)])
        obs, dobs = self._observe(times, jnp.stack([y_mid, y1]), args)
        for i, t in enumerate((t_mid, t1)):
            sample = jax.tree_util.tree_map(lambda x, i=i: x[i], obs)
            dsample = jax.tree_util.tree_map(lambda x, i=i: x[:, i], dobs)
            tracker, dtracker = self._update(tracker, dtracker, t, sample, dsample)
        return y1, y_error, dense_info, (inner, (tracker, dtracker)), result


def _direction_scales(mechanism, y0, V, dy0):
    """ρ_k = max_i |V_k,i| / |θ_i| over the parameters and the initial state (|θ_i| = 1 where
    θ_i = 0), 1 for a zero direction: the tangents' absolute tolerance is atol·ρ_k."""

    def ratio(theta, v):
        nominal = jnp.where(theta == 0, 1.0, jnp.abs(theta))
        return jnp.max(jnp.reshape(jnp.abs(v) / nominal[None], (v.shape[0], -1)), axis=1)

    theta, dtheta, _ = _perturbed(mechanism, V)
    parts = [ratio(t, v) for t, v in zip(theta, dtheta)]
    if y0 is not None and dy0 is not None:
        parts.append(ratio(y0, dy0))
    rho = jnp.max(jnp.stack(parts), axis=0) if parts else jnp.ones((1,))
    return jnp.where(rho > 0, rho, 1.0)


def _relabel(directions, source, target):
    """``directions`` (made for ``source``'s inexact leaves) on ``target``, a mechanism with the same
    leaves but other static fields (``with_memory_offset``)."""
    given = jax.tree_util.tree_structure(_partition(source)[0]).flatten_up_to(directions)
    treedef = jax.tree_util.tree_structure(_partition(target)[0])
    if treedef.num_leaves != len(given):
        raise AssertionError("the offset mechanism has other leaves than the mechanism")
    return jax.tree_util.tree_unflatten(treedef, given)


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
        directions: tangents of the mechanism's inexact leaves, each with a leading axis p
            (``None`` for a leaf that no direction perturbs: it is not linearised).
        dy0: tangents of ``y0`` (p, N), or ``None`` (zero, or ``y0`` assembled).

    Returns:
        (trajectory, tangents): a ``Trajectory`` and a ``Trajectory`` of tangents whose array
        leaves have a leading axis p (float0 for integer leaves).
    """
    config = config.sensitivity_settings(memory=bool(np.any(mechanism.memory_rows)))
    theta, dtheta, rebuild = _perturbed(mechanism, directions)
    p = dtheta[0].shape[0] if dtheta else dy0.shape[0]
    size = mechanism.state_size
    assembled_ok = jnp.asarray(True)
    if y0 is None:

        def start_state(theta):
            m = rebuild(theta)
            q0, qd0, residual, _ = assemble_state(m, t0)
            return dynamics_initial_state(m, q0, qd0), residual

        y0, S0, residual = _push_with_aux(start_state, (theta,), (dtheta,))
        assembled_ok = residual < ASSEMBLY_TOLERANCE
        rho = _direction_scales(mechanism, None, directions, None)
    else:
        S0 = jnp.zeros((p, size), y0.dtype) if dy0 is None else dy0
        rho = _direction_scales(mechanism, y0, directions, S0)
    error = input_error(mechanism, y0, assembled_ok)

    offset = config.exponential and bool(np.any(mechanism.memory_rows))
    if offset:
        solve_mechanism = mechanism.with_memory_offset()
        shift, dshift = _tangents(
            lambda y, m: memory_offset_shift(m, y), mechanism, y0, S0, directions
        )
        y_start, S_start = y0 - shift, S0 - dshift
        solve_directions = _relabel(directions, mechanism, solve_mechanism)
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
    if config.sensitivity_error_control and config.sensitivity_slip_steps:
        controller = SlipResolving(controller, size)
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

    def finish(theta, ys, y_final, floats):
        extremes = eqx.combine(floats, rest).extremes() if track_extremes else None
        return make_trajectory(
            rebuild(theta), ts, ys, y_final, extremes, sol.stats, sol.result, error, t_final
        )

    traj, linear = jax.linearize(finish, theta, ys, y_final, floats)
    tangents = jax.vmap(linear)(dtheta, jnp.moveaxis(Ss, 1, 0), S_final, dtracker)
    return traj, tangents


SENSITIVITY_CORE = stored_jit(sensitivity_core)
