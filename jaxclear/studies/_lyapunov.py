"""Largest Lyapunov exponent: from the tangent linear system (``jax.jvp`` through the solve) and
from two nearby trajectories, both with renormalisation over intervals (docs/chaos.md).

The core (``flow_lyapunov``) works on any flow map ``step(y, t_a, t_b) -> y(t_b)``: the mechanism
(``largest_lyapunov``, ``two_trajectory_lyapunov``) and any diffrax ODE (``ODEFlow``), which is how
the tests check it on the Lorenz system and on a damped oscillator.

Estimate (Benettin et al. 1980): with a unit perturbation d_k at t_k = t_start + k Δ,

    g_k = ‖D_y φ(y_k; t_k, t_k + Δ) d_k‖,   d_{k+1} = D_y φ d_k / g_k,   λ_K = Σ_{k<K} ln g_k / (K Δ),

where D_y φ d is the tangent of the flow (``jax.jvp``) or the divided difference
(φ(y_k + ε d_k) − φ(y_k))/ε of two solves.
"""

import dataclasses
import math
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._core._checks import is_concrete
from ..dynamics._assembly import assemble_state
from ..dynamics._constraints import constraint_velocity, constraints
from ..model import Mechanism, with_parameters
from ..solve._simulate import assemble, initial_state, simulate
from ..solve._solver import SolverConfig, recommended_solver, solver_config
from ._engine import EnsembleSettings, chunk_size_of, map_members, swept_values

METHODS = ("tangent", "two_trajectory")

DEFAULT_SEPARATION = 1e-8
"""Initial distance of the two trajectories in ``flow_lyapunov``'s norm (``weights``): small
enough that the separation grows linearly over an interval, large enough that it is not lost in
the difference of the two solves' errors (≈ rtol·‖y‖ where their step sequences differ)."""

MECHANISM_SEPARATION = 1e-7
"""Initial distance of the two trajectories for a mechanism, m (and s·m/s for velocities, see
``mechanism_weights``). Measured on one clearance joint (B, hybrid law, LuGre, 5000 rpm; docs/chaos.md):
at rtol 1e-10 with intervals of a sixth of a revolution, 1e-7 and 1e-6 gave −461/s and −465/s
against the tangent's −481/s; 1e-8 and 1e-9 over whole revolutions were lost in the difference of
the two solves' errors (−39/s to −242/s against −489/s), which is ~1e-8 here even at rtol 1e-9."""

LYAPUNOV_RTOL = 1e-9
LYAPUNOV_ATOL = 1e-12
"""Tolerances of ``lyapunov_solver``. The tangent is that of the discrete solve, whose error is not
controlled (only the state's is). One clearance joint (B, hybrid law, LuGre) at 5000 rpm, 4 to 10
revolutions after 2 (docs/chaos.md, "What λ means with impacts"): KenCarp5 gave λ = +1957/s at
rtol 1e-7 (spurious), −142/s at 1e-8, −489/s at 1e-9 and −491/s at 1e-10; Tsit5 +2298/s at 1e-6
(spurious: in one 1 ms window the tangent grew 2.4e23-fold where finite differences of the same
solves grew 24-fold), −405/s at 1e-8."""

LYAPUNOV_MAX_STEPS = 1_000_000
"""Step budget per interval of ``lyapunov_solver`` (one revolution at 5000 rpm took 22 700 steps
of KenCarp5 at rtol 1e-10 with one clearance joint)."""


def lyapunov_solver(mechanism: Mechanism) -> SolverConfig:
    """Default settings of ``largest_lyapunov``: KenCarp5 with LuGre friction (the method its
    tolerances were measured with, above), else the method ``recommended_solver`` picks (Tsit5),
    at rtol ``LYAPUNOV_RTOL``, atol ``LYAPUNOV_ATOL``."""
    config = recommended_solver(mechanism)
    if config.imex:
        config = config.replace(method="kencarp5")
    return config.replace(rtol=LYAPUNOV_RTOL, atol=LYAPUNOV_ATOL, max_steps=LYAPUNOV_MAX_STEPS)


