"""Lane refilling (issue 25, part 1; a prototype): many members of one mechanism topology solved by
one vectorised loop over a fixed number of lanes, where a lane whose member is done takes the next
member at once.

A vmapped ``simulate`` (the lockstep chunks of the ensemble engine,
``jaxclear.studies._engine.map_members``) steps all its members until the slowest one ends: a
member that needs fewer steps idles in its lane. Here each of ``lanes`` lanes integrates one
member with its own t, y, step size, solver state (the tracked extremes included), controller
state and step counters. Each iteration takes one step in every lane: diffrax's public step API,
vmapped over the lanes (``solver.step``, then the controller's ``adapt_step_size``, then
diffrax's own book-keeping: clipping to t1, keeping or rejecting the step, the result code). When
a lane's member reaches its t1, fails or uses up ``max_steps``, its results are written at the
member's index and the lane loads the next member of the queue (members in the order given); the
loop ends when every member is done.

Two nested loops: the inner one steps every lane until some member is done (its body is the
lockstep loop's, with no branch in it), the outer one writes the finished members out and
refills their lanes (at most once per member). All members' initial states (assembly, the
controller's first step, the solver's initial state) are made before the loop, vmapped over the
members, and a refill copies one in.

The solver, controller, terms and extremes tracker are those ``simulate`` builds for the same
mechanism and ``SolverConfig`` (``SolverConfig.make_solver``/``make_controller``, the vector field
and observation of ``jaxclear.solve._simulate``, ``ExtremesTracking``), and each lane repeats the
steps of diffrax's ``diffeqsolve`` loop (diffrax/_integrate.py ``loop``, ``body_fun_aux``), so a
member's steps are the ones its own ``simulate`` takes (tests/test_lanes.py measures how equal).

Not in this prototype: saved output points (``ts``; only y(t1) comes back, with the extremes of
the solver's steps), differentiation, the split over several devices, the compilation store
(``stored_jit``), solvers with a jump or step schedule (the PID controller here has none).
"""

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ..dynamics._assembly import assemble_state
from ..dynamics._equations import memory_offset_shift
from ..model import Mechanism, parameter_info, with_parameters
from ._extremes import Extremes, ExtremesTracking, Tracker
from ._observables import ASSEMBLY_TOLERANCE, input_error
from ._simulate import _DECAY, _FIELD, _FULL, _OBSERVE, _STAGE, initial_state
from ._solver import SolverConfig, solver_config

DEFAULT_LANES = 8
"""Lanes of the loop (members solved at once). On one CPU core a lane-step costs the same at 8
and 32 lanes, and fewer lanes leave a shorter tail: 8 lanes solved more members per second than
32 (benchmarks/lane_refill.py, case a, 128 members: 9.5 against 8.1 members/s). A GPU wants far
more lanes."""

DIFFEQSOLVE_FIRST_STEP = 0.01
"""First step, s, of a ``simulate`` without ``SolverConfig.dt0``: ``diffeqsolve`` wraps the terms
(a ``WrapTerm`` for the time direction), and the PID controller's initial step selection returns
0.01 for terms that are not an ``ODETerm`` (diffrax 0.7.2, _step_size_controller/pid.py
``_select_initial_step``); dtmax and t1 then clip it. The lanes take the same first step, so that
a member's steps are those of its ``simulate``."""

_IDLE = -1
"""Member index of a lane whose queue has run dry."""


class _Lane(eqx.Module):
    """One lane's integration state (a leading lane axis in the loop; a member axis for the
    initial states of all members)."""

    member: Array  # int32, the member this lane integrates (_IDLE: none)
    row: Array  # (p,) the member's parameter values
    start: Array  # statistics window start, s
    t1: Array
    clip_floor: Array  # t1 less 100 ulp: diffrax rounds a step ending above it to t1
    tprev: Array
    tnext: Array
    y: Array
    solver_state: Any
    controller_state: Any  # the PID controller's (1/error, previous 1/error, at dtmin)
    result: diffrax.RESULTS
    num_steps: Array
    num_accepted_steps: Array
    num_rejected_steps: Array


