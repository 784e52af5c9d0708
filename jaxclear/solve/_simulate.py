"""``simulate``: integrate a mechanism with diffrax and return a ``Trajectory``."""

from collections.abc import Callable
from typing import Any

import diffrax
import equinox as eqx
import jax
import jax.core  # jax.core.Tracer: imported for type checkers (jax imports it itself)
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import CustomVJPPrimal, SymbolicZero
from jax.interpreters import ad
from jaxtyping import ArrayLike

from .._core._checks import check_solve_memory, is_concrete, staging
from .._core._errors import InputCheck, ModelError, SimulationError
from .._core._executable_cache import stored_jit
from ..dynamics._assembly import assemble_state, check_assembly
from ..dynamics._equations import (
    implicit_stage,
    memory_decay_rates,
    memory_offset_shift,
    vector_field,
)
from ..dynamics._equations import initial_state as dynamics_initial_state
from ._extremes import ExtremesTracking
from ._observables import (
    ASSEMBLY_TOLERANCE,
    field_and_observation,
    input_error,
    make_trajectory,
    observe,
)
from ._sensitivity import SENSITIVITY_CORE
from ._solver import SolverConfig, solver_config
from ._trajectory import Trajectory

# diffrax traces the vector field once per Runge–Kutta stage (and per Jacobian); wrapped in a jit,
# the stages share one traced function, which XLA then inlines (same compiled code, less tracing).
_FULL = eqx.filter_jit(vector_field)
_DECAY = eqx.filter_jit(memory_decay_rates)
_STAGE = eqx.filter_jit(implicit_stage)
_INITIAL_STATE = stored_jit(dynamics_initial_state)  # eager: one program, not one per op


def initial_state(mechanism, q0, qd0):
    """Integrator state y0 = (q0, q̇0, internal states) from assembled coordinates."""
    return dynamics_initial_state(mechanism, q0, qd0)


def assemble(mechanism, t0: float = 0.0):
    """Consistent initial state y0 of a mechanism at time ``t0`` (eager, with diagnostics).

    Raises:
        AssemblyError: the geometry does not close, or constraints are redundant/singular.
    """
    check_parameters(mechanism)
    q0, qd0 = check_assembly(mechanism, t0)
    return _INITIAL_STATE(mechanism, q0, qd0)


def check_parameters(mechanism) -> None:
    """Raise ``ModelError`` naming any non-finite parameter (eager values only)."""
    leaves = jax.tree_util.tree_flatten_with_path(eqx.filter(mechanism, eqx.is_array))[0]
    for path, leaf in leaves:
        if is_concrete(leaf) and not np.all(np.isfinite(np.asarray(leaf))):
            where = jax.tree_util.keystr(path)
            raise ModelError(
                f"mechanism parameter {where} is not finite ({np.asarray(leaf)}); give a finite value."
            )


_OBSERVE = eqx.filter_jit(observe)
_FIELD = eqx.filter_jit(field_and_observation)


ADJOINTS = ("auto", "forward", "reverse", "discrete-forward", "discrete-reverse")
"""Names ``simulate`` accepts for ``adjoint`` (besides a ``diffrax.AbstractAdjoint``).

``"auto"``, ``"forward"``, ``"reverse"``: the error-controlled sensitivity solve
(``jaxclear.solve._sensitivity``); ``"discrete-forward"``, ``"discrete-reverse"`` (and a diffrax
adjoint): diffrax's differentiation of the solver's steps, whose error is not controlled."""

SENSITIVITY_ADJOINTS = ("auto", "forward", "reverse")

REVERSE_SENSITIVITY_MAX = 16
"""Reverse mode (``jax.grad``) through the sensitivity solve integrates one tangent per perturbed
scalar (a leaf of the mechanism, or the whole ``y0``, counts with its size), at most this many in
one augmented solve: with more, the tangents are integrated in blocks of this size, one augmented
solve after another (``jax.lax.map``; each block's solve takes its own steps), so the cost grows
with p but the derivative stays error-controlled (docs/differentiation.md, "Many parameters").
Forward mode (``jax.jacfwd``) integrates up to this many of its directions in one solve, more in
blocks of this size."""


def _tracer_kinds(tree) -> set[type]:
    """The tracer types on the array leaves of ``tree``, seen through ``vmap`` (a batching tracer
    holds the value it batches in ``val``)."""
    kinds: set[type] = set()
    for leaf in jax.tree_util.tree_leaves(eqx.filter(tree, eqx.is_array)):
        x = leaf
        while isinstance(x, jax.core.Tracer):
            kinds.add(type(x))
            x = getattr(x, "val", None)
    return kinds


def _has_forward_mode_tracer(tree) -> bool:
    """True if an array leaf is traced by ``jax.jvp``/``jax.jacfwd``, seen through ``vmap``.

    A transformation applied outside a ``jax.jit`` of the caller is invisible here (the leaves
    are then jit tracers); ``adjoint="forward"`` covers that case.
    """
    return any(issubclass(k, ad.JVPTracer) for k in _tracer_kinds(tree))


def _is_differentiated(tree) -> bool:
    """True if an array leaf is traced by a differentiation (``jax.jvp``, ``jax.grad``,
    ``jax.linearize``), seen through ``vmap``."""
    linearize = getattr(ad, "LinearizeTracer", None)
    kinds = _tracer_kinds(tree)
    return any(
        issubclass(k, ad.JVPTracer) or (linearize is not None and issubclass(k, linearize))
        for k in kinds
    )


