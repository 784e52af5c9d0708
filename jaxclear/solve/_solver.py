"""Solver settings: a frozen, static ``SolverConfig`` and named presets.

Changing any setting recompiles (they are static), so build one config and reuse it.
"""

import dataclasses

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._imex import AffineKenCarp
from ._lawson import LawsonTsit5
from ._root_finder import DiagonalNewton

EXPLICIT = {
    "tsit5": diffrax.Tsit5,
    "dopri5": diffrax.Dopri5,
    "dopri8": diffrax.Dopri8,
    "bosh3": diffrax.Bosh3,
}
IMPLICIT = {
    "kvaerno3": diffrax.Kvaerno3,
    "kvaerno4": diffrax.Kvaerno4,
    "kvaerno5": diffrax.Kvaerno5,
}
IMEX = {"kencarp3": diffrax.KenCarp3, "kencarp4": diffrax.KenCarp4, "kencarp5": diffrax.KenCarp5}
IMEX_ORDER = {"kencarp3": 3, "kencarp4": 4, "kencarp5": 5}  # AffineKenCarp variant of each
EXPONENTIAL = {"lawson-tsit5": LawsonTsit5}
METHODS = tuple(EXPLICIT) + tuple(EXPONENTIAL) + tuple(IMPLICIT) + tuple(IMEX)


SENSITIVITY_RTOL = 1e-8
"""Loosest relative tolerance of the sensitivity solve by default (``SolverConfig.sensitivity_rtol``).
Measured with ``python benchmarks/gradient_accuracy.py --cases B-coulomb --only-default --rtols
1e-7,1e-8,1e-9`` (docs/differentiation.md): the derivative of the loss over a revolution was off
by up to 26 % at rtol 1e-6, 2.2 % at 1e-7 and 0.5 % at 1e-8 (the central differences' own spread
there), no better at 1e-9."""


