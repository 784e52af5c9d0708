"""Poincaré sections once per crank revolution, bifurcation diagrams, phase portraits
(docs/chaos.md).

A constant-speed crank makes the equations of motion periodic in time with the crank period
T = 2π/|ω|. Sampling the state once per period (the stroboscopic Poincaré map) turns a periodic
response into a single point, a period-k response (a subharmonic, k revolutions per repetition)
into k points, a quasi-periodic one into a closed curve and a chaotic one into a scattered set.
The section times are passed to ``simulate`` as its output times, so the points are interpolated
from the solver's dense output at exactly those instants, not picked from a saved grid.
"""

import dataclasses
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._core._checks import is_concrete
from ..analysis._orbits import distinct_points
from ..analysis._signals import checked_signal_names, signal_names, signals
from ..model import Mechanism, with_parameters
from ..solve._lanes import _Program, batched_trajectories, members_solution
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, solver_config
from ._engine import (
    EnsembleSettings,
    chunk_size_of,
    concurrent_refill,
    map_members,
    swept_values,
)

DEFAULT_SKIP_REVOLUTIONS = 1
"""Start-up revolutions left out of a section by default: the journals start centred with the
ideal velocities (docs/model.md §1) and settle within the first revolution or two on the
benchmark; increase it for a clean attractor."""

_ROUNDING = 1e-9
"""Relative slack when counting whole revolutions in [t0, t1], so that a t1 computed as
t0 + k T in floating point still gives k revolutions."""


def default_section_signals(mechanism: Mechanism) -> tuple[str, ...]:
    """What a section samples by default: each clearance joint's eccentricity components
    (``<J>_ecc_x``, ``<J>_ecc_y``, m), then the slider's velocity and acceleration (``slider_v``,
    ``slider_a``) for the slider–crank, or else the driven body's torque."""
    names = signal_names(mechanism)
    out = [f"{j.name}_ecc_{axis}" for j in mechanism.clearance_joints for axis in "xy"]
    if "slider_v" in names:
        out += ["slider_v", "slider_a"]
    elif mechanism.driver is not None:
        out.append(f"{mechanism.driver.body}_torque")
    return tuple(n for n in out if n in names)


def crank_speed(mechanism: Mechanism) -> Float[Array, ""]:
    """The driver's constant angular speed ω, rad/s (traceable).

    Raises:
        ValueError: no driver, or a driver whose speed varies (no crank period to sample at).
    """
    driver = mechanism.driver
    speed = None if driver is None else driver.constant_speed
    if speed is None:
        raise ValueError(
            "mechanism: a Poincaré section once per revolution needs a constant-speed driver "
            "(ConstantSpeedDriver, e.g. slider_crank(rpm=...)); this mechanism has "
            f"{'no driver' if driver is None else type(driver).__name__}."
        )
    if is_concrete(speed) and not float(speed) != 0.0:
        raise ValueError("mechanism: the driver's speed is 0, so there is no crank period.")
    return jnp.asarray(speed, dtype=float)


def section_times(
    mechanism: Mechanism,
    revolutions: int,
    *,
    t0: ArrayLike = 0.0,
    skip_revolutions: int = DEFAULT_SKIP_REVOLUTIONS,
    phase: ArrayLike = 0.0,
) -> Float[Array, " revolutions"]:
    """Section instants t_k = t0 + (skip_revolutions + k + phase/2π)·T, k = 0..revolutions−1.

    T = 2π/|ω| from the driver's speed; traceable in the mechanism (e.g. ``rpm`` under
    ``jax.vmap``), ``t0`` and ``phase``.
    """
    period = 2.0 * jnp.pi / jnp.abs(crank_speed(mechanism))
    k = jnp.arange(revolutions, dtype=float)
    return (
        jnp.asarray(t0, dtype=float)
        + (skip_revolutions + k + jnp.asarray(phase, dtype=float) / (2.0 * jnp.pi)) * period
    )


def _float(x) -> float:
    return float(np.asarray(x))


