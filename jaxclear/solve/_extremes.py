"""Extremes and integrals over the solver's steps, not over the saved output grid.

A contact force peak lasts microseconds; a saved grid of a few hundred points per revolution
samples it at random phases, so a peak read from the grid moves with the number of points (the
peak normal force of joint A of the default run read 38.7 kN with 721 points and 50.6–51.8 kN
with 1441–5001 points, same solver steps). ``ExtremesTracking`` wraps a diffrax solver and
updates running extremes at the end of every accepted step, where the solver has resolved the
solution to its tolerance (diffrax keeps the solver state of accepted steps only,
diffrax/_integrate.py ``keep``). An impact is resolved by many steps (contact durations of tens
of µs against steps of ~1 µs in contact).

Each step is sampled at its midpoint (from the step's dense output) and its end, and between
samples the extremum of a smooth signal is estimated by the vertex of the parabola through three
consecutive samples when the middle one is a local extremum (peak interpolation). Without these
the step ends of a smooth run miss peaks by a lot: on the ideal slider–crank at 5000 rpm Tsit5
takes 29 steps per revolution (12° of crank angle), and the input-torque minimum read
−130.6 N m from the step ends, −137.1 N m with the parabola, against −138.52 N m
(tests/test_statistics.py).

With Tsit5 (``auto``'s and ``fast``'s method), Lawson–Tsit5 and jaxclear's IMEX KenCarp
(``AffineKenCarp``) the samples cost no evaluation of the model: the observations ride along the
solver's own stages (``ExtremesTracking``, ``RIDING_SOLVERS``). The end sample is the observation
at (t1, y1): Tsit5's last stage, or KenCarp's explicit first stage of the next step (one sample
late; the solve's very last end sample is KenCarp's last stage, at (t1, Y_s), within ~1e-3). The
midpoint sample is the derivative of the observations' dense output, within ~1e-4 (Tsit5) to
~2e-4 (KenCarp4) of the observation at the interpolated state (tests/test_extremes_sampling.py).
Other methods evaluate the observation at both samples.

The mean squares of the input torque and of each body's acceleration are integrated by the
trapezoidal rule over the same steps.

Contact events (optional, ``max_events > 0``): each clearance joint's contact onsets and ends,
located where the penetration δ changes sign between two consecutive samples (step midpoints and
ends) by linear interpolation of δ, are written into a fixed-size buffer. Contact modes and their
time shares then come from these events, not from the saved grid (``jaxclear.analysis.contact_events``).
"""

import dataclasses
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core._smooth import safe_norm
from ._imex import TABLEAUS, AffineKenCarp
from ._lawson import LawsonTsit5


class Observation(eqx.Module):
    """Quantities observed at one instant (built by ``jaxclear.solve._simulate``).

    Attributes:
        accelerations: q̈ (n,), m/s² and rad/s².
        body_accelerations: |r̈| of each body's centre of mass (bodies,), m/s².
        input_torque: driver torque, N m (zero without a driver).
        normal_force: {clearance joint: normal contact force F_N, N}.
        penetration: {clearance joint: penetration δ = e − c, m} (negative in free flight).
        constraint_violation: max |Φ|, m or rad.
    """

    accelerations: Float[Array, " n"]
    body_accelerations: Float[Array, " b"]
    input_torque: Float[Array, ""]
    normal_force: dict[str, Float[Array, ""]]
    penetration: dict[str, Float[Array, ""]]
    constraint_violation: Float[Array, ""]


