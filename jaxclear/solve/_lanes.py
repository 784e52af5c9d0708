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

Saved output points (``ts``): each accepted step fills the grid points in (t_prev, t_new] of
its lane's member from the step's dense output (``solver.interpolation_cls`` built from the
``dense_info`` that ``solver.step`` returns), as ``diffeqsolve`` with ``SaveAt(ts=...)`` does
(diffrax/_integrate.py ``body_fun_aux``, ``save_ts_impl``): an inner loop that runs while some
lane has a point left in its step, and writes the points straight into the (N, T, state) output
at the member's row (no per-lane buffer to copy out at a refill). ``MemberSolutions.trajectories``
then gives every member's ``Trajectory`` as ``simulate`` returns it.

Not here: differentiation, the split over several devices (``run_ensemble`` splits its chunks),
the compilation store (``stored_jit``), solvers with a jump or step schedule (the PID controller
here has none).
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
from ._observables import ASSEMBLY_TOLERANCE, input_error, make_trajectory
from ._simulate import _DECAY, _FIELD, _FULL, _OBSERVE, _STAGE, initial_state
from ._solver import SolverConfig, solver_config
from ._startup import ideal_mechanism
from ._trajectory import Trajectory

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
    save_index: Array  # int32, the member's next output point (ts)


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
        ts: (N, T) each member's output times, s (the grid given as ``ts``, clipped to the
            member's t1); ``None`` without ``ts``.
        ys: (N, T, state) the states at ``ts`` (the impact memory in its absolute form, as
            ``Trajectory``'s); a point after a failed member's ``t_final`` is not finite, as in
            ``simulate``. ``None`` without ``ts``.
        program: how the members were solved (the base mechanism, parameter names and solver
            settings; internal).
        rows: (N, p) each member's parameter values, in the order of ``program.names``.
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
    ts: Array | None
    ys: Array | None
    program: "_Program"
    rows: Array
    lanes: int = eqx.field(static=True)

    @property
    def succeeded(self) -> Array:
        """(N,) True where the solve reached t1 and the input checks passed."""
        return (self.result == 0) & (self.input_error == 0)

    @property
    def lane_use(self) -> Array:
        """Share of the lanes' steps that advanced a member (1: no lane ever idled)."""
        return jnp.sum(self.num_steps) / (self.iterations * self.lanes)

    def trajectories(self) -> Trajectory:
        """Every member's ``Trajectory`` on its ``ts``, as a batched ``Trajectory`` (leading axis
        N; ``.member(i)`` is member i as ``simulate`` returns it): the per-instant outputs
        (accelerations, multipliers, torque, clearance outputs, ...) evaluated at the saved
        states, as ``simulate`` evaluates them (``make_trajectory``).

        Raises:
            ValueError: the members were solved without ``ts``.
        """
        if self.ys is None:
            raise ValueError(
                "these members were solved without output points: call solve_members with ts "
                "(the output grid) to get their trajectories."
            )
        return _trajectories(self)

    def trajectory(self, index: int) -> Trajectory:
        """Member ``index``'s ``Trajectory`` (single, unbatched): ``trajectories().member(index)``."""
        return self.trajectories().member(index)


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
    """The pieces of one solve, as ``simulate`` (``_simulate_core``) builds them. With ``ideal``,
    each member's ``ideal_mechanism`` is solved (its clearance joints made ideal joints)."""

    mechanism: Mechanism
    names: tuple[str, ...] = eqx.field(static=True)
    config: SolverConfig = eqx.field(static=True)
    track: bool = eqx.field(static=True)
    max_events: int = eqx.field(static=True)
    ideal: bool = eqx.field(static=True, default=False)

    @property
    def solved(self) -> Mechanism:
        """The mechanism whose topology is solved (the base one, or its ideal mechanism)."""
        return ideal_mechanism(self.mechanism) if self.ideal else self.mechanism

    @property
    def offset(self) -> bool:
        return self.config.exponential and bool(np.any(self.solved.memory_rows))

    @property
    def terms(self):
        return diffrax.ODETerm(_FULL)

    @property
    def interpolation_cls(self):
        """The dense output's class (``solver.interpolation_cls``, as ``diffeqsolve`` builds it
        from a step's ``dense_info``)."""
        return self.solver(self.solved, jnp.asarray(0.0)).interpolation_cls

    def member(self, row) -> Mechanism:
        m = with_parameters(self.mechanism, {n: row[k] for k, n in enumerate(self.names)})
        return ideal_mechanism(m) if self.ideal else m

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
            save_index=jnp.asarray(0, dtype=jnp.int32),
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

    def advance(self, lane: _Lane):
        """One step of one lane: diffrax's ``body_fun_aux`` without saving, events or progress.

        Returns:
            The lane after the step, and what saving needs: the step's start and end, its
            ``dense_info`` and whether it was taken and accepted (``keep_step`` of a running
            lane)."""
        m = self.member(lane.row)
        args, solver, controller = self.args(m), self.solver(m, lane.start), self.controller(m)
        terms = self.terms
        y, y_error, dense_info, solver_state, solver_result = solver.step(
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
        running = self.running(lane)
        saving = (lane.tprev, lane.tnext, dense_info, running & keep_step)
        return _where(running, stepped, lane), saving

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


def _fill(program: _Program, ts, lane: _Lane, ys, saving):
    """Save the output points each lane's step has passed: the points in (t_prev, t_new] of an
    accepted step, from its dense output, as ``diffeqsolve``'s ``save_ts_impl`` does (the point
    ``ts[i]``, clipped to the member's t1, is saved while it is at most the step's end), written
    at the member's row of ``ys`` (N, T, state). A bounded loop: it runs while some lane has a
    point left in its step (at most T times)."""
    t_start, t_end, dense_info, keep = saving
    # the dense output's static parts (LawsonInterpolation's decay rows) stay out of the vmap
    dynamic, static = eqx.partition(dense_info, eqx.is_array)
    size, n = ts.shape[-1], ys.shape[0]
    interpolation = program.interpolation_cls

    def point(index):
        index = jnp.minimum(index, size - 1)
        if ts.ndim == 1:  # one grid for all members
            return jnp.minimum(ts[index], lane.t1)
        return jnp.minimum(ts[jnp.clip(lane.member, 0, ts.shape[0] - 1), index], lane.t1)

    def pending(index):
        return keep & (index < size) & (point(index) <= t_end)

    def cond(carry):
        return jnp.any(pending(carry[0]))

    def body(carry):
        index, ys = carry
        due = pending(index)
        y = jax.vmap(
            lambda a, b, info, t: interpolation(t0=a, t1=b, **eqx.combine(info, static)).evaluate(t)
        )(t_start, t_end, dynamic, point(index))
        at = (jnp.where(due, lane.member, n), jnp.minimum(index, size - 1))  # n: dropped
        return index + due.astype(index.dtype), ys.at[at].set(y, mode="drop")

    index, ys = jax.lax.while_loop(cond, body, (lane.save_index, ys))
    return dataclasses.replace(lane, save_index=index), ys


def _solve_lanes(program: _Program, rows, t0, t1, start, y0, lanes: int, ts=None, active=None):
    """The loop: all members' initial lanes, then steps with refills until every member is done.

    With ``ts`` ((T,) output times, or (N, T): each member's own), also the states there,
    (N, T, state). With ``active`` (a
    traced count), only the first ``active`` members are solved; the others are left as zeros
    (their rows pad a batch to a fixed shape, ``run_ensemble``'s refilled chunks)."""
    n = rows.shape[0]
    active = jnp.asarray(n if active is None else active, dtype=jnp.int32)
    initial, errors = jax.vmap(program.initial, in_axes=(0, None, 0, 0, None if y0 is None else 0))(
        rows, t0, t1, start, y0
    )
    first = jnp.arange(lanes)
    lane = jax.tree_util.tree_map(lambda x: x[jnp.minimum(first, n - 1)], initial)
    lane = dataclasses.replace(
        lane, member=jnp.where(first < active, first, _IDLE).astype(jnp.int32)
    )
    shapes = jax.eval_shape(jax.vmap(program.final), lane)
    out = jax.tree_util.tree_map(lambda s: jnp.zeros((n,) + s.shape[1:], s.dtype), shapes)
    if ts is not None:
        ys = jnp.full((n, ts.shape[-1]) + initial.y.shape[1:], jnp.inf, dtype=initial.y.dtype)
    else:
        ys = None

    def refill(carry):
        """Write the finished lanes' members out; load the next members of the queue."""
        lane, out, ys, queue, count = carry
        done = finished(lane)
        at = jnp.where(done, lane.member, n)  # n: out of range, dropped
        out = jax.tree_util.tree_map(
            lambda o, v: o.at[at].set(v, mode="drop"), out, jax.vmap(program.final)(lane)
        )
        member = queue + jnp.cumsum(done) - 1
        load = done & (member < active)
        fresh = jax.tree_util.tree_map(lambda x: x[jnp.clip(member, 0, n - 1)], initial)
        lane = _where(load, fresh, lane)
        member = jnp.where(load, member, jnp.where(done, _IDLE, lane.member))
        lane = dataclasses.replace(lane, member=member.astype(jnp.int32))
        return lane, out, ys, (queue + jnp.sum(done)).astype(jnp.int32), count

    def finished(lane):
        """Lanes whose member is done (reached t1, failed or ran out of steps)."""
        return (lane.member != _IDLE) & ~jax.vmap(program.running)(lane)

    def stepping(inner):
        lane = inner[0]
        return jnp.any(jax.vmap(program.running)(lane)) & ~jnp.any(finished(lane))

    def step(inner):
        lane, ys, count = inner
        # filter_vmap: the dense output's static parts come back as they are, not as arrays
        lane, saving = eqx.filter_vmap(program.advance)(lane)
        if ys is not None:
            lane, ys = _fill(program, ts, lane, ys, saving)
        return lane, ys, count + 1

    def rounds(carry):
        """Step every lane until one member is done (an inner loop like the lockstep loop: no
        branch in its body), then write it out and refill its lane."""
        lane, out, ys, queue, count = carry
        lane, ys, count = jax.lax.while_loop(stepping, step, (lane, ys, count))
        return refill((lane, out, ys, queue, count))

    def busy(carry):
        return jnp.any(carry[0].member != _IDLE)

    start_queue = jnp.minimum(jnp.asarray(lanes, dtype=jnp.int32), active)
    carry = (lane, out, ys, start_queue, jnp.asarray(0, dtype=jnp.int32))
    _, out, ys, _, count = jax.lax.while_loop(busy, rounds, carry)
    if program.track:  # per member, as a vmapped simulate builds them
        out["extremes"] = jax.vmap(Tracker.extremes)(out.pop("tracker"))
    if ts is not None and ys is not None:
        ts_members = jnp.minimum(ts if ts.ndim == 2 else ts[None, :], t1[:, None])
        if program.offset:  # back to the absolute impact memory, as _simulate_core converts
            shift = jax.vmap(
                lambda row, y: jax.vmap(lambda x: memory_offset_shift(program.member(row), x))(y)
            )(rows, ys)
            ys = ys + shift
        out["ts"], out["ys"] = ts_members, ys
    return out, errors, count


def members_solution(
    program: _Program, rows, t0, t1, start, y0, lanes: int, ts=None, active=None
) -> MemberSolutions:
    """``_solve_lanes`` as a ``MemberSolutions`` (traceable: call it inside a jit)."""
    out, errors, iterations = _solve_lanes(program, rows, t0, t1, start, y0, lanes, ts, active)
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
        ts=out.get("ts"),
        ys=out.get("ys"),
        program=program,
        rows=rows,
        lanes=int(lanes),
    )


_members_solution = eqx.filter_jit(members_solution)


def _result_item(code) -> diffrax.RESULTS:
    """A ``diffrax.RESULTS`` item holding the result code ``code`` (an int array)."""
    success = diffrax.RESULTS.successful
    value = jnp.asarray(code).astype(jnp.asarray(success._value).dtype)  # pyright: ignore[reportAttributeAccessIssue]
    return eqx.tree_at(lambda r: r._value, success, value)


def batched_trajectories(solution: MemberSolutions) -> Trajectory:
    """Every member's ``Trajectory`` (leading axis N), traceable: ``make_trajectory`` of each
    member, vmapped."""
    program = solution.program

    def one(row, ts, ys, y_final, extremes, steps, accepted, rejected, result, error, t_final):
        stats = {
            "num_steps": steps,
            "num_accepted_steps": accepted,
            "num_rejected_steps": rejected,
        }
        return make_trajectory(
            program.member(row),
            ts,
            ys,
            y_final,
            extremes,
            stats,
            _result_item(result),
            error,
            t_final,
        )

    return jax.vmap(one)(
        solution.rows,
        solution.ts,
        solution.ys,
        solution.y_final,
        solution.extremes,
        solution.num_steps,
        solution.num_accepted_steps,
        solution.num_rejected_steps,
        solution.result,
        solution.input_error,
        solution.t_final,
    )


_trajectories = eqx.filter_jit(batched_trajectories)


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
    ts: "ArrayLike | Sequence[float] | None" = None,
    ideal: bool = False,
) -> MemberSolutions:
    """Solve N members of one mechanism on ``lanes`` refilled lanes (module doc).

    Member i is ``with_parameters(mechanism, {name: values[name][i]})``, as in
    ``jaxclear.studies.run_ensemble``; its solve is the one ``simulate(member_i, t1[i], t0=t0,
    solver=solver, statistics_start=statistics_start[i], extremes=extremes,
    contact_events=contact_events, ts=jnp.minimum(ts, t1[i]))`` makes (with ``ts``: its saved
    states too; without: y(t1) only). Compiled once per mechanism topology, parameter names, N,
    lanes, number of output points and solver settings: new values, end times, output times and
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
        ts: output times (increasing, from t0 on), s: (T,) shared by all members, or (N, T),
            one row per member (e.g. each member's Poincaré section instants, which depend on its
            crank speed); a time after a member's t1 is clipped to it. Each member's states
            there come from its solver's dense output, as ``simulate``'s (``MemberSolutions.ys``, ``.trajectories()``).
            ``None`` (default): no output points.
        ideal: solve each member's ideal mechanism instead (``jaxclear.ideal_mechanism`` of
            the member: its clearance joints made ideal joints), as ``run_ensemble`` does for
            the deviations from the ideal mechanism.

    Returns:
        ``MemberSolutions``: y(t_final), result codes, step counts and extremes per member, and
        with ``ts`` the states there and the members' trajectories.

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
    solved = ideal_mechanism(mechanism) if ideal else mechanism
    if y0 is not None:
        y0 = jnp.asarray(y0, dtype=float)
        if y0.shape != (n, solved.state_size):
            raise ValueError(
                f"y0 must have shape (N, state) = ({n}, {solved.state_size}), got {y0.shape}."
            )
    events = int(contact_events) if extremes else 0
    if events < 0:
        raise ValueError(f"contact_events must be 0 or more, got {contact_events!r}.")
    if ts is not None:
        ts = np.asarray(ts, dtype=float)
        if (
            ts.ndim not in (1, 2)
            or (ts.ndim == 2 and ts.shape[0] != n)
            or ts.size < 1
            or not np.all(np.isfinite(ts))
            or np.any(np.diff(ts, axis=-1) < 0)
            or np.any(ts[..., 0] < t0)
        ):
            raise ValueError(
                f"ts must be a non-empty (T,) array, or (N, T) with one row per member (N = {n}), "
                f"of finite, increasing output times from t0 = {t0} on (a time after a member's "
                f"t1 is clipped to it); got shape {ts.shape}."
            )
        ts = jnp.asarray(ts)
    program = _Program(
        mechanism=mechanism,
        names=names,
        config=solver_config(solver, solved),
        track=bool(extremes),
        max_events=events,
        ideal=bool(ideal),
    )
    return _members_solution(
        program,
        jnp.asarray(rows),
        jnp.asarray(t0),
        jnp.asarray(ends),
        jnp.asarray(start),
        y0,
        int(lanes),
        ts,
    )