class MemberSolutions(eqx.Module):
    """What ``solve_members`` returns: one entry per member (leading axis N).

    Attributes:
        y_final: (N, state) the state at t_final (the impact memory in its absolute form, as
            ``Trajectory.y_final``).
        t_final: (N,) where each solve ended, s (t1 unless it failed).
        result: (N,) diffrax result codes (``diffrax.RESULTS``; 0 is success).
        input_error: (N,) ``InputCheck`` codes of the input checks (0: passed).
        num_steps, num_accepted_steps, num_rejected_steps: (N,) solver steps.
        extremes: the ``Extremes`` over each member's accepted steps (leading axis N), as
            ``Trajectory.extremes``; ``None`` without ``extremes``.
        iterations: loop iterations (steps taken by each lane, idle ones included): the lanes'
            use is ``num_steps.sum() / (iterations * lanes)``.
        lanes: lanes of the loop.
    """

    y_final: Array
    t_final: Array
    result: Array
    input_error: Array
    num_steps: Array
    num_accepted_steps: Array
    num_rejected_steps: Array
    extremes: Extremes | None
    iterations: Array
    lanes: int = eqx.field(static=True)

    @property
    def succeeded(self) -> Array:
        """(N,) True where the solve reached t1 and the input checks passed."""
        return (self.result == 0) & (self.input_error == 0)

    @property
    def lane_use(self) -> Array:
        """Share of the lanes' steps that advanced a member (1: no lane ever idled)."""
        return jnp.sum(self.num_steps) / (self.iterations * self.lanes)


def _where(mask, a, b):
    """``a`` where ``mask`` (one flag per row of the leading axis), else ``b``, leaf by leaf."""

    def pick(x, y):
        m = jnp.reshape(mask, mask.shape + (1,) * (jnp.ndim(x) - mask.ndim))
        return jnp.where(m, x, y)

    return jax.tree_util.tree_map(pick, a, b)


def _clip_floor(t1):
    """t1 less 100 ulp (diffrax/_integrate.py ``loop``, ``t1_clip_floor``)."""
    floor = t1
    for _ in range(100):
        floor = jnp.where(floor == 0, -jnp.finfo(floor.dtype).tiny, jnp.nextafter(floor, -jnp.inf))
    return floor