class Extremes(eqx.Module):
    """Extremes and integrals over the solver's accepted steps with t ≥ ``start``.

    A batched run adds a leading batch axis to every array. Before any step falls in the window
    the maxima are −inf, the minima +inf and ``duration`` 0.

    Attributes:
        start: start of the statistics window, s.
        duration: time covered by the window so far, s.
        acceleration_min, acceleration_max: per coordinate, q̈ extremes (n,), m/s² and rad/s².
        body_acceleration_max: per body, peak |r̈| of its centre of mass (bodies,), m/s².
        input_torque_min, input_torque_max: driver torque extremes, N m.
        input_torque_square_integral: ∫ τ² dt over the window (trapezoidal rule over the steps), N² m² s.
        body_acceleration_square_integral: per body, ∫ |r̈|² dt over the window (same rule),
            m² s⁻³.
        normal_force_max: {clearance joint: peak F_N, N}.
        penetration_max: {clearance joint: peak δ, m}.
        constraint_violation_max: peak max |Φ|, m or rad.
        times, recent: the last two accepted step ends and the observations there (for the
            trapezoidal rule and the peak interpolation).
        contact_onset: {clearance joint: onset time of the contact in progress, s; nan in free
            flight}.
        events: {clearance joint: (max_events, 2) onset and end times of finished contacts, s,
            in order; unused rows nan}.
        event_count: {clearance joint: contacts finished so far (more than ``max_events`` means
            the buffer overflowed: the later ones are counted, not stored)}.
    """

    start: Float[Array, ""]
    duration: Float[Array, ""]
    acceleration_min: Float[Array, " n"]
    acceleration_max: Float[Array, " n"]
    body_acceleration_max: Float[Array, " b"]
    input_torque_min: Float[Array, ""]
    input_torque_max: Float[Array, ""]
    input_torque_square_integral: Float[Array, ""]
    body_acceleration_square_integral: Float[Array, " b"]
    normal_force_max: dict[str, Float[Array, ""]]
    penetration_max: dict[str, Float[Array, ""]]
    constraint_violation_max: Float[Array, ""]
    times: Float[Array, " 2"]
    recent: tuple[Observation, Observation]
    contact_onset: dict[str, Float[Array, ""]]
    events: dict[str, Float[Array, "k 2"]]
    event_count: dict[str, Array]

    @property
    def input_torque_rms(self) -> Float[Array, "*batch"]:
        """RMS of the driver torque over the window, N m (nan if the window is empty)."""
        return jnp.sqrt(self.input_torque_square_integral / self.duration)

    @property
    def body_acceleration_rms(self) -> Float[Array, "*batch b"]:
        """RMS of each body's centre-of-mass acceleration magnitude over the window, m/s²."""
        return jnp.sqrt(self.body_acceleration_square_integral / self.duration[..., None])


def body_accelerations(qdd):
    """|r̈| of each body's centre of mass from q̈ = (ẍ, ÿ, θ̈) per body."""
    return safe_norm(jnp.reshape(qdd, (-1, 3))[:, :2], axis=-1)


def body_accelerations_rows(qdd):
    """``body_accelerations`` of each row of ``qdd`` (rows, n)."""
    return safe_norm(jnp.reshape(qdd, (qdd.shape[0], -1, 3))[..., :2], axis=-1)


class _Layout(eqx.Module):
    """Where each observed quantity sits in the flat vector a ``Tracker`` works on:
    [q̈ (n), |r̈| per body (b), τ, F_N per joint (J), δ per joint (J), max |Φ|]."""

    n: int = eqx.field(static=True)
    b: int = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    @classmethod
    def of(cls, obs: Observation) -> "_Layout":
        return cls(
            n=obs.accelerations.shape[-1],
            b=obs.body_accelerations.shape[-1],
            names=tuple(obs.penetration),
        )

    @property
    def torque(self) -> int:
        return self.n + self.b

    @property
    def normal_force(self) -> slice:
        return slice(self.torque + 1, self.torque + 1 + len(self.names))

    @property
    def penetration(self) -> slice:
        start = self.torque + 1 + len(self.names)
        return slice(start, start + len(self.names))

    @property
    def squares(self) -> slice:
        """The signals whose mean squares are integrated: the body accelerations, then τ."""
        return slice(self.n, self.torque + 1)

    def flat(self, obs: Observation) -> Float[Array, " k"]:
        parts = [
            obs.accelerations,
            obs.body_accelerations,
            jnp.reshape(obs.input_torque, (1,)),
            *(jnp.reshape(obs.normal_force[k], (1,)) for k in self.names),
            *(jnp.reshape(obs.penetration[k], (1,)) for k in self.names),
            jnp.reshape(obs.constraint_violation, (1,)),
        ]
        return jnp.concatenate([jnp.asarray(p, dtype=float) for p in parts])

    def observation(self, v) -> Observation:
        nf, pen = v[..., self.normal_force], v[..., self.penetration]
        return Observation(
            accelerations=v[..., : self.n],
            body_accelerations=v[..., self.n : self.torque],
            input_torque=v[..., self.torque],
            normal_force={k: nf[..., i] for i, k in enumerate(self.names)},
            penetration={k: pen[..., i] for i, k in enumerate(self.names)},
            constraint_violation=v[..., -1],
        )


