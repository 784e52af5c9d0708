"""Design optimisation: minimise an objective of the simulated response over bounded design parameters.

Objectives (``objective=``):

- any name of ``jaxclear.analysis.statistics`` (``B_peak_normal_force``, ``crank_torque_rms``,
  ``peak_slider_acceleration``, ...): taken from the solver's steps over the statistics window;
- ``"torque_fluctuation"``: RMS of the input torque about its mean over the window, N m;
- ``"<signal>_deviation"`` for a signal of ``jaxclear.signals`` (``"slider_a_deviation"``): RMS of
  the signal's difference from the same signal of the ideal mechanism (every clearance joint made
  ideal, the same design), over the window;
- a callable ``objective(traj) -> scalar`` (pure JAX) for anything else.

The two RMS objectives are trapezoidal means over the output grid (``num_points``), so they are
smooth in the design; the statistics are exact peaks of the solve.

Why averaged over perturbed starts: a response with impacts is a rough function of the design (a
peak force jumps when the impact sequence changes). The objective is the mean over ``starts``
solves whose journals start at different points of their clearance circles (start 0 centred, the
others at ``start_spread`` × c in directions spread round the circle), which smooths the surface
enough for gradient descent.

Method: Adam (optax) on the unconstrained variables of ``_parameter_space`` with gradients
through the vectorised solves (forward mode up to ``FORWARD_MODE_PARAMETERS`` parameters, reverse
mode above): by default at ``jaxclear.gradient_solver`` settings with diffrax's discrete
derivatives, at any other settings with ``simulate``'s error-controlled sensitivities
(``optimization_adjoint``); the best iterate is kept. Then an independent check: the initial and
the optimised designs are simulated again, without differentiation, at a tighter tolerance
(``verify_solver``), and the improvement is reported from those runs.
"""

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._core._errors import ModelError
from .._core._progress import progress_bar
from ..analysis._signals import signal_names, signals
from ..analysis._statistics import statistics
from ..model import Mechanism, with_parameters
from ..solve._simulate import simulate
from ..solve._solver import SolverConfig, gradient_solver, recommended_solver, solver_config
from ..solve._startup import ideal_mechanism
from ._parameter_space import FitParameter, ParameterSpace, parse_parameters


def optimization_adjoint(mechanism, solver: SolverConfig, mode: str) -> str:
    """How ``optimize`` differentiates (``mode``: ``"forward"`` or ``"reverse"``): diffrax's
    discrete derivatives at exactly ``gradient_solver`` settings (the default), where they were
    measured right (docs/differentiation.md, "Settings for gradients"); the error-controlled
    sensitivities at any other settings, where the discrete derivatives are not controlled (at
    rtol 1e-6 they were off by up to 107 % over 3 ms, docs/differentiation.md).

    The default stays ``gradient_solver``: on notebook 08's design (``rod_com_x``, one
    revolution, 4 starts) two iterates at ``simulate``'s settings took 66 s compiled against
    17.6 s for all 16 at ``gradient_solver``'s, and one start's sensitivity solve ran out of
    steps in a contact phase (``python benchmarks/optimize_defaults.py``,
    docs/identification.md, "Design optimisation")."""
    discrete = solver == gradient_solver(mechanism)
    return f"discrete-{mode}" if discrete else mode


FORWARD_MODE_PARAMETERS = 4
"""Up to this many design parameters the gradient is taken in forward mode (cost ≈ 1 + 0.5 p
solves, cheaper to compile than reverse mode); above, in reverse mode."""

VERIFY_RTOL = 1e-10
"""Relative tolerance of the verification runs (absolute: rtol / 1000), or the optimisation's own if
that is tighter; their method is ``recommended_solver``'s, so the check does not share the
optimisation's integrator when that is an exponential (Lawson) one."""


@dataclasses.dataclass
class OptimizationResult:
    """What ``optimize`` found.

    Attributes:
        initial, values: ``{name: value}`` before and after.
        objective: name of the objective (or the callable's name).
        history: per iteration ``{"iteration", "objective", "values"}`` (objectives from the
            differentiated solves).
        verified_initial, verified_final: the objective of the initial and optimised designs from
            the independent verification runs (``verify_solver``).
        improvement: (verified_initial − verified_final) / |verified_initial|.
        iterations: Adam steps taken. time: wall time, s (compilation included).
        solver, verify_solver: the ``SolverConfig``s of the optimisation and of the check.
        parameters: the ``FitParameter`` specs (bounds).
    """

    initial: dict[str, float]
    values: dict[str, float]
    objective: str
    history: list[dict[str, Any]]
    verified_initial: float
    verified_final: float
    improvement: float
    iterations: int
    time: float
    solver: SolverConfig
    verify_solver: SolverConfig
    parameters: list[FitParameter]

    def summary(self) -> dict[str, Any]:
        return {
            "objective": self.objective,
            "initial": self.initial,
            "values": self.values,
            "verified_initial": self.verified_initial,
            "verified_final": self.verified_final,
            "improvement": self.improvement,
            "iterations": self.iterations,
            "time_s": self.time,
            "history": self.history,
            "bounds": {p.name: [p.lower, p.upper] for p in self.parameters},
        }