class LyapunovResult(eqx.Module):
    """The largest Lyapunov exponent and how its estimate converged.

    Attributes:
        exponent: the estimate over all intervals, λ_K, 1/s (per unit of the flow's time).
        spread: max |λ_k − λ_K| over the last half of the intervals, 1/s: the running estimate
            stayed within ``exponent ± spread`` there (a convergence indicator, not a confidence
            interval).
        running: the running estimate λ_k after each interval (K,), 1/s.
        log_growth: ln g_k of each interval (K,): the finite-time exponent of interval k times Δ.
        times: the end of each interval (K,), s.
        succeeded: every solve succeeded and every growth factor is finite and positive.
        y_final: the state at the last interval's end.
        method: ``"tangent"`` or ``"two_trajectory"``.
    """

    exponent: Float[Array, ""]
    spread: Float[Array, ""]
    running: Float[Array, " K"]
    log_growth: Float[Array, " K"]
    times: Float[Array, " K"]
    succeeded: Bool[Array, ""]
    y_final: Float[Array, " N"]
    method: str = eqx.field(static=True)


class ODEFlow(eqx.Module):
    """Flow map y(t_a) ↦ y(t_b) of a diffrax ODE, for ``flow_lyapunov``.

    Solved with forward-mode adjoint (``diffrax.ForwardMode``) so that ``jax.jvp`` goes through.

    Attributes:
        term: a ``diffrax.ODETerm`` (or any term).
        solver: a diffrax solver (default ``diffrax.Tsit5()``).
        rtol, atol: tolerances of the PID step-size controller (static).
        args: passed to the vector field (its array leaves are traced).
        max_steps: step budget per interval (static).
    """

    term: diffrax.AbstractTerm
    solver: diffrax.AbstractSolver = diffrax.Tsit5()
    rtol: float = eqx.field(static=True, default=1e-10)
    atol: float = eqx.field(static=True, default=1e-10)
    args: object = None
    max_steps: int = eqx.field(static=True, default=100_000)

    def __call__(self, y, t_a, t_b):
        sol = diffrax.diffeqsolve(
            self.term,
            self.solver,
            t_a,
            t_b,
            None,
            y,
            args=self.args,
            stepsize_controller=diffrax.PIDController(rtol=self.rtol, atol=self.atol),
            saveat=diffrax.SaveAt(t1=True),
            max_steps=self.max_steps,
            adjoint=diffrax.ForwardMode(),
            throw=False,
        )
        y_b = sol.ys[-1]  # pyright: ignore[reportOptionalSubscript]
        return jnp.where(sol.result == diffrax.RESULTS.successful, y_b, jnp.nan)


def _identity_projection(y, t, d):
    return d