class _Program(eqx.Module):
    """The pieces of one solve, as ``simulate`` (``_simulate_core``) builds them."""

    mechanism: Mechanism
    names: tuple[str, ...] = eqx.field(static=True)
    config: SolverConfig = eqx.field(static=True)
    track: bool = eqx.field(static=True)
    max_events: int = eqx.field(static=True)

    @property
    def offset(self) -> bool:
        return self.config.exponential and bool(np.any(self.mechanism.memory_rows))

    @property
    def terms(self):
        return diffrax.ODETerm(_FULL)

    def member(self, row) -> Mechanism:
        return with_parameters(self.mechanism, {n: row[k] for k, n in enumerate(self.names)})

    def args(self, m: Mechanism) -> Mechanism:
        """The mechanism the vector field sees (the impact memory in offset form for exponential
        methods)."""
        return m.with_memory_offset() if self.offset else m

    def solver(self, m: Mechanism, start):
        inner = self.config.make_solver(
            num_explicit=2 * m.num_coordinates,
            decay=_DECAY,
            memory_rows=m.memory_rows,
            stage=_STAGE,
        )
        if not self.track:
            return inner
        return ExtremesTracking(inner, _OBSERVE, start, self.max_events, field=_FIELD)

    def controller(self, m: Mechanism):
        return self.config.make_controller(memory_rows=m.memory_rows if self.offset else None)

    def initial(self, row, t0, t1, start, y0):
        """A member's lane at t0 and its input-check code (``diffeqsolve``'s initialisation)."""
        m = self.member(row)
        if y0 is None:
            q0, qd0, residual, _ = assemble_state(m, t0)
            assembled = residual < ASSEMBLY_TOLERANCE
            y0 = initial_state(m, q0, qd0)
        else:
            assembled = jnp.asarray(True)
        error = input_error(m, y0, assembled)
        y = y0 - memory_offset_shift(m, y0) if self.offset else y0
        args, solver = self.args(m), self.solver(m, start)
        terms = self.terms
        dt0 = jnp.asarray(
            DIFFEQSOLVE_FIRST_STEP if self.config.dt0 is None else self.config.dt0, dtype=float
        )
        tnext, controller_state = self.controller(m).init(
            terms, t0, t1, y, dt0, args, solver.func, solver.error_order(terms)
        )
        tnext = jnp.minimum(tnext, t1)
        controller_state = jax.tree_util.tree_map(jnp.asarray, controller_state)
        lane = _Lane(
            member=jnp.asarray(_IDLE, dtype=jnp.int32),
            row=row,
            start=start,
            t1=t1,
            clip_floor=_clip_floor(t1),
            tprev=t0,
            tnext=tnext,
            y=y,
            solver_state=solver.init(terms, t0, tnext, y, args),
            controller_state=controller_state,
            result=diffrax.RESULTS.successful,
            num_steps=jnp.asarray(0, dtype=jnp.int32),
            num_accepted_steps=jnp.asarray(0, dtype=jnp.int32),
            num_rejected_steps=jnp.asarray(0, dtype=jnp.int32),
        )
        return lane, error

    def running(self, lane: _Lane):
        """Whether diffrax's loop would take another step (``cond_fun`` and ``max_steps``)."""
        return (
            (lane.member != _IDLE)
            & (lane.tprev < lane.t1)
            & (lane.result == diffrax.RESULTS.successful)
            & (lane.num_steps < self.config.max_steps)
        )

    def advance(self, lane: _Lane) -> _Lane:
        """One step of one lane: diffrax's ``body_fun_aux`` without saving, events or progress."""
        m = self.member(lane.row)
        args, solver, controller = self.args(m), self.solver(m, lane.start), self.controller(m)
        terms = self.terms
        y, y_error, _, solver_state, solver_result = solver.step(
            terms, lane.tprev, lane.tnext, lane.y, args, lane.solver_state, False
        )
        y_error = jax.tree_util.tree_map(lambda x: jnp.where(jnp.isnan(x), jnp.inf, x), y_error)
        keep_step, tprev, tnext, _, controller_state, controller_result = (
            controller.adapt_step_size(
                lane.tprev,
                lane.tnext,
                lane.y,
                y,
                args,
                y_error,
                solver.error_order(terms),  # pyright: ignore[reportArgumentType]
                lane.controller_state,
            )
        )
        tprev = jnp.minimum(tprev, lane.t1)
        clip = tnext > lane.clip_floor
        tnext = jnp.where(
            clip, jnp.where(keep_step, lane.t1, tprev + 0.5 * (lane.t1 - tprev)), tnext
        )
        keep = lambda a, b: jnp.where(keep_step, a, b)  # noqa: E731
        y = keep(y, lane.y)
        solver_state = jax.tree_util.tree_map(keep, solver_state, lane.solver_state)
        solver_result = diffrax.RESULTS.where(keep_step, solver_result, diffrax.RESULTS.successful)
        okay = lambda r: (r == diffrax.RESULTS.successful) | (r == diffrax.RESULTS.event_occurred)  # noqa: E731
        result = diffrax.RESULTS.where(okay(lane.result), solver_result, lane.result)
        result = diffrax.RESULTS.where(okay(result), controller_result, result)
        stepped = dataclasses.replace(
            lane,
            tprev=tprev,
            tnext=tnext,
            y=y,
            solver_state=solver_state,
            controller_state=jax.tree_util.tree_map(jnp.asarray, controller_state),
            result=result,
            num_steps=lane.num_steps + 1,
            num_accepted_steps=lane.num_accepted_steps + jnp.where(keep_step, 1, 0),
            num_rejected_steps=lane.num_rejected_steps + jnp.where(keep_step, 0, 1),
        )
        return _where(self.running(lane), stepped, lane)

    def final(self, lane: _Lane):
        """A finished lane's outputs (diffrax's final result code; y in absolute form)."""
        y = lane.y
        if self.offset:
            y = y + memory_offset_shift(self.member(lane.row), y)
        unfinished = (lane.tprev < lane.t1) & (lane.result == diffrax.RESULTS.successful)
        result = diffrax.RESULTS.where(unfinished, diffrax.RESULTS.max_steps_reached, lane.result)
        out = {
            "y_final": y,
            "t_final": lane.tprev,
            "result": result._value,  # pyright: ignore[reportAttributeAccessIssue]
            "num_steps": lane.num_steps,
            "num_accepted_steps": lane.num_accepted_steps,
            "num_rejected_steps": lane.num_rejected_steps,
        }
        if self.track:
            out["tracker"] = lane.solver_state[1]  # pyright: ignore[reportIndexIssue]
        return out