class SolverConfig(eqx.Module):
    """Time-integration settings (all static).

    Attributes:
        method: solver name, one of ``METHODS`` (explicit: tsit5, dopri5, dopri8, bosh3;
            exponential: lawson-tsit5, Tsit5 with the impact-memory decay taken exactly
            (``jaxclear.solve._lawson``);
            implicit, for stiff problems: kvaerno3, kvaerno4, kvaerno5; IMEX, implicit only in the
            stiff internal states (LuGre z, impact memory relaxation): kencarp3, kencarp4, kencarp5).
        rtol, atol: error-control tolerances of the adaptive step (mixed units: m, rad, m/s, ...).
        max_steps: step budget; contact runs need tens of thousands of steps.
        dt0: initial step, s (``None``: chosen by diffrax).
        dtmax: largest step, s (``None``: unbounded).
        pcoeff, icoeff: PID controller gains (``None``: 0.1/0.7 for explicit methods, 0.3/0.3
            for implicit ones; how the explicit gains were chosen: docs/solvers.md, "Choosing the
            method").
        newton_rtol, newton_atol: tolerances of the implicit stage equations (chord iteration).
            Loose values (≈√rtol) avoid step-size collapse at impacts (docs/model.md §5b).
        checkpoints: reverse-mode checkpoints (``reverse_adjoint``): how many solver steps' states
            ``jax.grad`` through the solve stores. ``None``: diffrax's default, about
            √(2 max_steps), which recomputes steps between checkpoints in the backward pass; on
            these contact solves the recomputed steps need not retrace the forward pass, and the
            gradient then moved with the count (``gradient_solver`` gives the figures). A count of
            at least the steps taken (``gradient_solver``: ``max_steps - 1``) stores every step:
            no recomputation, memory ∝ ``checkpoints``.
        memory_speed: for exponential methods, which integrate the impact memory as the offset
            u = m − δ̇: reference speed of those rows, m/s, controlled with absolute tolerance
            ``atol + rtol * memory_speed``. u is ~0 in free flight and its error is an error in
            the latched impact speed, so it is measured against a typical approach speed rather
            than against |u| (with ``atol`` alone the offset rows, not the motion, set the step
            size in contact).
        sensitivity_error_control: derivatives (``jax.jvp``/``jax.grad`` of ``simulate``) integrate
            the tangents with the state and let the step-size controller's error norm cover them
            (``jaxclear.solve._sensitivity``, docs/differentiation.md). ``False`` leaves them out
            of the norm, as diffrax's own differentiation does: for checks only, the derivative's
            error is then not controlled.
        sensitivity_rtol: relative tolerance of that sensitivity solve (state and tangents; its
            absolute tolerances scale with it: ``atol * sensitivity_rtol / rtol``). ``None``
            (default): ``min(rtol, SENSITIVITY_RTOL)``, 1e-8 at the default rtol 1e-6, where
            derivatives over a revolution match converged central differences; at rtol 1e-6
            they were off by up to 26 % (docs/differentiation.md, "How the derivative's error
            follows the tolerance"). Pass ``sensitivity_rtol=rtol`` for derivatives at the
            solve's own tolerance: about half the steps, right over short windows only.
        sensitivity_method: method of that sensitivity solve. ``None`` (default): the solve's
            own, except that ``tsit5`` becomes ``lawson-tsit5`` when the mechanism has impact
            memories (the same tableau with the memory's decay taken exactly: not held to
            ~3.5 µs steps in free flight, it took 10 958 steps over a revolution of the
            one-joint Coulomb case at rtol 1e-8 against Tsit5's 18 581, as accurate;
            docs/differentiation.md).
        sensitivity_slip_steps: that sensitivity solve also rejects a step that jumps a
            Coulomb-type friction law's slip reversal in contact without a stage inside the band
            where the force turns over: the state's error stays small there, but the tangents lose
            the force jump's kick (``solve._sensitivity.SlipResolving``; docs/differentiation.md,
            "Slip reversals in contact"). ``False``: for checks only.
    """

    method: str = eqx.field(static=True, default="kvaerno5")
    rtol: float = eqx.field(static=True, default=1e-6)
    atol: float = eqx.field(static=True, default=1e-9)
    max_steps: int = eqx.field(static=True, default=200_000)
    dt0: float | None = eqx.field(static=True, default=None)
    dtmax: float | None = eqx.field(static=True, default=None)
    pcoeff: float | None = eqx.field(static=True, default=None)
    icoeff: float | None = eqx.field(static=True, default=None)
    newton_rtol: float = eqx.field(static=True, default=1e-3)
    newton_atol: float = eqx.field(static=True, default=1e-6)
    memory_speed: float = eqx.field(static=True, default=1.0)
    checkpoints: int | None = eqx.field(static=True, default=None)
    sensitivity_error_control: bool = eqx.field(static=True, default=True)
    sensitivity_rtol: float | None = eqx.field(static=True, default=None)
    sensitivity_method: str | None = eqx.field(static=True, default=None)
    sensitivity_slip_steps: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        if self.method not in METHODS:
            raise ValueError(
                f"solver method {self.method!r} is unknown; choose one of {', '.join(METHODS)}."
            )
        for name in ("rtol", "atol", "newton_rtol", "newton_atol", "memory_speed"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise ValueError(f"SolverConfig.{name} must be a positive number, got {value!r}.")
        if self.sensitivity_rtol is not None and not (
            isinstance(self.sensitivity_rtol, int | float) and self.sensitivity_rtol > 0
        ):
            raise ValueError(
                "SolverConfig.sensitivity_rtol must be None (default: min(rtol, 1e-8)) or a "
                f"positive number, got {self.sensitivity_rtol!r}."
            )
        if self.sensitivity_method is not None and self.sensitivity_method not in METHODS:
            raise ValueError(
                f"SolverConfig.sensitivity_method {self.sensitivity_method!r} is unknown; choose "
                f"None (the solve's own) or one of {', '.join(METHODS)}."
            )
        if not (isinstance(self.max_steps, int) and self.max_steps > 0):
            raise ValueError(
                f"SolverConfig.max_steps must be a positive integer, got {self.max_steps!r}."
            )
        if self.checkpoints is not None and not (
            isinstance(self.checkpoints, int) and 0 < self.checkpoints <= self.max_steps
        ):
            raise ValueError(
                f"SolverConfig.checkpoints must be None or an integer in [1, max_steps={self.max_steps}], "
                f"got {self.checkpoints!r}."
            )

    @property
    def implicit(self) -> bool:
        return self.method in IMPLICIT or self.method in IMEX

    @property
    def imex(self) -> bool:
        return self.method in IMEX

    @property
    def exponential(self) -> bool:
        return self.method in EXPONENTIAL

    def replace(self, **changes) -> "SolverConfig":
        """Copy with some settings changed."""
        return dataclasses.replace(self, **changes)

    def sensitivity_settings(self, memory: bool = True) -> "SolverConfig":
        """The settings of the error-controlled sensitivity solve that derivatives of ``simulate``
        run (``jax.jvp``/``jax.grad`` with the default adjoints): rtol ``sensitivity_rtol``
        (default ``min(rtol, SENSITIVITY_RTOL)``), atol scaled with it, method
        ``sensitivity_method`` (default: the own, ``tsit5`` → ``lawson-tsit5`` if ``memory``, i.e.
        the mechanism has impact memories), the rest unchanged."""
        rtol = self.sensitivity_rtol
        if rtol is None:
            rtol = min(self.rtol, SENSITIVITY_RTOL)
        method = self.sensitivity_method
        if method is None:
            method = "lawson-tsit5" if self.method == "tsit5" and memory else self.method
        if rtol == self.rtol and method == self.method:
            return self
        return self.replace(
            rtol=rtol,
            atol=self.atol * rtol / self.rtol,
            method=method,
            sensitivity_rtol=rtol,
            sensitivity_method=method,
        )

    def reverse_adjoint(self) -> diffrax.RecursiveCheckpointAdjoint:
        """The reverse-mode adjoint for these settings, to pass as ``simulate(..., adjoint=...)``
        under ``jax.grad``/``jax.vjp``/``jax.jacrev``:
        ``diffrax.RecursiveCheckpointAdjoint(checkpoints=self.checkpoints)``."""
        return diffrax.RecursiveCheckpointAdjoint(checkpoints=self.checkpoints)

    def make_solver(
        self, num_explicit: int | None = None, decay=None, memory_rows=None, stage=None
    ):
        """The diffrax solver.

        ``num_explicit``: for IMEX methods, the number of leading state components (q, q̇) that the
        stiff part leaves alone. With ``stage`` too (``stage(t, P, γh, args) -> (Y, f(Y), f_I(Y))``,
        the closed-form stage solve and both evaluations, ``dynamics._equations.implicit_stage``)
        the result is ``AffineKenCarp`` (its terms are the full vector field); with
        ``num_explicit`` alone, diffrax's KenCarp whose stage equations ``DiagonalNewton`` solves
        (terms: a ``MultiTerm`` of the non-stiff and stiff parts); otherwise ``diffrax.VeryChord``.
        ``decay``, ``memory_rows``: for exponential methods, ``decay(t, y, args)``, the diagonal
        decay rates of the rows marked in the boolean mask ``memory_rows``."""
        if self.method in EXPONENTIAL:
            if decay is None or memory_rows is None:
                raise ValueError(f"solver method {self.method!r} needs decay= and memory_rows=.")
            return EXPONENTIAL[self.method](
                decay, tuple(int(i) for i in np.flatnonzero(memory_rows))
            )
        if self.imex and num_explicit is not None and stage is not None:
            return AffineKenCarp(stage, num_explicit, IMEX_ORDER[self.method])
        if self.imex and num_explicit is not None:
            root = DiagonalNewton(
                rtol=self.newton_rtol, atol=self.newton_atol, num_explicit=num_explicit, affine=True
            )
            return IMEX[self.method](root_finder=root)
        if self.implicit:
            root = diffrax.VeryChord(rtol=self.newton_rtol, atol=self.newton_atol)
            return {**IMPLICIT, **IMEX}[self.method](root_finder=root)
        return EXPLICIT[self.method]()

    def make_controller(self, memory_rows=None):
        """The PID step-size controller. ``memory_rows``: boolean mask of the state's impact-memory
        offset rows (``Mechanism.memory_rows``), which get the absolute tolerance
        ``atol + rtol * memory_speed``."""
        default_p, default_i = (0.3, 0.3) if self.implicit else (0.1, 0.7)
        atol = self.atol
        if memory_rows is not None and np.any(memory_rows):
            atol = jnp.asarray(
                np.where(memory_rows, self.atol + self.rtol * self.memory_speed, self.atol)
            )
        return diffrax.PIDController(
            rtol=self.rtol,
            atol=atol,
            pcoeff=default_p if self.pcoeff is None else self.pcoeff,
            icoeff=default_i if self.icoeff is None else self.icoeff,
            dtmax=self.dtmax,
        )


PRESETS = {
    "robust": SolverConfig(method="kvaerno5"),
    "fast": SolverConfig(method="tsit5"),
    "imex": SolverConfig(method="kencarp4"),
    "accurate": SolverConfig(
        method="kvaerno5", rtol=1e-9, atol=1e-12, newton_rtol=1e-5, newton_atol=1e-9
    ),
}
"""Named presets: ``robust`` (L-stable implicit Kvaerno5 on the whole state), ``imex`` (KenCarp4:
implicit only in the declared stiff internal states — LuGre z, impact-memory relaxation — explicit
elsewhere; the fastest choice with LuGre friction, see ``recommended_solver``), ``fast`` (explicit
Tsit5, best for ideal joints and frictionless/Coulomb contact), ``accurate`` (Kvaerno5 with tight
tolerances).

Not a preset: method ``lawson-tsit5`` (Tsit5 with the impact-memory decay taken exactly). Tsit5's
steps in free flight are limited by that decay, which also makes it more accurate than its
tolerance asks; Lawson–Tsit5 is free of the limit and takes the accuracy the tolerance allows
(fewer steps at the same rtol, a larger error: docs/solvers.md, "Accuracy")."""


def recommended_solver(mechanism) -> SolverConfig:
    """What ``solver="auto"`` picks for a mechanism: ``imex`` if a clearance joint has a friction law
    with internal states (LuGre) or the mechanism has a translational clearance joint, ``fast``
    (Tsit5) otherwise.

    With LuGre the bristle state makes Tsit5 take several times more steps than the IMEX methods,
    which are implicit in that state only; the four corner impact memories of a translational
    clearance joint do the same (2.4x the steps per revolution with Tsit5); otherwise Tsit5 is the
    fastest. The measurements behind the choice: docs/solvers.md, "Choosing the method".
    """
    stiff = any(
        joint.friction_law.num_states > 0
        for joint in (*mechanism.clearance_joints, *mechanism.translational_clearance_joints)
    )
    return PRESETS["imex" if stiff or mechanism.translational_clearance_joints else "fast"]


GRADIENT_MAX_STEPS = 200_000
"""Step budget of ``gradient_solver``: one revolution at 5000 rpm at its settings fits (step counts:
docs/differentiation.md, "Settings for gradients"). Reverse mode stores every step
(``checkpoints = max_steps - 1``); for longer solves raise both with
``config.replace(max_steps=n, checkpoints=n - 1)``."""


def gradient_solver(mechanism) -> SolverConfig:
    """Settings for solves that are differentiated (``jax.grad``, ``jax.jacfwd``), chosen by
    measurement so that gradients match converged central differences.

    Pass ``adjoint=config.reverse_adjoint()`` to ``simulate`` for reverse mode (it stores every
    step, see below) and ``adjoint="forward"`` for ``jax.jacfwd``/``jax.jvp``.

    - No friction states (ideal joints, Coulomb-type friction): ``lawson-tsit5`` (``tsit5`` for
      ideal joints) at rtol 1e-12, atol 1e-15.
    - Friction with internal states (LuGre): ``tsit5`` at rtol 1e-12, atol 1e-15, steps of at
      most 1 µs.

    Why these settings, with the measurements (``python benchmarks/gradient_accuracy.py``,
    ``python benchmarks/gradient_cost.py``): docs/differentiation.md, "Settings for gradients".
    In short: diffrax differentiates the steps taken, not the step-size choices, so the gradient's
    error is not controlled and the margin of rtol 1e-12 is wanted; reverse mode stores every step,
    because with fewer checkpoints the recomputed steps need not retrace the forward pass; with
    LuGre, steps of at most 1 µs keep reverse mode finite. Over a revolution the three-joint
    mechanisms are chaotic: converged central differences exist only over the first milliseconds;
    fit over windows (multiple shooting) there.

    Args:
        mechanism: the ``Mechanism`` to differentiate (its friction laws decide).

    Returns:
        A ``SolverConfig`` (static: build it once and reuse it).
    """
    stiff = any(
        joint.friction_law.num_states > 0
        for joint in (*mechanism.clearance_joints, *mechanism.translational_clearance_joints)
    )
    budget = dict(max_steps=GRADIENT_MAX_STEPS, checkpoints=GRADIENT_MAX_STEPS - 1)
    if stiff:
        return SolverConfig(method="tsit5", rtol=1e-12, atol=1e-15, dtmax=1e-6, **budget)
    # lawson-tsit5 needs impact-memory rows; ideal joints have none
    method = (
        "lawson-tsit5"
        if mechanism.clearance_joints or mechanism.translational_clearance_joints
        else "tsit5"
    )
    return SolverConfig(method=method, rtol=1e-12, atol=1e-15, **budget)


def solver_config(solver: "str | SolverConfig", mechanism=None) -> SolverConfig:
    """A SolverConfig from ``"auto"`` (needs ``mechanism``), a preset name, a method name or a config."""
    if isinstance(solver, SolverConfig):
        return solver
    if solver == "auto":
        if mechanism is None:
            raise ValueError(
                "solver 'auto' needs the mechanism to choose; pass a preset or method name instead."
            )
        return recommended_solver(mechanism)
    if solver in PRESETS:
        return PRESETS[solver]
    if solver in METHODS:
        return SolverConfig(method=solver)
    raise ValueError(
        f"solver {solver!r} is unknown; choose 'auto', a preset ({', '.join(PRESETS)}) or a method ({', '.join(METHODS)})."
    )