def start_offsets(mechanism: Mechanism, starts: int, spread: float) -> jnp.ndarray:
    """Initial eccentricities (starts, joints, 2), m: start 0 centred, the others at ``spread`` × c
    in directions spread evenly round the circle (rotated per joint so joints differ)."""
    joints = mechanism.clearance_joints
    out = np.zeros((starts, len(joints), 2))
    for s in range(1, starts):
        for j, joint in enumerate(joints):
            angle = 2 * math.pi * (s - 1) / max(starts - 1, 1) + 0.7 * j
            c = float(joint.geometry.clearance)
            out[s, j] = spread * c * np.array([math.cos(angle), math.sin(angle)])
    return jnp.asarray(out)


def _rms(t, x, start):
    """Trapezoidal RMS of x(t) over t ≥ start (x sampled on the grid t)."""
    w = jnp.where(t >= start, 1.0, 0.0)
    dt = jnp.diff(t)
    seg = 0.5 * (w[1:] + w[:-1]) * dt
    mean_square = jnp.sum(seg * 0.5 * (x[1:] ** 2 + x[:-1] ** 2)) / jnp.sum(seg)
    return jnp.sqrt(mean_square)


def _mean(t, x, start):
    w = jnp.where(t >= start, 1.0, 0.0)
    seg = 0.5 * (w[1:] + w[:-1]) * jnp.diff(t)
    return jnp.sum(seg * 0.5 * (x[1:] + x[:-1])) / jnp.sum(seg)


def _check_objective(mechanism: Mechanism, objective) -> None:
    if callable(objective):
        return
    if objective == "torque_fluctuation":
        if mechanism.driver is None:
            raise ModelError("objective 'torque_fluctuation' needs a driven mechanism.")
        return
    if isinstance(objective, str) and objective.endswith("_deviation"):
        name = objective[: -len("_deviation")]
        if name not in signal_names(mechanism):
            raise ModelError(
                f"objective {objective!r}: {name!r} is not a signal of this mechanism; "
                f"use one of {', '.join(n + '_deviation' for n in signal_names(mechanism))}."
            )
        return
    names = _statistics_names(mechanism)
    if objective not in names:
        raise ModelError(
            f"unknown objective {objective!r}; use 'torque_fluctuation', '<signal>_deviation' or one "
            f"of {', '.join(names)}, or pass a callable."
        )


def _statistics_names(mechanism: Mechanism) -> list[str]:
    names = []
    for joint in mechanism.clearance_joints:
        names += [f"{joint.name}_peak_normal_force", f"{joint.name}_peak_penetration"]
    names += [f"peak_{b}_acceleration" for b in mechanism.body_names]
    if mechanism.driver is not None:
        names += [f"{mechanism.driver.body}_torque_{k}" for k in ("min", "max", "rms")]
    return names


def _value(objective, traj, ideal, start):
    if callable(objective):
        return jnp.asarray(objective(traj), dtype=float)
    if objective == "torque_fluctuation":
        tau = traj.input_torque
        return _rms(traj.t, tau - _mean(traj.t, tau, start), start)
    if objective.endswith("_deviation"):
        name = objective[: -len("_deviation")]
        x = signals(traj, [name])[name] - signals(ideal, [name])[name]
        return _rms(traj.t, x, start)
    return statistics(traj)[objective]


@eqx.filter_jit
def _averaged(
    mechanism, specs, objective, solver, u, offsets, t1, num_points, start, adjoint="reverse"
):
    """Mean objective over the perturbed starts, for unconstrained design variables u."""
    design = with_parameters(mechanism, specs.values(u))
    needs_ideal = isinstance(objective, str) and objective.endswith("_deviation")
    ideal = (
        simulate(
            ideal_mechanism(design),
            t1,
            num_points=num_points,
            solver=solver,
            extremes=False,
            adjoint=adjoint,
        )
        if needs_ideal
        else None
    )

    def one(offset):
        m = design
        for j in range(len(m.clearance_joints)):
            m = eqx.tree_at(lambda m, j=j: m.clearance_joints[j].initial_eccentricity, m, offset[j])
        traj = simulate(
            m, t1, num_points=num_points, solver=solver, statistics_start=start, adjoint=adjoint
        )
        value = _value(objective, traj, ideal, start)
        return jnp.where(traj.succeeded, value, jnp.inf)

    return jnp.mean(jax.vmap(one)(offsets))


@eqx.filter_jit
def _averaged_and_gradient(
    mechanism, specs, objective, solver, u, offsets, t1, num_points, start, mode
):
    """(mean objective, its gradient in u) by forward (``mode="forward"``) or reverse mode, with
    ``optimization_adjoint``'s derivatives: both from the same (differentiated) solves."""
    args = (mechanism, specs, objective, solver)
    rest = (offsets, t1, num_points, start)
    adjoint = optimization_adjoint(mechanism, solver, mode)
    if mode == "forward":

        def f(u):
            value = _averaged(*args, u, *rest, adjoint=adjoint)
            return value, value

        grad, value = jax.jacfwd(f, has_aux=True)(u)
        return value, grad
    return jax.value_and_grad(lambda u: _averaged(*args, u, *rest, adjoint=adjoint))(u)