class Tracker(eqx.Module):
    """What the solve carries to build ``Extremes``: every observed quantity in one flat vector
    (``_Layout``), so that a step's update is a handful of vector operations.

    Updated per quantity (one small kernel per leaf and operation), the two updates of a step
    cost ~9 µs on the three-joint slider–crank, a quarter of a Tsit5 step (case b of
    ``benchmarks/bench_clearance.py`` on one core: 34.5 µs per step, 25.7 µs with the updates
    replaced by a trivial one in a local copy; 28.0 µs with this tracker). Same arithmetic.
    """

    layout: _Layout
    start: Float[Array, ""]
    duration: Float[Array, ""]
    maximum: Float[Array, " k"]
    minimum: Float[Array, " k"]
    square_integral: Float[Array, " s"]
    times: Float[Array, " 2"]
    recent: Float[Array, "2 k"]
    contact_onset: Float[Array, " j"]
    events: Float[Array, "j e 2"]
    event_count: Array
    pending: tuple | None = None
    """(t, flat observation): a sample not taken in yet, which ``extremes`` takes in; ``None``:
    none. ``ExtremesTracking`` on ``AffineKenCarp`` takes a step's end sample in one step late,
    from the next step's first stage (the observation at (t1, y1)), and leaves an estimate of
    it here for the solve's last step."""

    @classmethod
    def first(cls, start, t, obs: Observation, max_events: int = 0) -> "Tracker":
        layout = _Layout.of(obs)
        v = layout.flat(obs)
        t = jnp.asarray(t, dtype=float)
        inside = t >= start
        joints = len(layout.names)
        return cls(
            layout=layout,
            start=jnp.asarray(start, dtype=float),
            duration=jnp.zeros((), dtype=float),
            maximum=jnp.where(inside, v, -jnp.inf),
            minimum=jnp.where(inside, v, jnp.inf),
            square_integral=jnp.zeros((layout.b + 1,), dtype=float),
            times=jnp.stack([t, t]),
            recent=jnp.stack([v, v]),
            contact_onset=jnp.where(v[layout.penetration] > 0, t, jnp.nan),
            events=jnp.full((joints, max_events, 2), jnp.nan),
            event_count=jnp.zeros((joints,), dtype=jnp.int32),
        )

    def _contact_events(self, t, v):
        """Onsets and ends of contact between the last sample (at ``times[1]``) and ``t``."""
        pen = self.layout.penetration
        t_last = self.times[1]
        before, after = self.recent[1, pen], v[pen]
        crossing = (before > 0) != (after > 0)
        denominator = jnp.where(crossing, before - after, 1.0)
        at = t_last + (t - t_last) * jnp.where(crossing, before / denominator, 1.0)
        starts = (before <= 0) & (after > 0)
        ends = (before > 0) & (after <= 0)
        onset, count, buffer = self.contact_onset, self.event_count, self.events
        size = buffer.shape[-2]
        if size:
            row = jnp.minimum(count, size - 1)
            store = ends & (count < size)
            new = jnp.stack([onset, at], axis=-1)  # (J, 2)
            target = (jnp.arange(size)[None, :] == row[:, None]) & store[:, None]
            buffer = jnp.where(target[:, :, None], new[:, None, :], buffer)
        counts = count + ends.astype(count.dtype)
        onsets = jnp.where(starts, at, jnp.where(ends, jnp.nan, onset))
        return onsets, buffer, counts

    def update(self, t, obs: Observation) -> "Tracker":
        """The tracker after a step ending at ``t`` with observation ``obs`` there."""
        return self.update_flat(t, self.layout.flat(obs))

    def update_pair(self, t_a, v_a, t_b, v_b) -> "Tracker":
        """``update_flat(t_a, v_a).update_flat(t_b, v_b)`` (t_a < t_b: a step's midpoint and
        end), the same values from one pass over both samples (half the kernels of two updates)."""
        return self._update_rows(jnp.stack([t_a, t_b]), jnp.stack([v_a, v_b]))

    def update_flat(self, t, v) -> "Tracker":
        """``update`` with the observation as its flat vector (``_Layout.flat``)."""
        return self._update_rows(jnp.reshape(t, (1,)), v[None])

    def _update_rows(self, ts, vs) -> "Tracker":
        """The tracker after the samples ``vs`` (K, k) at the increasing times ``ts`` (K,), in
        one pass: the K parabola vertices, extremes and trapezoids as arrays over the rows."""
        ts = jnp.asarray(ts, dtype=float)
        # row i: the update at ts[i], after the two samples before it
        times = jnp.concatenate([self.times, ts])
        values = jnp.concatenate([self.recent, vs])
        t_e, t_l, t_n = times[:-2, None], times[1:-1, None], times[2:, None]
        earlier, last, v = values[:-2], values[1:-1], values[2:]
        # the vertex of the parabola through (t_e, earlier), (t_l, last), (t_n, v) where the
        # middle value is a local extremum and lies in the window; else the new value
        spaced = (t_l > t_e) & (t_n > t_l)
        width_0 = jnp.where(spaced, t_l - t_e, 1.0)
        width_1 = jnp.where(spaced, t_n - t_l, 1.0)
        d1 = (last - earlier) / width_0
        d2 = (v - last) / width_1
        curvature = (d2 - d1) / (width_0 + width_1)
        extremum = spaced & ((last - earlier) * (v - last) < 0) & (curvature != 0)
        safe = jnp.where(extremum, curvature, 1.0)
        s = jnp.clip(0.5 * width_0 - d1 / (2 * safe), 0.0, width_0 + width_1)  # vertex - t_e
        vertex = earlier + d1 * s + safe * s * (s - width_0)
        use = extremum & (t_e + s >= self.start)
        new = jnp.where(t_n >= self.start, v, jnp.nan)
        # both the new value and the refined one count (the refined one only near an extremum);
        # NaN: not in the window
        candidates = jnp.concatenate([new, jnp.where(use, vertex, new)])
        width = jnp.maximum(t_n[:, 0] - jnp.maximum(t_l[:, 0], self.start), 0.0)
        sq = self.layout.squares
        square = 0.5 * (last[:, sq] ** 2 + v[:, sq] ** 2)
        duration, square_integral = self.duration, self.square_integral
        for i in range(ts.shape[0]):
            duration = duration + width[i]
            square_integral = square_integral + width[i] * square[i]
        tracker = self
        for i in range(ts.shape[0]):  # contact events in order
            onsets, events, counts = tracker._contact_events(ts[i], vs[i])
            tracker = eqx.tree_at(
                lambda x: (x.times, x.recent, x.contact_onset, x.events, x.event_count),
                tracker,
                (times[i + 1 : i + 3], values[i + 1 : i + 3], onsets, events, counts),
            )
        return Tracker(
            layout=self.layout,
            start=self.start,
            duration=duration,
            maximum=jnp.fmax(self.maximum, jnp.nanmax(candidates, axis=0)),
            minimum=jnp.fmin(self.minimum, jnp.nanmin(candidates, axis=0)),
            square_integral=square_integral,
            times=times[-2:],
            recent=values[-2:],
            contact_onset=tracker.contact_onset,
            events=tracker.events,
            event_count=tracker.event_count,
        )

    def extremes(self) -> Extremes:
        """The ``Extremes`` (named quantities) of this state; works with leading batch axes
        (without a ``pending`` sample)."""
        if self.pending is not None:
            return self.update_flat(*self.pending).extremes()
        lay = self.layout
        hi, lo = lay.observation(self.maximum), lay.observation(self.minimum)
        pick = lambda a, i: a[..., i]  # noqa: E731
        return Extremes(
            start=self.start,
            duration=self.duration,
            acceleration_min=lo.accelerations,
            acceleration_max=hi.accelerations,
            body_acceleration_max=hi.body_accelerations,
            input_torque_min=lo.input_torque,
            input_torque_max=hi.input_torque,
            input_torque_square_integral=self.square_integral[..., -1],
            body_acceleration_square_integral=self.square_integral[..., :-1],
            normal_force_max=hi.normal_force,
            penetration_max=hi.penetration,
            constraint_violation_max=hi.constraint_violation,
            times=self.times,
            recent=(
                lay.observation(self.recent[..., 0, :]),
                lay.observation(self.recent[..., 1, :]),
            ),
            contact_onset={k: pick(self.contact_onset, i) for i, k in enumerate(lay.names)},
            events={k: self.events[..., i, :, :] for i, k in enumerate(lay.names)},
            event_count={k: pick(self.event_count, i) for i, k in enumerate(lay.names)},
        )