def _auto_mode(tree) -> str:
    """``adjoint="auto"``'s sensitivity mode: ``"forward"`` under ``jax.jvp``/``jax.jacfwd``,
    ``"reverse"`` under ``jax.grad``/``jax.vjp``/``jax.jacrev``, and ``"either"`` when the leaves
    show neither (the transformation is applied outside a ``jax.jit`` of the caller, which hides
    it): a ``jax.custom_jvp`` that integrates one tangent per perturbed scalar and contracts them
    with the tangents, so that both modes go through it."""
    kinds = _tracer_kinds(tree)
    if any(issubclass(k, ad.JVPTracer) for k in kinds):
        return "forward"
    linearize = getattr(ad, "LinearizeTracer", None)
    if linearize is not None and any(issubclass(k, linearize) for k in kinds):
        return "reverse"
    return "either"


def make_adjoint(adjoint, traced_tree=None, config=None) -> diffrax.AbstractAdjoint:
    """The diffrax adjoint for ``simulate``'s ``adjoint`` argument.

    ``"reverse"``: ``diffrax.RecursiveCheckpointAdjoint`` with ``config.checkpoints`` checkpoints
    (``SolverConfig.reverse_adjoint``; reverse mode: ``jax.grad``, ``jax.vjp``, ``jax.jacrev``;
    ``None`` is diffrax's default, ``gradient_solver`` stores every step). ``"forward"``:
    ``diffrax.ForwardMode`` (``jax.jvp``, ``jax.jacfwd``; cheaper than reverse mode for a few
    parameters, no reverse mode). ``"auto"``: forward mode if ``traced_tree`` carries
    ``jax.jvp``/``jax.jacfwd`` tracers, reverse mode otherwise.
    """
    if isinstance(adjoint, diffrax.AbstractAdjoint):
        return adjoint
    if adjoint in ("discrete-forward", "discrete-reverse"):
        adjoint = adjoint.removeprefix("discrete-")
    if adjoint == "auto":
        adjoint = "forward" if _has_forward_mode_tracer(traced_tree) else "reverse"
    if adjoint == "reverse":
        if config is not None:
            return config.reverse_adjoint()
        return diffrax.RecursiveCheckpointAdjoint()
    if adjoint == "forward":
        return diffrax.ForwardMode()
    raise ValueError(
        f"adjoint {adjoint!r} is unknown; use one of {', '.join(map(repr, ADJOINTS))} or a diffrax.AbstractAdjoint."
    )


@stored_jit
def _simulate_core(
    mechanism,
    ts,
    t0,
    t1,
    y0,
    stats_start,
    config: SolverConfig,
    adjoint,
    progress: bool,
    track_extremes: bool,
    max_events: int = 0,
):
    assembled_ok = jnp.asarray(True)
    if y0 is None:
        q0, qd0, pos_res, _ = assemble_state(mechanism, t0)
        assembled_ok = pos_res < ASSEMBLY_TOLERANCE
        y0 = initial_state(mechanism, q0, qd0)
    error = input_error(mechanism, y0, assembled_ok)
    saveat = diffrax.SaveAt(
        subs=[diffrax.SubSaveAt(ts=ts), diffrax.SubSaveAt(t1=True)], solver_state=track_extremes
    )
    # IMEX methods run as AffineKenCarp (closed-form stage solves, jaxclear/solve/_imex.py) on the full
    # vector field, with the stiff part passed to the solver.
    terms = diffrax.ODETerm(_FULL)
    # Exponential methods integrate the impact memory in offset form u = m − δ̇ (a pure decay in
    # free flight); states are converted at the ends, so y0, ys and y_final hold m as always.
    offset = config.exponential and bool(np.any(mechanism.memory_rows))
    solve_mechanism = mechanism.with_memory_offset() if offset else mechanism
    y_start = y0 - memory_offset_shift(mechanism, y0) if offset else y0
    solver = config.make_solver(
        num_explicit=2 * mechanism.num_coordinates,
        decay=_DECAY,
        memory_rows=mechanism.memory_rows,
        stage=_STAGE,
    )
    # ForwardMode sets the Runge–Kutta stage loop to a kind that jvp can go through only for an
    # unwrapped solver (diffrax/_adjoint.py, ForwardMode, "Support forward-mode autodiff"); do it
    # for the wrapped one the same way.
    if isinstance(adjoint, diffrax.ForwardMode) and isinstance(solver, diffrax.AbstractRungeKutta):
        if solver.scan_kind is None:
            solver = eqx.tree_at(lambda s: s.scan_kind, solver, "lax", is_leaf=lambda x: x is None)
    sol = diffrax.diffeqsolve(
        terms,
        ExtremesTracking(
            solver, _OBSERVE, jnp.asarray(stats_start, dtype=float), max_events, field=_FIELD
        )
        if track_extremes
        else solver,
        t0,
        t1,
        config.dt0,
        y_start,
        args=solve_mechanism,
        saveat=saveat,
        stepsize_controller=config.make_controller(
            memory_rows=mechanism.memory_rows if offset else None
        ),
        max_steps=config.max_steps,
        adjoint=adjoint,
        throw=False,
        progress_meter=diffrax.TqdmProgressMeter() if progress else diffrax.NoProgressMeter(),
    )
    # diffrax types Solution.ys/ts as optional; the SaveAt above always saves both
    ys, y_final = sol.ys[0], sol.ys[1][-1]  # pyright: ignore[reportOptionalSubscript]
    if offset:
        ys = ys + jax.vmap(lambda y: memory_offset_shift(mechanism, y))(ys)
        y_final = y_final + memory_offset_shift(mechanism, y_final)
    extremes = sol.solver_state[1].extremes() if track_extremes else None  # pyright: ignore[reportOptionalSubscript]
    t_final = sol.ts[1][-1]  # pyright: ignore[reportOptionalSubscript]
    return make_trajectory(
        mechanism, ts, ys, y_final, extremes, sol.stats, sol.result, error, t_final
    )