@eqx.filter_jit
def _solve_lanes(program: _Program, rows, t0, t1, start, y0, lanes: int):
    """The loop: all members' initial lanes, then steps with refills until every member is done."""
    n = rows.shape[0]
    initial, errors = jax.vmap(program.initial, in_axes=(0, None, 0, 0, None if y0 is None else 0))(
        rows, t0, t1, start, y0
    )
    first = jnp.arange(lanes)
    lane = jax.tree_util.tree_map(lambda x: x[jnp.minimum(first, n - 1)], initial)
    lane = dataclasses.replace(lane, member=jnp.where(first < n, first, _IDLE).astype(jnp.int32))
    shapes = jax.eval_shape(jax.vmap(program.final), lane)
    out = jax.tree_util.tree_map(lambda s: jnp.zeros((n,) + s.shape[1:], s.dtype), shapes)

    def refill(carry):
        """Write the finished lanes' members out; load the next members of the queue."""
        lane, out, queue, count = carry
        done = finished(lane)
        at = jnp.where(done, lane.member, n)  # n: out of range, dropped
        out = jax.tree_util.tree_map(
            lambda o, v: o.at[at].set(v, mode="drop"), out, jax.vmap(program.final)(lane)
        )
        member = queue + jnp.cumsum(done) - 1
        load = done & (member < n)
        fresh = jax.tree_util.tree_map(lambda x: x[jnp.clip(member, 0, n - 1)], initial)
        lane = _where(load, fresh, lane)
        member = jnp.where(load, member, jnp.where(done, _IDLE, lane.member))
        lane = dataclasses.replace(lane, member=member.astype(jnp.int32))
        return lane, out, (queue + jnp.sum(done)).astype(jnp.int32), count

    def finished(lane):
        """Lanes whose member is done (reached t1, failed or ran out of steps)."""
        return (lane.member != _IDLE) & ~jax.vmap(program.running)(lane)

    def stepping(inner):
        lane, _ = inner
        return jnp.any(jax.vmap(program.running)(lane)) & ~jnp.any(finished(lane))

    def step(inner):
        lane, count = inner
        return jax.vmap(program.advance)(lane), count + 1

    def rounds(carry):
        """Step every lane until one member is done (an inner loop like the lockstep loop: no
        branch in its body), then write it out and refill its lane."""
        lane, out, queue, count = carry
        lane, count = jax.lax.while_loop(stepping, step, (lane, count))
        return refill((lane, out, queue, count))

    def busy(carry):
        return jnp.any(carry[0].member != _IDLE)

    start_queue = jnp.asarray(min(lanes, n), dtype=jnp.int32)
    carry = (lane, out, start_queue, jnp.asarray(0, dtype=jnp.int32))
    _, out, _, count = jax.lax.while_loop(busy, rounds, carry)
    if program.track:  # per member, as a vmapped simulate builds them
        out["extremes"] = jax.vmap(Tracker.extremes)(out.pop("tracker"))
    return out, errors, count