class AbstractWrappingSolver(diffrax.AbstractAdaptiveSolver):
    """A diffrax solver that runs ``solver`` and carries something of its own in the solver state
    (``ExtremesTracking``; ``jaxclear.solve._sensitivity.TangentTracking``): everything but
    ``init`` and ``step`` is the wrapped solver's."""

    solver: eqx.AbstractVar[diffrax.AbstractSolver]

    # pyright reads diffrax's AbstractVar/AbstractClassVar attributes of AbstractSolver as class
    # variables; diffrax's own wrapping solvers (HalfSolver) override them with properties too.
    @property
    def term_structure(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.solver.term_structure

    @property
    def interpolation_cls(self):  # pyright: ignore[reportIncompatibleMethodOverride]
        return self.solver.interpolation_cls

    def order(self, terms):
        return self.solver.order(terms)

    def error_order(self, terms):
        return self.solver.error_order(terms)

    def strong_order(self, terms):
        return self.solver.strong_order(terms)

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)


RIDING_SOLVERS = (diffrax.Tsit5, diffrax.Dopri5, LawsonTsit5, AffineKenCarp)
"""Solvers on which the observations ride along the stages (``ExtremesTracking``): explicit
Runge–Kutta methods whose last stage is at (t1, y1) (first same as last) and whose dense output
is built from the stages (``k``); ``LawsonTsit5``, which is Tsit5 on rows without decay; and
``AffineKenCarp``, whose first stage is explicit and at (t0, y0)."""