TIME_ARGUMENTS_MESSAGE = (
    "simulate's error-controlled derivatives are with respect to the mechanism's parameters and y0; "
    "for derivatives with respect to t0, t1, ts or statistics_start pass adjoint='discrete-forward' "
    "(jax.jvp, jax.jacfwd) or adjoint='discrete-reverse' (jax.grad), which differentiate the solver's steps."
)


def _is_zero(x) -> bool:
    return isinstance(x, SymbolicZero) or x is None


def _check_no_time_tangents(tangents) -> None:
    leaves = jax.tree_util.tree_leaves(tangents, is_leaf=lambda x: isinstance(x, SymbolicZero))
    if not all(_is_zero(x) for x in leaves):
        raise ValueError(TIME_ARGUMENTS_MESSAGE)


def _inexact_leaves(tree) -> list:
    """The leaves of ``tree``, ``None`` for those that are not inexact arrays (float0 tangents)."""
    return [
        x if jnp.issubdtype(x.dtype, jnp.inexact) else None for x in jax.tree_util.tree_leaves(tree)
    ]


def _with_integer_zeros(primal, leaves):
    """The tangent tree of ``primal`` from its inexact leaves' tangents (``None`` elsewhere):
    float0 zeros for the integer leaves."""
    p_leaves, treedef = jax.tree_util.tree_flatten(primal)
    full = [
        np.zeros(np.shape(x), dtype=jax.dtypes.float0) if t is None else t
        for t, x in zip(leaves, p_leaves)
    ]
    return jax.tree_util.tree_unflatten(treedef, full)


def _unit_directions(leaves, flags, p):
    """Unit directions along each scalar of the perturbed leaves (p = their total size), ``None``
    for the others (not linearised): a list like ``leaves`` of arrays with a leading axis p."""
    eye, offset, out = jnp.eye(p), 0, []
    for leaf, flag in zip(leaves, flags):
        if flag:
            size = int(np.prod(leaf.shape))
            out.append(jnp.reshape(eye[:, offset : offset + size], (p,) + leaf.shape))
            offset += size
        else:
            out.append(None)
    return out