def _check_int(value, parameter: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{parameter} must be an integer >= {minimum}, got {value!r}.")
    return int(value)


def _section(
    mechanism, t1, revolutions, t0, skip_revolutions, names, config, phase, y0, throw
) -> tuple[dict[str, Array], Array, Array]:
    """Points, times and success flag of a section (no argument checks)."""
    times = section_times(
        mechanism, revolutions, t0=t0, skip_revolutions=skip_revolutions, phase=phase
    )
    concrete = all(is_concrete(x) for x in jax.tree_util.tree_leaves((times, t0, t1)))
    if concrete:
        times = np.asarray(times)  # simulate checks concrete grids against [t0, t1]
        end = float(times[-1]) if t1 is None else max(float(t1), float(times[-1]))
    else:
        end = times[-1] if t1 is None else jnp.maximum(t1, times[-1])
    traj = simulate(
        mechanism, end, t0=t0, ts=times, solver=config, y0=y0, extremes=False, throw=throw
    )
    ok = traj.succeeded
    points = {n: jnp.where(ok, x, jnp.nan) for n, x in signals(traj, names).items()}
    return points, jnp.asarray(times), ok


def poincare_section(
    mechanism: Mechanism,
    t1: ArrayLike | None = None,
    *,
    revolutions: int | None = None,
    t0: ArrayLike = 0.0,
    skip_revolutions: int = DEFAULT_SKIP_REVOLUTIONS,
    signals: Sequence[str] | None = None,
    solver: "str | SolverConfig" = "auto",
    phase: ArrayLike = 0.0,
    y0: ArrayLike | None = None,
    throw: bool = True,
) -> dict[str, Float[Array, " revolutions"]]:
    """Stroboscopic Poincaré section: named signals once per crank revolution.

    The section instants are t_k = t0 + (skip_revolutions + k + phase/2π)·T with T = 2π/|ω| the
    crank period (``section_times``); the crank is then at the same angle, its angle at t0 plus
    ``phase``, at every point. They are ``simulate``'s output times, so the values come from the
    solver's dense output at those instants.

    A pure function of the mechanism's leaves: under ``jax.vmap`` over a parameter (give
    ``revolutions``, whose count fixes the output shape) it gives one section per value, the
    points of a bifurcation diagram (``bifurcation_points`` does this in chunks).

    Args:
        mechanism: a ``Mechanism`` with a constant-speed driver.
        t1: end of the simulated interval, s: the section holds every instant in
            [t0 + skip_revolutions·T, t1]. Optional when ``revolutions`` is given (the solve
            then ends at the last instant).
        revolutions: number of section points (static). Required under ``jax.jit``/``vmap``
            when the crank speed or ``t1`` is traced.
        t0: start time, s (the state there is ``y0`` or the assembled one).
        skip_revolutions: start-up revolutions left out (integer ≥ 0).
        signals: signal names (``jaxclear.signal_names``); default ``default_section_signals``
            (each clearance joint's ``<J>_ecc_x``, ``<J>_ecc_y``, and ``slider_v``, ``slider_a``).
        solver: as in ``simulate``.
        phase: crank angle of the section past the crank's angle at ``t0``, rad, in [0, 2π).
        y0: initial state at ``t0`` (default: assembled).
        throw: eager calls: raise ``SimulationError`` if the solve fails. Otherwise (and under
            transformations) a failed solve gives NaN points.

    Returns:
        ``{signal name: values (revolutions,)}`` in SI units, plus ``"t"``: the instants, s.

    Raises:
        ValueError: no constant-speed driver, unknown ``signals``, neither ``t1`` nor
            ``revolutions`` (or ``t1`` traced without ``revolutions``), ``t1`` too short for one
            point or for ``revolutions`` points, a bad ``skip_revolutions`` or ``phase``.
    """
    speed = crank_speed(mechanism)
    names = checked_signal_names(
        mechanism, default_section_signals(mechanism) if signals is None else signals, "signals"
    )
    skip = _check_int(skip_revolutions, "skip_revolutions", 0)
    if is_concrete(phase) and not 0.0 <= _float(phase) < 2.0 * np.pi:
        raise ValueError(f"phase must be in [0, 2π) rad, got {phase!r}.")
    if revolutions is None:
        if t1 is None:
            raise ValueError("give t1 (end time, s) or revolutions (number of section points).")
        if not (is_concrete(t1) and is_concrete(t0) and is_concrete(speed)):
            raise ValueError(
                "revolutions must be given when t1, t0 or the crank speed is traced "
                "(jax.jit/vmap): the number of points fixes the output shape."
            )
        start, end = _float(t0), _float(t1)
        period = 2.0 * np.pi / abs(_float(speed))
        offset = skip + _float(phase) / (2.0 * np.pi)  # revolutions from t0 to the first point
        span = (end - start) / period - offset
        revolutions = int(np.floor(span * (1.0 + _ROUNDING) + _ROUNDING)) + 1
        if revolutions < 1:
            raise ValueError(
                f"t1 = {end} s leaves no section point: the first is at t0 + (skip_revolutions + "
                f"phase/2π)·T = {start + offset * period:.6g} s (crank period T = {period:.6g} s)."
            )
    else:
        revolutions = _check_int(revolutions, "revolutions", 1)
        if t1 is not None and is_concrete(t1) and is_concrete(t0) and is_concrete(speed):
            times = section_times(mechanism, revolutions, t0=t0, skip_revolutions=skip, phase=phase)
            last = _float(times[-1])
            if _float(t1) < last * (1.0 - _ROUNDING):
                raise ValueError(
                    f"t1 = {_float(t1)} s ends before the last of {revolutions} section points "
                    f"({last:.6g} s); raise t1 or lower revolutions."
                )
    config = solver_config(solver, mechanism)
    points, times, _ = _section(
        mechanism, t1, revolutions, t0, skip, names, config, phase, y0, throw
    )
    return {**points, "t": times}


@dataclasses.dataclass(frozen=True)
class BifurcationDiagram:
    """Poincaré sections over the values of one parameter (``bifurcation_points``).

    Attributes:
        parameter: the swept parameter's name (``jaxclear.parameter_names``).
        values: its values (N,), SI units.
        times: section instants (N, revolutions), s (they depend on the value if it changes the
            crank speed).
        points: ``{signal name: (N, revolutions)}``, NaN for a member whose solve failed.
        succeeded: (N,) whether each member's solve reached its last instant.
    """

    parameter: str
    values: np.ndarray
    times: np.ndarray
    points: dict[str, np.ndarray]
    succeeded: np.ndarray

    def scatter(self, signal: str) -> tuple[np.ndarray, np.ndarray]:
        """``(parameter values, section values)``, flattened, for a scatter plot of ``signal``."""
        if signal not in self.points:
            raise ValueError(
                f"signal {signal!r} is not in the diagram; it has {list(self.points)}."
            )
        y = self.points[signal]
        return np.repeat(self.values, y.shape[1]), y.reshape(-1)

    def distinct(self, signal: str, tolerance: float) -> np.ndarray:
        """Number of distinct section values of ``signal`` per parameter value
        (``distinct_points``)."""
        return distinct_points(self.points[signal], tolerance)


def _bifurcation_member(v, mechanism, name, revolutions, t0, skip, names, config, phase):
    m = with_parameters(mechanism, {name: v[0]})
    return _section(m, None, revolutions, t0, skip, names, config, phase, None, False)


@eqx.filter_jit
def _bifurcation_chunk(
    rows, count, mechanism, name, revolutions, t0, skip, names, config, phase, lanes
):
    """A chunk of ``bifurcation_points`` on refilled lanes (``map_members(..., batched=True)``):
    each row's section as ``_bifurcation_member`` gives it, from ``solve_members``' loop with
    each member's own section instants as its output times (the solve ``simulate`` makes for
    ``_section``: no extremes, no contact events, ends at the last instant)."""
    times = jax.vmap(
        lambda v: section_times(
            with_parameters(mechanism, {name: v[0]}),
            revolutions,
            t0=t0,
            skip_revolutions=skip,
            phase=phase,
        )
    )(rows)
    program = _Program(mechanism=mechanism, names=(name,), config=config, track=False, max_events=0)
    starts = jnp.full(rows.shape[0], t0, dtype=float)
    solution = members_solution(
        program, rows, jnp.asarray(t0, dtype=float), times[:, -1], starts, None, lanes, times, count
    )
    trajectories = batched_trajectories(solution)

    def one(trajectory):
        ok = trajectory.succeeded
        points = {n: jnp.where(ok, x, jnp.nan) for n, x in signals(trajectory, names).items()}
        return points, ok

    points, ok = jax.vmap(one)(trajectories)
    return points, times, ok


def bifurcation_points(
    mechanism: Mechanism,
    name: str,
    values,
    revolutions: int,
    *,
    t0: float = 0.0,
    skip_revolutions: int = DEFAULT_SKIP_REVOLUTIONS,
    signals: Sequence[str] | None = None,
    solver: "str | SolverConfig" = "auto",
    phase: float = 0.0,
    settings: EnsembleSettings = EnsembleSettings(),
) -> BifurcationDiagram:
    """Bifurcation diagram: the Poincaré section (``poincare_section``) for each value of one
    named parameter, solved in chunks by the ensemble engine (``map_members``).

    Every value gets ``revolutions`` points after ``skip_revolutions`` start-up revolutions of its
    own crank period (so a sweep over ``rpm`` skips the same number of revolutions, not the same
    time). A failed member gives NaN points and ``succeeded`` False; the others go on.

    Args:
        mechanism: a ``Mechanism`` with a constant-speed driver.
        name: the parameter (``jaxclear.parameter_names``), e.g. ``"rpm"``, ``"B.clearance"``,
            ``"B.restitution"``, ``"B.friction_coefficient"`` (Coulomb-type laws; LuGre has
            ``"B.kinetic_friction"``, ``"B.static_friction"``, ...).
        values: its values (N,), SI units (``rpm`` in rev/min).
        revolutions: section points per value.
        t0, skip_revolutions, signals, solver, phase: as in ``poincare_section``.
        settings: ``chunk_size`` (values per vectorised solve, at most the number of values:
            one compilation per chunk size), ``devices`` (to split each chunk over, default all
            local devices), ``engine`` and ``lanes`` of an ``EnsembleSettings``: ``"refill"``
            (default) solves a chunk on ``lanes`` lanes, a lane whose member is done taking
            the next one at once (``jaxclear.solve.solve_members``, each member's section
            instants as its output times); ``"lockstep"``, a vmapped ``poincare_section``,
            steps all members until the slowest is done. Its other fields are not used here.

    Returns:
        A ``BifurcationDiagram``.

    Raises:
        ValueError: an unknown ``name`` or ``signals``, ``values`` not 1-D and finite, and the
            errors of ``poincare_section``'s arguments.
    """
    values = swept_values(mechanism, name, values)
    names = checked_signal_names(
        mechanism, default_section_signals(mechanism) if signals is None else signals, "signals"
    )
    skip = _check_int(skip_revolutions, "skip_revolutions", 0)
    revolutions = _check_int(revolutions, "revolutions", 1)
    if not 0.0 <= float(phase) < 2.0 * np.pi:
        raise ValueError(f"phase must be in [0, 2π) rad, got {phase!r}.")
    crank_speed(mechanism)
    config = solver_config(solver, mechanism)
    args = (mechanism, name, revolutions, float(t0), skip, names, config, float(phase))
    chunked = dataclasses.replace(settings, chunk_size=min(chunk_size_of(settings), values.size))
    if settings.engine == "refill":
        points, times, ok = map_members(
            _bifurcation_chunk,
            (*args, settings.lanes),
            values[:, None],
            settings=chunked,
            batched=True,
            concurrent=concurrent_refill(mechanism, config, ideal=False),
        )
    else:
        points, times, ok = map_members(
            _bifurcation_member, args, values[:, None], settings=chunked
        )
    return BifurcationDiagram(
        parameter=name,
        values=values,
        times=np.asarray(times),
        points={n: np.asarray(points[n]) for n in names},
        succeeded=np.asarray(ok, dtype=bool),
    )