class ExtremesTracking(AbstractWrappingSolver):
    """A diffrax solver that runs ``solver`` and carries a ``Tracker`` in its solver state.

    After each step it samples the observation at the step's midpoint and at its end; diffrax
    keeps the new solver state only if the step is accepted, so rejected steps leave the extremes
    alone. Read the result with ``SaveAt(solver_state=True)``: ``sol.solver_state[1].extremes()``.

    **How the samples are taken.** With ``field`` given and a solver of ``RIDING_SOLVERS``
    (Tsit5, the ``fast`` preset and ``auto``'s choice without friction states; ``LawsonTsit5``;
    ``AffineKenCarp``, the ``imex`` preset and ``auto``'s choice with LuGre friction), the
    observation rides along the solver's own evaluations: the solver integrates (y, w) with
    w' = v(t, y), v the flat observation (``_Layout.flat``), from w = 0 at each step, where one
    evaluation of the right-hand side gives both dy/dt and v (``field``). No extra evaluation of
    the model: the end sample is v at the last stage, which is (t1, y1) (first same as last),
    and the midpoint sample is the derivative of w's dense output there (the solver's continuous
    extension, one order below the state's). ``LawsonTsit5`` is Tsit5 on w (decay rate 0).
    ``AffineKenCarp``'s last stage is at t1 but not at y1 (its explicit tableau is not stiffly
    accurate); its first stage is explicit and at (t0, y0), so a step's end sample is taken in
    by the next step, from its first stage (``_step_imex``, ``Tracker.pending``). The step-size controller sees the error of y only (w is a read-out,
    not part of the state), and y's steps and values are those of the plain solve. Otherwise
    (implicit methods, diffrax's KenCarp) ``observe`` is evaluated at the midpoint (from the
    step's dense output) and at the end, in one vectorised call.

    Attributes:
        solver: the wrapped solver (any adaptive diffrax solver).
        observe: ``observe(t, y, args) -> Observation``.
        start: start time of the statistics window, s.
        max_events: room for this many contact events per clearance joint (0: none recorded).
        field: ``field(t, y, args) -> (dy/dt, Observation)``, the vector field of the solve's
            ``ODETerm`` and the observation from one evaluation, and with ``gamma_h=`` the
            ``AffineKenCarp`` stage and the observation at it
            (``jaxclear.solve._observables.field_and_observation``); ``None``: always sample
            with ``observe``.
    """

    solver: diffrax.AbstractSolver
    observe: Callable = eqx.field(static=True)
    start: Float[Array, ""]
    max_events: int = eqx.field(static=True, default=0)
    field: Callable | None = eqx.field(static=True, default=None)

    @property
    def rides(self) -> bool:
        """Whether the observations ride along the solver's stages (see the class)."""
        return self.field is not None and type(self.solver) in RIDING_SOLVERS

    def _riding_term(self, layout: "_Layout") -> diffrax.ODETerm:
        """The term of the (y, w) system. (As one vector [y, w] it ran a few per cent faster,
        but the solver's sums over the stages then round y differently: the chaotic three-joint
        case took another path with extremes on than off.)"""
        field = self.field
        assert field is not None

        def vector_field(t, yw, args):
            dy, obs = field(t, yw[0], args)
            # q̈ is in dy already, and the bodies' |r̈| follow from it
            return dy, layout.flat(obs)[layout.torque :]

        return diffrax.ODETerm(vector_field)

    def _riding_stage(self, layout: "_Layout") -> Callable:
        """``AffineKenCarp``'s ``observed`` stage: its stage and the flat observation after q̈
        and the bodies' |r̈| at the stage's state, from one evaluation."""
        field = self.field
        assert field is not None

        def observed(t, partial, gamma_h, args):
            stage, obs = field(t, partial, args, gamma_h=gamma_h)
            return stage, layout.flat(obs)[layout.torque :]

        return observed

    def init(self, terms, t0, t1, y0, args):
        tracker = Tracker.first(self.start, t0, self.observe(t0, y0, args), self.max_events)
        if self.rides and isinstance(self.solver, AffineKenCarp):
            pending = (tracker.times[1], tracker.recent[1])  # the same structure as ``step``'s
            tracker = dataclasses.replace(tracker, pending=pending)
            return self.solver.init(terms, t0, t1, y0, args), tracker
        if self.rides:
            w0 = jnp.zeros_like(tracker.recent[1, tracker.layout.torque :])
            inner = self.solver.init(self._riding_term(tracker.layout), t0, t1, (y0, w0), args)
        else:
            inner = self.solver.init(terms, t0, t1, y0, args)
        return inner, tracker

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        inner, tracker = solver_state
        if self.rides and isinstance(self.solver, AffineKenCarp):
            return self._step_imex(t0, t1, y0, args, inner, tracker)
        if self.rides:
            n = tracker.layout.n
            w0 = jnp.zeros_like(tracker.recent[1, tracker.layout.torque :])
            (y1, w1), (y_error, _), dense, inner, result = self.solver.step(  # pyright: ignore[reportGeneralTypeIssues]
                self._riding_term(tracker.layout), t0, t1, (y0, w0), args, inner, made_jump
            )
            k, k_w = dense["k"]
            # observed: q̈ (the q̇ rows' rates) and w's rates; k_i = h f(Y_i), and the last
            # stage is (t1, y1)
            h = t1 - t0
            end = (k[-1, n : 2 * n] / h, k_w[-1] / h)
            # at the midpoint, the derivative of their dense output
            t_mid = 0.5 * (t0 + t1)
            # LawsonTsit5 is Tsit5 on the q̇ rows and on w (their decay rate is 0)
            interpolation = (
                diffrax.Tsit5.interpolation_cls
                if isinstance(self.solver, LawsonTsit5)
                else self.solver.interpolation_cls
            )
            readout = interpolation(
                t0=t0,
                t1=t1,
                y0=(y0[n : 2 * n], w0),
                y1=(y1[n : 2 * n], w1),
                k=(k[:, n : 2 * n], k_w),
            )
            mid = readout.derivative(t_mid)
            mid, end = (
                jnp.concatenate([qdd, body_accelerations(qdd), rest]) for qdd, rest in (mid, end)
            )
            tracker = tracker.update_pair(t_mid, _exact_violation(mid, end), t1, end)
            dense_info = dict(dense, y0=y0, y1=y1, k=k)
            return y1, y_error, dense_info, (inner, tracker), result
        y1, y_error, dense_info, inner, result = self.solver.step(
            terms, t0, t1, y0, args, inner, made_jump
        )
        t_mid = 0.5 * (t0 + t1)
        y_mid = self.solver.interpolation_cls(t0=t0, t1=t1, **dense_info).evaluate(t_mid)
        # both samples in one vmapped evaluation: XLA's CPU cost is per kernel, nearly the same
        # for two points as for one, and the observation is compiled once
        times = jnp.stack([jnp.asarray(t_mid, dtype=float), jnp.asarray(t1, dtype=float)])
        both = jax.vmap(lambda t, y: self.observe(t, y, args))(times, jnp.stack([y_mid, y1]))
        first, second = (jax.tree_util.tree_map(lambda x, i=i: x[i], both) for i in (0, 1))
        flat = tracker.layout.flat
        tracker = tracker.update_pair(t_mid, flat(first), t1, flat(second))
        return y1, y_error, dense_info, (inner, tracker), result

    def _step_imex(self, t0, t1, y0, args, inner, tracker):
        """``step`` on ``AffineKenCarp``, one sample late: its last stage is at t1 but not at
        y1 (the explicit tableau is not stiffly accurate), and its first stage is explicit and
        at (t0, y0), the step before's end. So a step takes in that end sample (from its first
        stage) and its own midpoint (the derivative of the dense output of q̇ and w), and leaves
        its last stage's observation, at (t1, Y_s), as an estimate of its end
        (``Tracker.pending``): the next step replaces it, and ``Tracker.extremes`` takes it in
        after the last step. (Measured at the end of an impact step of the one-joint
        slider–crank: within 2e-4 of q̈, 3e-4 of τ, 8e-4 of F_N; the dense output's derivative
        at t1 was 10 times farther.)"""
        layout = tracker.layout
        n = layout.n
        solver = self.solver
        assert isinstance(solver, AffineKenCarp)
        y1, y_error, dense_info, vs = solver.observed_step(
            self._riding_stage(layout), t0, t1, y0, args
        )
        ks_e, ks_i = dense_info["k"]  # pyright: ignore[reportGeneralTypeIssues]
        h = t1 - t0
        k = (ks_e + ks_i)[:, n : 2 * n]
        weights = jnp.asarray(TABLEAUS[solver.variant].midpoint_derivative, dtype=vs.dtype)
        # rows: the start (first stage), the midpoint, the last stage
        qdd = jnp.stack([k[0], weights @ k, k[-1]]) / h
        rest = jnp.stack([vs[0], weights @ vs, vs[-1]])
        start, mid, end = jnp.concatenate([qdd, body_accelerations_rows(qdd), rest], axis=1)
        t_start = jnp.asarray(t0, dtype=float)
        tracker = tracker.update_pair(t_start, start, 0.5 * (t0 + t1), _exact_violation(mid, start))
        tracker = dataclasses.replace(tracker, pending=(jnp.asarray(t1, dtype=float), end))
        return y1, y_error, dense_info, (inner, tracker), diffrax.RESULTS.successful