def differentiable_simulate(
    mode, mechanism, grid, t0, t1, y0, start, config, progress, track_extremes, max_events
) -> Trajectory:
    """``_simulate_core`` whose derivatives come from the error-controlled sensitivity solve
    (``jaxclear.solve._sensitivity``): a ``jax.custom_jvp`` for ``mode="forward"`` (``jax.jvp``,
    ``jax.jacfwd``: one solve along the incoming directions, ``merged_jvp``; under an outer
    differentiation along every perturbed scalar, contracted), a ``jax.custom_vjp`` for
    ``mode="reverse"`` (``jax.grad``,
    ``jax.vjp``, ``jax.jacrev``: the forward pass integrates one tangent per perturbed scalar of the
    mechanism and y0, the backward pass contracts them with the cotangent). Without
    differentiation either is the plain solve."""
    dynamic, static = eqx.partition(mechanism, eqx.is_inexact_array)

    def primal(dynamic, y0, grid, t0, t1, start):
        return _simulate_core(
            eqx.combine(dynamic, static),
            grid,
            t0,
            t1,
            y0,
            start,
            config,
            diffrax.RecursiveCheckpointAdjoint(),
            progress,
            track_extremes,
            max_events,
        )

    def solve_with_tangents(dynamic, y0, directions, dy0, grid, t0, t1, start):
        return SENSITIVITY_CORE(
            eqx.combine(dynamic, static),
            grid,
            t0,
            t1,
            y0,
            start,
            directions,
            dy0,
            config,
            progress,
            track_extremes,
            max_events,
        )

    def tangent_solve(dynamic, y0, directions, dy0, grid, t0, t1, start):
        traj, tangent = solve_with_tangents(dynamic, y0, directions, dy0, grid, t0, t1, start)
        return traj, _inexact_leaves(tangent)

    args = (dynamic, y0, grid, t0, t1, start)
    is_zero = lambda x: isinstance(x, SymbolicZero)  # noqa: E731

    def perturbed(primals, tangents):
        """The perturbed leaves: (values, their tree, tangents, flags, y0 perturbed, p scalars)."""
        dynamic, y0 = primals[:2]
        d_dynamic, d_y0 = tangents[:2]
        values, d_def = jax.tree_util.tree_flatten(dynamic)
        d_leaves = jax.tree_util.tree_leaves(d_dynamic, is_leaf=is_zero)
        flags = [not _is_zero(d) for d in d_leaves]
        y0_flag = y0 is not None and not _is_zero(d_y0)
        p = sum(int(np.prod(v.shape)) for v, f in zip(values, flags) if f)
        p += int(y0.size) if y0_flag else 0
        return values, d_def, d_leaves, flags, y0_flag, p

    def jvp_contracted(primals, tangents):
        # the sensitivities along every perturbed scalar, computed from the primals alone (one
        # augmented solve: under jax.jacfwd's vmap it stays unbatched, so all directions share
        # it), then contracted with the tangents: linear in them, so JAX also transposes the
        # contraction for reverse mode (the solve itself, a while loop, is never transposed).
        # The trajectory returned is the augmented solve's, the one its tangents belong to (as
        # reverse mode's): a loss of it and its tangents is differentiated consistently, and no
        # plain solve is needed.
        dynamic, y0 = primals[:2]
        d_y0 = tangents[1]
        _check_no_time_tangents(tangents[2:])
        values, d_def, d_leaves, flags, y0_flag, p = perturbed(primals, tangents)
        if p == 0:
            traj = primal(*primals)
            zeros = [None if x is None else jnp.zeros_like(x) for x in _inexact_leaves(traj)]
            return traj, _with_integer_zeros(traj, zeros)
        units = _unit_directions(values + ([y0] if y0_flag else []), flags + [y0_flag], p)
        directions = jax.tree_util.tree_unflatten(d_def, units[: len(values)])
        dy0 = units[-1] if y0_flag else None
        traj, sens = tangent_solve(dynamic, y0, directions, dy0, *primals[2:])
        chosen = [d for d, f in zip(d_leaves, flags) if f] + ([d_y0] if y0_flag else [])
        along = jnp.concatenate([jnp.reshape(d, (-1,)) for d in chosen])
        out = [None if s is None else jnp.tensordot(along, s, axes=1) for s in sens]
        return traj, _with_integer_zeros(traj, out)

    def solve_along(primals, dirs, flags, y0_flag, d_def, static_part):
        """(the trajectory's arrays, its tangents' inexact leaves with a leading axis k) of one
        augmented solve along k directions: ``dirs``, the tangents of the perturbed leaves (and
        y0 last), each with a leading axis k; more than ``REVERSE_SENSITIVITY_MAX`` in blocks of
        that size (``jax.lax.map``, the last padded with zero directions), the trajectory the first
        block's. The trajectory's static fields go to ``static_part["traj"]``."""
        k = dirs[0].shape[0]

        def one(dirs):
            it = iter(dirs)
            full = [next(it) if f else None for f in flags]
            directions = jax.tree_util.tree_unflatten(d_def, full)
            dy0 = dirs[-1] if y0_flag else None
            traj, tangent = solve_with_tangents(
                primals[0], primals[1], directions, dy0, *primals[2:]
            )
            arrays, static_part["traj"] = eqx.partition(traj, eqx.is_array)
            return arrays, _inexact_leaves(tangent)

        size = REVERSE_SENSITIVITY_MAX
        if k <= size:
            return one(dirs)
        blocks = -(-k // size)
        padded = [
            jnp.reshape(
                jnp.concatenate([u, jnp.zeros((blocks * size - k,) + u.shape[1:], u.dtype)]),
                (blocks, size) + u.shape[1:],
            )
            for u in dirs
        ]
        arrays, tangents = jax.lax.map(one, padded)
        arrays = jax.tree_util.tree_map(lambda x: x[0], arrays)
        tangents = [
            None if t is None else jnp.reshape(t, (blocks * size,) + t.shape[2:])[:k]
            for t in tangents
        ]
        return arrays, tangents

    def merged_jvp(primals, tangents):
        """The augmented solve along the incoming tangents themselves: a
        ``jax.custom_batching.custom_vmap`` whose rule, where only the tangents are batched (the
        directions of ``jax.jacfwd``), integrates its k directions in one solve (min(k, p): along
        the p perturbed scalars and contracted, where k > p), so the cost follows the number of
        directions, not of the leaves they touch (a length that moves 7 leaves costs one tangent,
        not 7). Where the primal values are batched too (an inner ``jax.vmap``), each lane solves
        along every perturbed scalar and contracts (``jvp_contracted``), so that an outer
        ``jax.jacfwd`` shares that solve."""
        values, d_def, d_leaves, flags, y0_flag, p = perturbed(primals, tangents)
        chosen = [d for d, f in zip(d_leaves, flags) if f] + ([tangents[1]] if y0_flag else [])
        static_part = {}
        setting = dict(flags=flags, y0_flag=y0_flag, d_def=d_def, static_part=static_part)

        def contracted(primals, dirs):
            # along the p perturbed scalars, contracted with the k directions (k, ...)
            units = _unit_directions(
                values + ([primals[1]] if y0_flag else []), flags + [y0_flag], p
            )
            arrays, sens = solve_along(primals, [u for u in units if u is not None], **setting)
            k = dirs[0].shape[0]
            along = jnp.concatenate([jnp.reshape(d, (k, -1)) for d in dirs], axis=1)
            return arrays, [None if s is None else jnp.tensordot(along, s, axes=1) for s in sens]

        def lane(primals, chosen):
            # one lane of a batch of primal values: as jvp_contracted up to
            # REVERSE_SENSITIVITY_MAX perturbed scalars, else along its own tangent
            dirs = [c[None] for c in chosen]
            solve = contracted if p <= REVERSE_SENSITIVITY_MAX else partial_solve
            arrays, out = solve(primals, dirs)
            return arrays, [None if t is None else t[0] for t in out]

        def partial_solve(primals, dirs):
            return solve_along(primals, dirs, **setting)

        @jax.custom_batching.custom_vmap
        def along(primals, chosen):
            arrays, out = solve_along(primals, [c[None] for c in chosen], **setting)
            return arrays, [None if t is None else t[0] for t in out]

        @along.def_vmap
        def _(k, in_batched, primals, chosen):
            primal_batched, chosen_batched = in_batched
            if any(jax.tree_util.tree_leaves(primal_batched)):
                in_axes = (
                    jax.tree_util.tree_map(lambda b: 0 if b else None, primal_batched),
                    [0 if b else None for b in chosen_batched],
                )
                out = jax.vmap(lane, in_axes=in_axes)(primals, chosen)
                return out, jax.tree_util.tree_map(lambda _: True, out)
            dirs = [
                c if b else jnp.broadcast_to(c, (k,) + c.shape)
                for c, b in zip(chosen, chosen_batched)
            ]
            arrays, out = (partial_solve if k <= p else contracted)(primals, dirs)
            return (arrays, out), (
                jax.tree_util.tree_map(lambda _: False, arrays),
                jax.tree_util.tree_map(lambda _: True, out),
            )

        arrays, out = along(primals, chosen)
        traj = eqx.combine(arrays, static_part["traj"])
        return traj, _with_integer_zeros(traj, out)

    if mode == "forward":
        fn = jax.custom_jvp(primal)

        def jvp(primals, tangents):
            dynamic, y0 = primals[:2]
            d_dynamic, d_y0 = tangents[:2]
            _check_no_time_tangents(tangents[2:])
            p = perturbed(primals, tangents)[-1]
            if p > 0 and not _is_differentiated(primals):
                return merged_jvp(primals, tangents)
            # under an outer differentiation (the rule's primal values are its tracers: a
            # custom_vmap is not transposed), as before the merged rule
            if p <= REVERSE_SENSITIVITY_MAX:
                # one augmented solve along every perturbed scalar, shared by jax.jacfwd's
                # directions (FORWARD_MERGED in docs/differentiation.md)
                return jvp_contracted(primals, tangents)
            # None along the leaves without a tangent: the sensitivity solve does not linearise
            # along them
            directions = jax.tree_util.tree_map(
                lambda x, d: None if _is_zero(d) else d[None],
                dynamic,
                d_dynamic,
                is_leaf=is_zero,
            )
            dy0 = None if y0 is None or _is_zero(d_y0) else d_y0[None]
            # the trajectory from the plain solve: it does not depend on the tangents, so under
            # jax.jacfwd (a vmap of jax.jvp over them) it stays unbatched, as jacfwd requires, and
            # equals an undifferentiated call; the tangent from the augmented solve along this
            # direction (jacfwd batches them, each with its own steps)
            traj = primal(*primals)
            _, tangents = tangent_solve(dynamic, y0, directions, dy0, *primals[2:])
            return traj, _with_integer_zeros(traj, [None if t is None else t[0] for t in tangents])

        fn.defjvp(jvp, symbolic_zeros=True)
        return fn(*args)

    if mode == "either":
        fn = jax.custom_jvp(primal)
        fn.defjvp(jvp_contracted, symbolic_zeros=True)
        return fn(*args)

    fn = jax.custom_vjp(primal)
    layout = {}  # static facts the forward pass finds for the backward pass
    is_primal = lambda x: isinstance(x, CustomVJPPrimal)  # noqa: E731

    def fwd(dynamic, y0, *times):
        _check_no_time_tangents(
            [
                SymbolicZero(None) if not x.perturbed else x
                for x in jax.tree_util.tree_leaves(times, is_leaf=is_primal)
            ]  # type: ignore[arg-type]
        )
        plain = lambda tree: jax.tree_util.tree_map(lambda x: x.value, tree, is_leaf=is_primal)  # noqa: E731
        d_leaves, d_def = jax.tree_util.tree_flatten(dynamic, is_leaf=is_primal)
        values = [x.value for x in d_leaves]
        flags = [bool(x.perturbed) for x in d_leaves]
        y0_value = None if y0 is None else y0.value
        y0_flag = y0 is not None and bool(y0.perturbed)
        p = sum(int(np.prod(v.shape)) for v, f in zip(values, flags) if f)
        p += int(y0_value.size) if y0_flag else 0
        dynamic, times = jax.tree_util.tree_unflatten(d_def, values), plain(times)
        if p == 0:
            return primal(dynamic, y0_value, *times), None
        units = _unit_directions(values + ([y0_value] if y0_flag else []), flags + [y0_flag], p)
        layout.update(shapes=[v.shape for v in values], flags=flags, y0_flag=y0_flag, p=p)
        # one augmented solve, or blocks of REVERSE_SENSITIVITY_MAX (the last padded with zero
        # directions, whose tangents are zero and whose weight in the error norm is atol), the
        # trajectory the first block's
        static_part = {}
        arrays, tangents = solve_along(
            (dynamic, y0_value, *times),
            [u for u in units if u is not None],
            flags,
            y0_flag,
            d_def,
            static_part,
        )
        return eqx.combine(arrays, static_part["traj"]), tangents

    def bwd(residuals, cotangent):
        if residuals is None:
            return (None,) * len(args)
        tangents = residuals
        shapes, flags, y0_flag, p = (layout[k] for k in ("shapes", "flags", "y0_flag", "p"))
        cts = jax.tree_util.tree_leaves(cotangent, is_leaf=lambda x: isinstance(x, SymbolicZero))
        total = jnp.zeros((p,))
        for tangent, ct in zip(tangents, cts):
            if tangent is None or _is_zero(ct) or not jnp.issubdtype(ct.dtype, jnp.inexact):
                continue
            total = total + jnp.reshape(tangent, (p, -1)) @ jnp.reshape(ct, (-1,))
        grads, offset = [], 0
        for shape, flag in zip(shapes, flags):
            size = int(np.prod(shape))
            grads.append(jnp.reshape(total[offset : offset + size], shape) if flag else None)
            offset += size if flag else 0
        d_def = jax.tree_util.tree_structure(dynamic)
        g_dynamic = jax.tree_util.tree_unflatten(
            d_def, [g if g is not None else jnp.zeros(s) for g, s in zip(grads, shapes)]
        )
        g_y0 = jnp.reshape(total[offset:], y0.shape) if y0_flag else None
        return (g_dynamic, g_y0, None, None, None, None)

    fn.defvjp(fwd, bwd, symbolic_zeros=True)
    return fn(*args)


def _is_concrete_number(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


def _time_grid(t0, t1, ts, num_points):
    """Output times: checked NumPy values for concrete t0, t1, ts; a traced grid otherwise."""
    if ts is None:
        n = 201 if num_points is None else int(num_points)
        if n < 2:
            raise ValueError(
                f"num_points must be at least 2 (the grid holds t0 and t1), got {num_points}; for "
                "the state at t1 alone pass ts=[t1] (or read Trajectory.y_final)."
            )
        if not (_is_concrete_number(t0) and _is_concrete_number(t1)):
            return jnp.linspace(t0, t1, n)
        ts = np.linspace(t0, t1, n)
    if isinstance(ts, jax.core.Tracer):
        if ts.ndim != 1:
            raise ValueError(f"ts must be a 1-D array of output times, got shape {ts.shape}.")
        return ts
    ts = np.asarray(ts, dtype=float)
    if ts.ndim != 1 or ts.size < 1:
        raise ValueError("ts must be a 1-D array of output times.")
    if _is_concrete_number(t0) and _is_concrete_number(t1):
        if np.any(np.diff(ts) < 0) or ts[0] < t0 or ts[-1] > t1 or not np.all(np.isfinite(ts)):
            raise ValueError(
                f"ts must be increasing and inside [t0, t1] = [{t0}, {t1}]; got {ts[0]} .. {ts[-1]}."
            )
    return jnp.asarray(ts)


def _check_memory(mechanism, ts, num_points, events: int) -> None:
    """Refuse output buffers larger than this machine's memory before making the time grid or
    compiling (XLA may wait forever for one it cannot allocate): ``check_solve_memory``."""
    if ts is not None:
        num_saved = int(np.size(ts))
    else:  # as _time_grid
        num_saved = 201 if num_points is None else int(num_points)
    # a translational clearance joint has three event channels (J, J.upper, J.lower)
    channels = len(mechanism.clearance_joints) + 3 * len(mechanism.translational_clearance_joints)
    check_solve_memory(mechanism.state_size, channels, num_saved, events)


def _is_traced(tree) -> bool:
    leaves = jax.tree_util.tree_leaves(eqx.filter(tree, eqx.is_array))
    return staging() or any(isinstance(x, jax.core.Tracer) for x in leaves)


def simulate(
    mechanism,
    t1: ArrayLike,
    *,
    t0: ArrayLike = 0.0,
    ts=None,
    num_points: int | None = None,
    solver: "str | SolverConfig" = "auto",
    y0=None,
    adjoint: "str | diffrax.AbstractAdjoint" = "auto",
    statistics_start: ArrayLike | None = None,
    extremes: bool = True,
    contact_events: int = 0,
    progress: bool = False,
    throw: bool = True,
) -> Trajectory:
    """Simulate a mechanism from ``t0`` to ``t1``: the front door of jaxclear.

    A pure function of the mechanism's array leaves (masses, lengths, clearances, stiffnesses,
    restitution, friction, crank speed, ...) and of ``y0``: it works unchanged under
    ``jax.jit``, ``jax.vmap``, ``jax.grad``, ``jax.jvp``/``jax.jacfwd`` and their compositions.
    Compiled once per mechanism topology, solver config and number of output points: new
    parameter values or end times reuse the compiled code.

    Called eagerly (no transformation), it checks its inputs on the host (``ModelError``,
    ``AssemblyError`` naming the offending part) and raises ``SimulationError`` if the solve fails.
    Under a transformation nothing can be raised on values: failures are data, as in a batch
    (``Trajectory.succeeded``, ``.result``, ``.input_error``; ``raise_for_failure`` raises them
    afterwards on concrete results).

    The initial state is assembled (consistent positions and velocities, journals at their
    ``initial_eccentricity``, centred by default) unless ``y0`` is given.

    Args:
        mechanism: a ``Mechanism``.
        t1: end time, s.
        t0: start time, s.
        ts: output times (increasing, inside [t0, t1]); default ``num_points`` uniform points.
        num_points: number of uniform output points if ``ts`` is not given (default 201).
        solver: ``"auto"`` (``imex`` with LuGre friction, else ``fast``; see
            ``recommended_solver``), a preset name (``"robust"``, ``"fast"``, ``"imex"``,
            ``"accurate"``), a method name or a ``SolverConfig``.
        y0: initial state (from ``assemble``) to skip assembly.
        adjoint: how derivatives go through the solve: ``"reverse"`` (``jax.grad``, ``jax.vjp``,
            ``jax.jacrev``: the error-controlled sensitivities along every perturbed scalar,
            contracted with the cotangent), ``"forward"`` (``jax.jvp``, ``jax.jacfwd``: the
            directions share one augmented solve up to 16 perturbed scalars; no reverse mode), ``"auto"`` (default: forward mode when
            the inputs carry ``jax.jvp``/``jax.jacfwd`` tracers, reverse mode under
            ``jax.grad``/``jax.vjp``/``jax.jacrev``; when a ``jax.jit`` of your function hides the
            transformation, a rule that serves both: the sensitivities along every perturbed
            scalar, contracted with the tangents), ``"discrete-forward"``/``"discrete-reverse"``
            (diffrax's differentiation of the solver's steps, error not controlled) or any
            ``diffrax.AbstractAdjoint``. The sensitivity solve runs at ``solver.sensitivity_rtol``
            (default ``min(rtol, 1e-8)``: derivatives over a revolution match converged central
            differences, docs/differentiation.md) with ``solver.sensitivity_method`` (default the
            solver's, Tsit5 as Lawson–Tsit5 where there are impact memories). No effect on the
            values.
        statistics_start: start time, s, of the window over which ``Trajectory.extremes`` (peak
            forces, penetrations and accelerations, torque extremes and RMS) are taken from the
            solver's steps; default ``t0``. Use it to leave out the start-up revolutions.
        extremes: track ``Trajectory.extremes`` (samples at each step's midpoint and end, taken
            from the solver's own stages with Tsit5 and by two more evaluations of forces and
            accelerations otherwise: +12–14 % run time on the benchmark slider–crank with one
            clearance joint, +28–30 % with three and LuGre, benchmarks/README.md). ``False`` skips it (``Trajectory.extremes`` is then ``None``),
            e.g. for fits that need only the trajectory.
        contact_events: record up to this many contact events (onset and end, located between
            the solver's samples) per clearance joint in ``Trajectory.extremes`` (needs
            ``extremes``): contact modes that do not depend on the output grid
            (``jaxclear.analysis.contact_events``). 0 (default) records none; a new value
            compiles again.
        progress: show a progress bar (tqdm) over simulated time.
        throw: eager calls only: raise ``SimulationError`` if the solve fails (else inspect
            ``Trajectory.result``).

    Returns:
        A ``Trajectory``.

    Raises:
        ValueError: a bad argument (time grid, adjoint name, shape of ``y0``).
        ModelError: a non-finite or invalid parameter (eager calls).
        AssemblyError: the mechanism cannot be assembled (eager calls).
        SimulationError: the solver failed (eager calls with ``throw``; gives the time reached,
            the state and a fix).
    """
    config = solver_config(solver, mechanism)
    traced = _is_traced((mechanism, y0, t0, t1, ts, statistics_start))
    if _is_concrete_number(t0) and _is_concrete_number(t1):
        t0, t1 = float(np.asarray(t0)), float(np.asarray(t1))
        if not np.isfinite(t0):
            raise ValueError(f"t0 must be finite, got {t0}.")
        if not (np.isfinite(t1) and t1 > t0):
            raise ValueError(f"t1 must be finite and greater than t0={t0}, got {t1}.")
    _check_memory(mechanism, ts, num_points, int(contact_events) if extremes else 0)
    grid = _time_grid(t0, t1, ts, num_points)
    if y0 is not None:
        y0 = jnp.asarray(y0, dtype=float)
        if y0.shape != (mechanism.state_size,):
            raise ValueError(f"y0 must have shape ({mechanism.state_size},), got {y0.shape}.")
    elif not traced:
        y0 = assemble(mechanism, float(np.asarray(t0)))
    start = t0 if statistics_start is None else statistics_start
    if not (isinstance(adjoint, diffrax.AbstractAdjoint) or adjoint in ADJOINTS):
        raise ValueError(
            f"adjoint {adjoint!r} is unknown; use one of {', '.join(map(repr, ADJOINTS))} or a diffrax.AbstractAdjoint."
        )
    events = int(contact_events) if extremes else 0
    times = (grid, jnp.asarray(t0, dtype=float), jnp.asarray(t1, dtype=float))
    start = jnp.asarray(start, dtype=float)
    try:
        if traced and isinstance(adjoint, str) and adjoint in SENSITIVITY_ADJOINTS:
            if adjoint == "auto":
                adjoint = _auto_mode((mechanism, y0))
            return differentiable_simulate(
                adjoint, mechanism, *times, y0, start, config, progress, extremes, events
            )
        traj = _simulate_core(
            mechanism,
            *times,
            y0,
            start,
            config,
            make_adjoint(adjoint, (mechanism, y0), config),
            progress,
            extremes,
            events,
        )
    except TypeError as e:  # jax.jvp/jacfwd through a reverse-mode rule (a custom_vjp)
        if "custom_vjp" in str(e):
            raise TypeError(
                "forward-mode differentiation (jax.jvp, jax.jacfwd) of simulate needs adjoint='forward' "
                "(or the default 'auto' when the jvp is not outside a jax.jit of your function)."
            ) from e
        raise
    if not traced:
        raise_for_failure(traj, config if throw else None)
    return traj


def raise_for_failure(traj: Trajectory, config: SolverConfig | None = None) -> None:
    """Raise the errors of a concrete (not traced) trajectory, single or batched.

    Input checks made inside the compiled solve raise ``ModelError`` (``AssemblyError`` for an
    assembly failure), naming the failing batch members. With ``config`` given, a failed solve of
    an unbatched trajectory raises ``SimulationError`` with the time reached, the state and a fix.
    """
    raise_input_errors(traj)
    if config is not None and np.ndim(traj.succeeded) == 0 and not bool(traj.succeeded):
        raise failure_error(traj, config)


def raise_input_errors(traj: Trajectory) -> None:
    """Raise ``ModelError`` (``AssemblyError`` for ``InputCheck.NOT_ASSEMBLED``) for the input checks made inside the
    compiled solve; for a batch, name the failing members."""
    codes = np.atleast_1d(np.asarray(traj.input_error))
    bad = np.flatnonzero(codes)
    if bad.size == 0:
        return
    check = InputCheck(int(codes[bad[0]]))
    where = f" (batch members {bad.tolist()} of {codes.size})" if np.ndim(traj.input_error) else ""
    raise check.error(check.message + where + ".")


def _result_message(result) -> str:
    try:
        return diffrax.RESULTS[result]
    except Exception:  # message lookup is best effort; the outcome itself is in Trajectory.result
        return "solver failed"


def failure_error(traj: Trajectory, config: SolverConfig) -> SimulationError:
    """A ``SimulationError`` describing a failed solve: time reached, state, suggested fix."""
    mech = traj.mechanism
    n = mech.num_coordinates
    y = np.asarray(traj.y_final)
    t = float(traj.t_final)
    state = {"q": y[:n].tolist(), "qd": y[n : 2 * n].tolist(), "internal": y[2 * n :].tolist()}
    reason = _result_message(traj.result)
    if int(traj.num_steps) >= config.max_steps:
        fix = f"raise max_steps (now {config.max_steps}) or loosen rtol/atol (now {config.rtol}/{config.atol})"
    elif not np.all(np.isfinite(y)):
        fix = "the state became non-finite: check parameters, or try the 'robust' implicit solver"
    elif not config.implicit:
        fix = "the problem may be stiff (e.g. LuGre friction): use solver='robust' (Kvaerno5)"
    else:
        fix = "loosen newton_rtol/newton_atol, loosen rtol, or increase the smoothing widths"
    coords = ", ".join(
        f"{b}=({y[3 * i]:.6g}, {y[3 * i + 1]:.6g}, {y[3 * i + 2]:.6g})"
        for i, b in enumerate(mech.body_names)
    )
    return SimulationError(
        f"simulation failed at t = {t:.9g} s after {int(traj.num_steps)} steps ({reason}). "
        f"Coordinates (x, y, phi): {coords}. Suggested fix: {fix}.",
        t=t,
        state=state,
    )


def simulate_batch(
    build: Callable[[Any], Any],
    parameters: Any,
    t1: ArrayLike,
    *,
    t0: ArrayLike = 0.0,
    ts=None,
    num_points: int | None = None,
    solver: "str | SolverConfig" = "auto",
    adjoint: "str | diffrax.AbstractAdjoint" = "auto",
    statistics_start: ArrayLike | None = None,
    extremes: bool = True,
    contact_events: int = 0,
) -> Trajectory:
    """Simulate many variants of a mechanism in one vectorised solve: ``jax.vmap`` of ``simulate``.

    Jittable and differentiable like ``simulate``. Members run in lockstep until the slowest one
    finishes.

    Args:
        build: ``build(p) -> Mechanism`` for one member's parameters ``p`` (a pytree of arrays).
        parameters: pytree whose leaves have a leading batch axis.
        t1, t0, ts, num_points, solver, adjoint, statistics_start, extremes, contact_events: as in
            ``simulate``.

    Returns:
        A batched ``Trajectory`` (``traj.member(k)`` is member k as a single one). Members whose solve fails do not raise: check ``traj.succeeded``
        and ``traj.t_final`` per member.

    Raises:
        AssemblyError, ModelError: eager calls only: some members cannot be assembled or have
            invalid values (the message lists them).
    """
    if solver == "auto":
        # the friction laws (which decide) are static: build one member abstractly to see them
        first = jax.tree_util.tree_map(lambda x: x[0], parameters)
        solver = solver_config("auto", eqx.filter_eval_shape(build, first))
    config = solver_config(solver)

    def one(p):
        return simulate(
            build(p),
            t1,
            t0=t0,
            ts=ts,
            num_points=num_points,
            solver=config,
            adjoint=adjoint,
            statistics_start=statistics_start,
            extremes=extremes,
            throw=False,
            contact_events=contact_events,
        )

    traj = eqx.filter_vmap(one)(parameters)
    if not _is_traced(traj):
        raise_input_errors(traj)
    return traj