def _scan(step, project, y0, t_start, transient, interval, weights, direction, method, eps, n):
    """λ estimate over ``n`` intervals after a transient (see the module docstring)."""
    if transient is not None:
        y0 = step(y0, t_start - transient, t_start)

    def norm(d):
        return jnp.sqrt(jnp.sum((weights * d) ** 2))

    d0 = project(y0, t_start, direction)
    d0 = d0 / norm(d0)

    def body(carry, k):
        y, d = carry
        t_a = t_start + k * interval
        t_b = t_a + interval
        if method == "tangent":
            y_b, d_b = jax.jvp(lambda y: step(y, t_a, t_b), (y,), (d,))
        else:
            pair = jax.vmap(lambda y: step(y, t_a, t_b))(jnp.stack([y, y + eps * d]))
            y_b, d_b = pair[0], (pair[1] - pair[0]) / eps
        d_b = project(y_b, t_b, d_b)
        growth = norm(d_b)
        return (y_b, d_b / growth), (jnp.log(growth), t_b)

    (y_final, _), (log_growth, times) = jax.lax.scan(body, (y0, d0), jnp.arange(n, dtype=float))
    running = jnp.cumsum(log_growth) / (interval * jnp.arange(1, n + 1, dtype=float))
    exponent = running[-1]
    spread = jnp.max(jnp.abs(running[n // 2 :] - exponent))
    succeeded = jnp.all(jnp.isfinite(log_growth)) & jnp.all(jnp.isfinite(y_final))
    return LyapunovResult(
        exponent=exponent,
        spread=spread,
        running=running,
        log_growth=log_growth,
        times=times,
        succeeded=succeeded,
        y_final=y_final,
        method=method,
    )


_SCAN = eqx.filter_jit(_scan)


def _intervals(t0, t1, transient, interval) -> tuple[int, float, float, float]:
    """Number of whole intervals in [t0 + transient, t1], and t0, transient, interval as floats
    (concrete times only)."""
    for name, value in (("t0", t0), ("t1", t1), ("transient", transient), ("interval", interval)):
        if not is_concrete(value):
            raise ValueError(
                f"{name} must be a concrete number (it fixes the number of intervals, a static "
                "shape); vmap over the mechanism's parameters instead."
            )
        if not np.isfinite(float(np.asarray(value))):
            raise ValueError(f"{name} must be finite, got {value!r}.")
    t0, t1, transient, interval = (float(np.asarray(x)) for x in (t0, t1, transient, interval))
    if not interval > 0:
        raise ValueError(f"interval must be > 0 s, got {interval}.")
    if not transient >= 0:
        raise ValueError(f"transient must be >= 0 s, got {transient}.")
    n = math.floor((t1 - t0 - transient) / interval * (1.0 + 1e-9) + 1e-9)
    if n < 1:
        raise ValueError(
            f"t1 = {t1} s leaves no interval of {interval} s after t0 + transient = {t0 + transient} s."
        )
    return n, t0, transient, interval


def _method(method: str) -> str:
    if method not in METHODS:
        raise ValueError(f"method {method!r} is unknown; choose one of {', '.join(METHODS)}.")
    return method


def flow_lyapunov(
    step: Callable[[Array, Array, Array], Array],
    y0: ArrayLike,
    t1: ArrayLike,
    *,
    interval: ArrayLike,
    t0: ArrayLike = 0.0,
    transient: ArrayLike = 0.0,
    method: str = "tangent",
    separation: float = DEFAULT_SEPARATION,
    weights=None,
    project: Callable[[Array, Array, Array], Array] | None = None,
    direction=None,
    seed: int = 0,
) -> LyapunovResult:
    """Largest Lyapunov exponent of any flow map ``step(y, t_a, t_b) -> y(t_b)``.

    After ``transient`` (one ``step`` from t0 to t0 + transient, no perturbation), a unit
    perturbation d (in the weighted norm ‖d‖ = ‖weights ⊙ d‖₂) is carried over K intervals of
    length Δ = ``interval`` (K = whole intervals in [t0 + transient, t1]) and renormalised after
    each; λ_K = Σ ln g_k / (K Δ) (module docstring).

    ``method="tangent"``: g_k from the tangent linear system, ``jax.jvp`` of ``step`` (``step``
    must support forward mode: diffrax with ``adjoint=diffrax.ForwardMode()``, as ``ODEFlow``).
    ``method="two_trajectory"``: from a second solve started ``separation`` away (in the weighted
    norm) along d, brought back to that distance after each interval; both solves run as one
    ``jax.vmap`` of ``step``.

    Jitted (``step``, ``project`` static: reuse the same objects to reuse the compilation; an
    ``eqx.Module`` step has its array leaves traced); differentiable and vmappable in ``y0`` and
    in the array leaves of a Module ``step``.

    Args:
        step: the flow map; returns NaN (or ``inf``) where a solve fails.
        y0: state at ``t0`` (N,).
        t1: end time.
        interval: renormalisation interval Δ (> 0). Short enough that a unit perturbation does not
            overflow (growth e^{λΔ}), long enough to keep the number of solves down.
        t0: start time. transient: time left out before the estimate starts (≥ 0).
        method: ``"tangent"`` or ``"two_trajectory"``.
        separation: initial distance of the second trajectory (``two_trajectory``).
        weights: (N,) non-negative weights of the norm (default ones). Rows of weight 0 are left
            out of the norm and of the initial perturbation (states slaved to the others).
        project: ``project(y, t, d) -> d``, a linear projection of perturbations onto the
            admissible ones at (y, t) (e.g. the tangent space of constraints), applied to the
            initial and every propagated perturbation. Default: none.
        direction: initial perturbation direction (N,) (default: a normal random vector on the
            weighted rows, from ``seed``), projected and normalised.
        seed: seed of the random initial direction.

    Returns:
        A ``LyapunovResult``.

    Raises:
        ValueError: non-concrete or inconsistent times, unknown ``method``, non-positive
            ``separation``, bad shapes of ``weights`` or ``direction``.
    """
    method = _method(method)
    n, t0, transient, interval = _intervals(t0, t1, transient, interval)
    y0 = jnp.asarray(y0, dtype=float)
    if y0.ndim != 1:
        raise ValueError(f"y0 must be a 1-D state vector, got shape {y0.shape}.")
    w = jnp.ones_like(y0) if weights is None else jnp.asarray(weights, dtype=float)
    if w.shape != y0.shape:
        raise ValueError(f"weights must have y0's shape {y0.shape}, got {w.shape}.")
    if is_concrete(w) and not (np.all(np.asarray(w) >= 0) and np.any(np.asarray(w) > 0)):
        raise ValueError("weights must be non-negative with at least one positive entry.")
    if not (isinstance(separation, int | float) and separation > 0):
        raise ValueError(f"separation must be a positive number, got {separation!r}.")
    if direction is None:
        direction = jax.random.normal(jax.random.PRNGKey(seed), y0.shape, dtype=float)
        direction = jnp.where(w > 0, direction, 0.0)
    direction = jnp.asarray(direction, dtype=float)
    if direction.shape != y0.shape:
        raise ValueError(f"direction must have y0's shape {y0.shape}, got {direction.shape}.")
    return _SCAN(
        step,
        _identity_projection if project is None else project,
        y0,
        jnp.asarray(t0 + transient, dtype=float),
        None if transient == 0.0 else jnp.asarray(transient, dtype=float),
        jnp.asarray(interval, dtype=float),
        w,
        direction,
        method,
        float(separation),
        n,
    )


# --- mechanisms -----------------------------------------------------------------------------------


class MechanismFlow(eqx.Module):
    """Flow map of a mechanism: ``simulate`` from t_a to t_b started at y (forward-mode adjoint,
    no extremes, no output grid to speak of). A failed solve gives NaN."""

    mechanism: Mechanism
    config: SolverConfig = eqx.field(static=True)

    def __call__(self, y, t_a, t_b):
        traj = simulate(
            self.mechanism,
            t_b,
            t0=t_a,
            ts=jnp.reshape(t_b, (1,)),  # only the end state is used
            solver=self.config,
            y0=y,
            # diffrax's tangent of the discrete flow (the exponent is defined on it, see
            # LYAPUNOV_RTOL); the error-controlled sensitivities cost several times more here
            adjoint="discrete-forward",
            extremes=False,
            throw=False,
        )
        return jnp.where(traj.succeeded, traj.y_final, jnp.nan)


def mechanism_weights(mechanism: Mechanism) -> Float[Array, " N"]:
    """Default norm weights for a mechanism's state y = (q, q̇, internal states): 1 on q (m, rad),
    1/|ω| on q̇ (s, so that a speed perturbation v counts as the displacement v/ω it makes in a
    radian of crank rotation; 1 without a constant-speed driver) and 0 on the internal states
    (impact memory, LuGre z: slaved to the motion, left out of the norm)."""
    n = mechanism.num_coordinates
    speed = None if mechanism.driver is None else mechanism.driver.constant_speed
    time_scale = 1.0 if speed is None else 1.0 / jnp.abs(speed)
    internal = mechanism.state_size - 2 * n
    return jnp.concatenate(
        [jnp.ones(n), jnp.full((n,), time_scale, dtype=float), jnp.zeros(internal)]
    )


class ConstraintProjection(eqx.Module):
    """Projection of a state perturbation onto the tangent space of the consistent states.

    Consistent states satisfy c(y, t) = (Φ(q, t), Φ̇(q, q̇, t)) = 0. A perturbation d is
    admissible when J d = 0, J = ∂c/∂(q, q̇); with W the norm weights on (q, q̇), the projection
    orthogonal in the weighted norm is d ← d − W⁻² Jᵀ (J W⁻² Jᵀ)⁻¹ J d. Internal-state rows are
    left as they are. The Baumgarte-stabilised equations keep c = 0 invariant, so the exact tangent
    flow keeps admissible perturbations admissible; projecting after each interval removes the
    numerical drift, which would otherwise decay at the stabilisation's rate.
    """

    mechanism: Mechanism
    weights: Float[Array, " N"]

    def __call__(self, y, t, d):
        m = self.mechanism
        n = m.num_coordinates

        def residual(x):
            q, qd = x[:n], x[n:]
            return jnp.concatenate([constraints(m, q, t), constraint_velocity(m, q, qd, t)])

        jac = jax.jacfwd(residual)(y[: 2 * n])
        inverse_square = 1.0 / self.weights[: 2 * n] ** 2
        scaled = jac * inverse_square[None, :]
        correction = scaled.T @ jnp.linalg.solve(scaled @ jac.T, jac @ d[: 2 * n])
        return d.at[: 2 * n].add(-correction)


def _mechanism_start(mechanism, y0, t0):
    if y0 is not None:
        y0 = jnp.asarray(y0, dtype=float)
        if y0.shape != (mechanism.state_size,):
            raise ValueError(f"y0 must have shape ({mechanism.state_size},), got {y0.shape}.")
        return y0
    if all(is_concrete(x) for x in jax.tree_util.tree_leaves(eqx.filter(mechanism, eqx.is_array))):
        return assemble(mechanism, float(np.asarray(t0)))
    q0, qd0, _, _ = assemble_state(mechanism, t0)
    return initial_state(mechanism, q0, qd0)


def largest_lyapunov(
    mechanism: Mechanism,
    t1: ArrayLike,
    *,
    interval: ArrayLike | None = None,
    t0: ArrayLike = 0.0,
    transient: ArrayLike = 0.0,
    solver: "str | SolverConfig | None" = None,
    y0: ArrayLike | None = None,
    method: str = "tangent",
    separation: float = MECHANISM_SEPARATION,
    project: bool = True,
    weights=None,
    seed: int = 0,
) -> LyapunovResult:
    """Largest Lyapunov exponent of a mechanism's response, from the tangent linear system.

    ``jax.jvp`` of ``simulate(mechanism, t + Δ, t0=t, y0=y, adjoint="discrete-forward")`` carries a
    perturbation of the state over each interval Δ (``flow_lyapunov``); the perturbation is kept
    on the consistent states (``ConstraintProjection``) and measured in the norm of
    ``mechanism_weights``. A periodic (stable) response gives λ < 0, a chaotic one λ > 0; the
    time scale is 1/λ (docs/chaos.md, also on what λ means with impacts and how it depends on the
    solver tolerance).

    Args:
        mechanism: a ``Mechanism`` (constant-speed driver for the default ``interval``).
        t1: end time, s.
        interval: renormalisation interval, s (default one crank period).
        t0: start time, s. transient: start-up time left out, s (e.g. a few crank periods).
        solver: as in ``simulate``; default ``lyapunov_solver(mechanism)`` (rtol 1e-9). The
            tangent is that of the discrete solve: at the usual rtol 1e-6 it can grow without
            bound where an explicit step runs at its stability limit, giving a large spurious
            positive exponent (``LYAPUNOV_RTOL``). Check that a tighter tolerance gives the
            same estimate.
        y0: state at ``t0`` (default: assembled).
        method: ``"tangent"`` or ``"two_trajectory"`` (``two_trajectory_lyapunov``).
        separation: initial distance of the two trajectories (``two_trajectory`` only).
        project: keep perturbations on the consistent states. ``False`` lets the constraint
            directions in: they decay at the Baumgarte rate (−α for α = β), which then bounds the
            estimate from below; a mechanism without degrees of freedom (all joints ideal, crank
            driven) has only those and needs ``project=False``.
        weights: norm weights (N,) (default ``mechanism_weights``).
        seed: seed of the random initial direction (on q, q̇).

    Returns:
        A ``LyapunovResult`` (exponent in 1/s; multiply by the crank period for the exponent per
        revolution).

    Raises:
        ValueError: no interval and no constant-speed driver, the arguments of ``flow_lyapunov``,
            ``project`` for a mechanism without degrees of freedom.
        ModelError, AssemblyError: eager assembly of ``y0`` failed.
    """
    if interval is None:
        speed = None if mechanism.driver is None else mechanism.driver.constant_speed
        if speed is None or not is_concrete(speed):
            raise ValueError(
                "interval: give the renormalisation interval, s (the default, one crank period, "
                "needs a concrete constant driver speed)."
            )
        interval = 2.0 * math.pi / abs(float(speed))
    if project and mechanism.degrees_of_freedom <= 0:
        raise ValueError(
            "project=True: this mechanism has no degrees of freedom (every joint ideal, the crank "
            "driven), so no perturbation keeps the constraints; use project=False to measure the "
            "decay of constraint violations under Baumgarte stabilisation (−α for α = β)."
        )
    config = lyapunov_solver(mechanism) if solver is None else solver_config(solver, mechanism)
    y_start = _mechanism_start(mechanism, y0, t0)
    w = mechanism_weights(mechanism) if weights is None else jnp.asarray(weights, dtype=float)
    return flow_lyapunov(
        MechanismFlow(mechanism, config),
        y_start,
        t1,
        interval=interval,
        t0=t0,
        transient=transient,
        method=method,
        separation=separation,
        weights=w,
        project=ConstraintProjection(mechanism, w) if project else None,
        seed=seed,
    )


def two_trajectory_lyapunov(
    mechanism: Mechanism,
    t1: ArrayLike,
    *,
    separation: float = MECHANISM_SEPARATION,
    **options,
) -> LyapunovResult:
    """Largest Lyapunov exponent from two nearby trajectories (the classic estimate), renormalised
    to ``separation`` after each interval: the cross-check of ``largest_lyapunov``, which it
    calls with ``method="two_trajectory"`` (same arguments). The separation must stay above the
    difference of the two solves' errors (~1e-8 on the benchmark at rtol 1e-9) through each
    interval: with a contracting (periodic) response use short intervals, e.g. a sixth of a
    revolution (docs/chaos.md)."""
    return largest_lyapunov(
        mechanism, t1, separation=separation, method="two_trajectory", **options
    )


# --- over the values of a parameter ---------------------------------------------------------------


@dataclasses.dataclass
class LyapunovSweep:
    """The largest Lyapunov exponent for each value of one parameter (``lyapunov_sweep``).

    Attributes:
        parameter: the swept parameter's name (``jaxclear.parameter_names``).
        values: its values (N,), SI units.
        exponents: λ per value (N,), 1/s; NaN where the estimate failed.
        spread: the convergence indicator of each estimate (N,), 1/s (``LyapunovResult.spread``).
        succeeded: (N,) every solve of the estimate succeeded.
        interval: the renormalisation interval, s. transient: the start-up left out, s.
        t1: the end of every estimate, s.
    """

    parameter: str
    values: np.ndarray
    exponents: np.ndarray
    spread: np.ndarray
    succeeded: np.ndarray
    interval: float
    transient: float
    t1: float


def _lyapunov_member(v, mechanism, name, t1, interval, t0, transient, config, method, project):
    m = with_parameters(mechanism, {name: v[0]})
    r = largest_lyapunov(
        m,
        t1,
        interval=interval,
        t0=t0,
        transient=transient,
        solver=config,
        method=method,
        project=project,
    )
    ok = r.succeeded & jnp.isfinite(r.exponent)
    return jnp.where(ok, r.exponent, jnp.nan), jnp.where(ok, r.spread, jnp.nan), ok


def lyapunov_sweep(
    mechanism: Mechanism,
    name: str,
    values,
    t1: float,
    *,
    interval: float | None = None,
    t0: float = 0.0,
    transient: float = 0.0,
    solver: "str | SolverConfig | None" = None,
    method: str = "tangent",
    project: bool = True,
    settings: EnsembleSettings = EnsembleSettings(),
) -> LyapunovSweep:
    """``largest_lyapunov`` for each value of one named parameter, in vmapped chunks
    (``map_members``, as ``bifurcation_points``).

    Every value uses the same interval, transient and end time in seconds (by default one crank
    period of ``mechanism`` as given): over an ``rpm`` sweep the interval is then not each value's
    period, which the estimate does not need (λ is a rate per second).

    Args:
        mechanism: the base mechanism (concrete values).
        name: the parameter (``jaxclear.parameter_names``), e.g. ``"B.clearance"``, ``"rpm"``.
        values: its values (N,), SI units (``rpm`` in rev/min).
        t1: end time, s.
        interval: renormalisation interval, s (default the base mechanism's crank period).
        t0, transient: start and start-up time left out, s.
        solver: default ``lyapunov_solver(mechanism)`` (rtol 1e-9; see ``largest_lyapunov``).
        method: ``"tangent"`` or ``"two_trajectory"``. project: as in ``largest_lyapunov``.
        settings: ``chunk_size`` (values per vectorised solve, at most the number of values) and
            ``devices`` (to split each chunk over) of an ``EnsembleSettings``; its other fields
            are not used here.

    Returns:
        A ``LyapunovSweep``.

    Raises:
        ValueError: an unknown ``name``, ``values`` not 1-D and finite, no ``interval`` without a
            constant-speed driver, and the errors of ``largest_lyapunov``'s arguments.
    """
    values = swept_values(mechanism, name, values)
    if interval is None:
        speed = None if mechanism.driver is None else mechanism.driver.constant_speed
        if speed is None or not is_concrete(speed) or float(speed) == 0.0:
            raise ValueError(
                "interval: give the renormalisation interval, s (the default, one crank period, "
                "needs a constant driver speed)."
            )
        interval = 2.0 * math.pi / abs(float(speed))
    _intervals(t0, t1, transient, interval)  # argument errors before any compilation
    config = lyapunov_solver(mechanism) if solver is None else solver_config(solver, mechanism)
    exponents, spread, ok = map_members(
        _lyapunov_member,
        (
            mechanism,
            name,
            float(t1),
            float(interval),
            float(t0),
            float(transient),
            config,
            _method(method),
            bool(project),
        ),
        values[:, None],
        settings=dataclasses.replace(
            settings, chunk_size=min(chunk_size_of(settings, "lockstep"), values.size)
        ),
    )
    return LyapunovSweep(
        parameter=name,
        values=values,
        exponents=np.asarray(exponents),
        spread=np.asarray(spread),
        succeeded=np.asarray(ok, dtype=bool),
        interval=float(interval),
        transient=float(transient),
        t1=float(t1),
    )