def _exact_violation(mid, exact):
    """The midpoint sample with the constraint violation (the layout's last entry) of a sample
    at the solution, ``exact``. max |Φ| is ~1e-10 on the solution but larger at the intermediate
    stages, and the dense output's derivative mixes those in: riding midpoints had raised the
    ideal slider–crank's max_constraint_violation from 1.08e-7 to 9.68e-6 (2 revolutions, Tsit5)."""
    return mid.at[-1].set(exact[-1])


def _merge_events(parts, seams, joint: str):
    """One joint's finished contacts over consecutive solves, the onset of the one in progress at
    the end and how many contacts overflowed the buffers; a contact in progress across a seam (the later solve starts it at its first
    instant, ``Tracker.first``) is joined into one."""
    rows, open_onset, lost = [], np.nan, 0
    for x, seam in zip(parts, seams):
        buffer, count = np.asarray(x.events[joint]), int(x.event_count[joint])
        lost += max(count - buffer.shape[0], 0)
        stored = buffer[:count].copy()
        onset_now = float(x.contact_onset[joint])
        if np.isfinite(open_onset):
            if stored.shape[0] and stored[0, 0] == seam:
                stored[0, 0] = open_onset  # the contact in progress at the seam ended here
            elif stored.shape[0] == 0 and onset_now == seam:
                onset_now = open_onset  # and is still in progress at this solve's end
        rows.append(stored)
        open_onset = onset_now
    return np.concatenate(rows, axis=0), open_onset, lost