def _per_member(x, n: int, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(
            f"{what} must be a finite number or a finite (N,) array with one value per member "
            f"(N = {n}); got shape {a.shape}."
        )
    return a


def solve_members(
    mechanism: Mechanism,
    values: Mapping[str, Any],
    t1: "ArrayLike | Sequence[float]",
    *,
    t0: float = 0.0,
    solver: "str | SolverConfig" = "auto",
    lanes: int = DEFAULT_LANES,
    statistics_start: "ArrayLike | Sequence[float] | None" = None,
    y0: ArrayLike | None = None,
    extremes: bool = True,
    contact_events: int = 0,
) -> MemberSolutions:
    """Solve N members of one mechanism on ``lanes`` refilled lanes (module doc).

    Member i is ``with_parameters(mechanism, {name: values[name][i]})``, as in
    ``jaxclear.studies.run_ensemble``; its solve is the one ``simulate(member_i, t1[i], t0=t0,
    solver=solver, statistics_start=statistics_start[i], extremes=extremes,
    contact_events=contact_events)`` makes, without the saved output points. Compiled once per
    mechanism topology, parameter names, N, lanes and solver settings: new values, end times and
    statistics windows reuse the program. Failures are data (``result``, ``input_error``): nothing
    is raised on values.

    Args:
        mechanism: the base mechanism (``Mechanism``).
        values: ``{name: (N,) values}`` of parameters (``jaxclear.parameter_names``).
        t1: end time, s: one for all members, or (N,) one per member (each > t0).
        t0: start time, s (all members).
        solver: as in ``simulate`` (``"auto"``, a preset, a method or a ``SolverConfig``).
        lanes: members integrated at once (the loop's vector width); more lanes than members
            leave the rest idle. Members are taken in the order given: where their costs are
            known, longest first leaves the shortest tail (benchmarks/lane_refill.py,
            "lanes-lpt").
        statistics_start: start of each member's extremes window, s (default t0): a number or
            (N,) values.
        y0: (N, state) initial states. Default: each member assembled at t0 inside the
            compiled solve, as a vmapped ``simulate`` does (an eager ``simulate`` assembles on
            the host, ``jaxclear.solve.assemble``: pass those states for the same start).
        extremes: track each member's ``Extremes`` (as ``simulate``'s ``extremes``).
        contact_events: room for contact events per clearance joint (as ``simulate``'s).

    Returns:
        ``MemberSolutions``: y(t_final), result codes, step counts and extremes per member.

    Raises:
        ValueError: bad arguments (naming the argument and what is allowed).
        ModelError: an unknown parameter name.
    """
    if not values:
        raise ValueError("values is empty: give at least one parameter, {name: (N,) values}.")
    names = tuple(values)
    for name in names:
        parameter_info(mechanism, name)  # ModelError naming the closest valid name
    columns = [np.atleast_1d(np.asarray(values[name], dtype=float)) for name in names]
    if len({c.shape for c in columns}) != 1 or columns[0].ndim != 1 or columns[0].size == 0:
        raise ValueError(
            "values must be non-empty 1-D arrays of one length (one value per member); got "
            + ", ".join(f"{n} {c.shape}" for n, c in zip(names, columns))
            + "."
        )
    rows = np.stack(columns, axis=1)
    n = rows.shape[0]
    if isinstance(lanes, bool) or not isinstance(lanes, int | np.integer) or lanes < 1:
        raise ValueError(f"lanes must be a positive integer (members at once), got {lanes!r}.")
    t0 = float(t0)
    ends = _per_member(t1, n, "t1")
    if np.any(ends <= t0):
        raise ValueError(f"t1 must be greater than t0 = {t0} for every member.")
    start = _per_member(t0 if statistics_start is None else statistics_start, n, "statistics_start")
    if y0 is not None:
        y0 = jnp.asarray(y0, dtype=float)
        if y0.shape != (n, mechanism.state_size):
            raise ValueError(
                f"y0 must have shape (N, state) = ({n}, {mechanism.state_size}), got {y0.shape}."
            )
    events = int(contact_events) if extremes else 0
    if events < 0:
        raise ValueError(f"contact_events must be 0 or more, got {contact_events!r}.")
    program = _Program(
        mechanism=mechanism,
        names=names,
        config=solver_config(solver, mechanism),
        track=bool(extremes),
        max_events=events,
    )
    out, errors, iterations = _solve_lanes(
        program,
        jnp.asarray(rows),
        jnp.asarray(t0),
        jnp.asarray(ends),
        jnp.asarray(start),
        y0,
        int(lanes),
    )
    return MemberSolutions(
        y_final=out["y_final"],
        t_final=out["t_final"],
        result=out["result"],
        input_error=errors,
        num_steps=out["num_steps"],
        num_accepted_steps=out["num_accepted_steps"],
        num_rejected_steps=out["num_rejected_steps"],
        extremes=out.get("extremes"),
        iterations=iterations,
        lanes=int(lanes),
    )