def optimize(
    mechanism: Mechanism,
    objective: "str | Callable",
    parameters: "Mapping[str, Any] | Sequence[str | FitParameter]",
    *,
    t1: float,
    statistics_start: float = 0.0,
    num_points: int = 401,
    starts: int = 4,
    start_spread: float = 0.5,
    solver: "str | SolverConfig | None" = None,
    verify_solver: "str | SolverConfig | None" = None,
    learning_rate: float = 0.1,
    max_iterations: int = 30,
    progress: bool = False,
    callback: Callable[[dict[str, Any]], None] | None = None,
) -> OptimizationResult:
    """Minimise ``objective`` of the response over bounded design parameters (module doc).

    Args:
        mechanism: the design to start from (every parameter not designed stays as it is).
        objective: a statistics name, ``"torque_fluctuation"``, ``"<signal>_deviation"`` or a
            callable ``f(traj) -> scalar`` (module doc).
        parameters: the design parameters as for ``jaxclear.identify`` (names, ``{name: initial}``,
            ``{name: (initial, lower, upper)}``, ...); bounds keep designs admissible.
        t1: simulated time from 0, s. statistics_start: start of the window the objective covers, s
            (leave out the start-up). num_points: output points (the RMS objectives' grid).
        starts: perturbed starts averaged (1: only the centred start). start_spread: their offset,
            fraction of each joint's clearance.
        solver: settings of the differentiated solves (default ``jaxclear.gradient_solver``,
            differentiated by diffrax's discrete derivatives; any other settings by ``simulate``'s
            error-controlled sensitivities, ``optimization_adjoint``).
        verify_solver: settings of the independent check (default: the recommended method at
            ``VERIFY_RTOL`` or the optimisation's rtol, whichever is tighter).
        learning_rate: Adam step size in the unconstrained variables (≈ relative change per step
            for positive parameters). max_iterations: Adam steps.
        progress: a tqdm bar over iterations. callback: called with each history entry.

    Returns:
        An ``OptimizationResult``; ``improvement`` is from the verification runs.

    Raises:
        ModelError: unknown objective or parameter, bad bounds, ``starts`` < 1.
    """
    started = time.perf_counter()
    _check_objective(mechanism, objective)
    if starts < 1:
        raise ModelError(f"starts must be at least 1, got {starts}.")
    specs = tuple(parse_parameters(mechanism, parameters))
    config = gradient_solver(mechanism) if solver is None else solver_config(solver, mechanism)
    if verify_solver is None:
        rtol = min(VERIFY_RTOL, config.rtol)
        verify = recommended_solver(mechanism).replace(
            rtol=rtol, atol=rtol * 1e-3, max_steps=max(config.max_steps, 100_000)
        )
    else:
        verify = solver_config(verify_solver, mechanism)
    name = objective if isinstance(objective, str) else getattr(objective, "__name__", "objective")
    offsets = start_offsets(mechanism, starts, start_spread)
    space = ParameterSpace.of(specs)
    mode = "forward" if len(specs) <= FORWARD_MODE_PARAMETERS else "reverse"
    # arrays, not Python floats: new end times and windows reuse the compiled solve
    args = (offsets, jnp.asarray(float(t1)), int(num_points), jnp.asarray(float(statistics_start)))

    u = jnp.asarray([float(q.to_unconstrained(q.initial)) for q in specs])
    u0 = u
    optimiser = optax.adam(learning_rate)
    state = optimiser.init(u)
    history: list[dict[str, Any]] = []
    best_u, best = u, math.inf
    bar = progress_bar(progress, max_iterations + 1, "optimize")
    iterations = 0
    for it in range(max_iterations + 1):
        value, grad = _averaged_and_gradient(mechanism, space, objective, config, u, *args, mode)
        value = float(value)
        entry = {"iteration": it, "objective": value, "values": _values(specs, u)}
        history.append(entry)
        if callback is not None:
            callback(entry)
        bar.update(1)
        if np.isfinite(value) and value < best:
            best, best_u = value, u
        if it == max_iterations or not np.all(np.isfinite(np.asarray(grad))):
            break
        updates, state = optimiser.update(grad, state, u)
        u = optax.apply_updates(u, updates)
        iterations = it + 1
    bar.close()

    verified = [
        float(_averaged(mechanism, space, objective, verify, x, *args)) for x in (u0, best_u)
    ]
    return OptimizationResult(
        initial=_values(specs, u0),
        values=_values(specs, best_u),
        objective=name,
        history=history,
        verified_initial=verified[0],
        verified_final=verified[1],
        improvement=(verified[0] - verified[1]) / abs(verified[0]),
        iterations=iterations,
        time=time.perf_counter() - started,
        solver=config,
        verify_solver=verify,
        parameters=list(specs),
    )


def _values(specs, u) -> dict[str, float]:
    return {q.name: float(q.from_unconstrained(u[i])) for i, q in enumerate(specs)}