def combine_extremes(parts: "list[Extremes]", seams) -> Extremes:
    """The ``Extremes`` of consecutive solves (each started from the last one's final state) as if
    one solve had covered them all: peaks over all, integrals and durations summed, contact events
    concatenated with contacts across a seam joined. Host-side (concrete, unbatched values).

    Args:
        parts: the solves' ``Extremes``, in time order.
        seams: each solve's start time, s (where a contact in progress is joined to the last one).
    """
    if not parts:
        raise ValueError("combine_extremes needs at least one Extremes.")
    durations = [float(x.duration) for x in parts]
    used = [x for x, d in zip(parts, durations) if d > 0] or [parts[-1]]

    def fold(name, op):
        return jax.tree_util.tree_map(
            lambda *v: jnp.asarray(op(np.stack([np.asarray(a) for a in v]), axis=0)),
            *(getattr(x, name) for x in parts),
        )

    joints = list(parts[0].events)
    merged = {k: _merge_events(parts, seams, k) for k in joints}
    last = parts[-1]
    return Extremes(
        start=jnp.asarray(used[0].start),
        duration=jnp.asarray(sum(durations)),
        acceleration_min=fold("acceleration_min", np.min),
        acceleration_max=fold("acceleration_max", np.max),
        body_acceleration_max=fold("body_acceleration_max", np.max),
        input_torque_min=fold("input_torque_min", np.min),
        input_torque_max=fold("input_torque_max", np.max),
        input_torque_square_integral=fold("input_torque_square_integral", np.sum),
        body_acceleration_square_integral=fold("body_acceleration_square_integral", np.sum),
        normal_force_max=fold("normal_force_max", np.max),
        penetration_max=fold("penetration_max", np.max),
        constraint_violation_max=fold("constraint_violation_max", np.max),
        times=last.times,
        recent=last.recent,
        contact_onset={k: jnp.asarray(merged[k][1]) for k in joints},
        events={k: jnp.asarray(merged[k][0]) for k in joints},
        # more contacts than stored where a solve's buffer overflowed: contact_events then refuses
        event_count={
            k: jnp.asarray(merged[k][0].shape[0] + merged[k][2], dtype=jnp.int32) for k in joints
        },
    )
