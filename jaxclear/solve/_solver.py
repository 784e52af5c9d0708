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
            for implicit ones). The PI gains for explicit methods were chosen on the three
            benchmark cases (benchmarks/bench_clearance.py, Tsit5, rtol 1e-6): against the integral
            controller 0/1 they took 5449/8958/49078 steps instead of 7154/9650/53822 (rejected
            1030/1827/7423 instead of 1694/2512/12239); 0.2/0.4, 0.1/0.5, 0.2/0.6 and 0/0.7 were
            within ±5 % of 0.1/0.7 in total steps. Indicative only: the same run's step count moves
            by up to ~30 % with rounding-level changes (e.g. case a: 5449 steps, 7185 with XLA's
            fusion emitters off), because the contact sequence is sensitive (docs/model.md §5b).
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

    def __check_init__(self):
        if self.method not in METHODS:
            raise ValueError(
                f"solver method {self.method!r} is unknown; choose one of {', '.join(METHODS)}."
            )
        for name in ("rtol", "atol", "newton_rtol", "newton_atol", "memory_speed"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise ValueError(f"SolverConfig.{name} must be a positive number, got {value!r}.")
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
steps in free flight are held below ~3.5 µs by that decay, which also makes it more accurate than
its tolerance asks; Lawson–Tsit5 is free of the limit and takes the accuracy the tolerance allows.
On the one-joint benchmark (README, "Accuracy" and "Performance"): at rtol 1e-6 it needs about half
Tsit5's steps, but over the first contacts its orbit was up to 0.44 µm off the converged one where
Tsit5's stayed within 0.13 µm; at rtol 1e-7 it is within 0.017 µm for about Tsit5's steps at 1e-6."""


def recommended_solver(mechanism) -> SolverConfig:
    """What ``solver="auto"`` picks for a mechanism: ``imex`` if a clearance joint has a friction law
    with internal states (LuGre), ``fast`` (Tsit5) otherwise.

    Measured on the benchmark slider–crank (benchmarks/bench_clearance.py and the default
    ``jaxclear run``, 2 revolutions at 5000 rpm, rtol 1e-6, one core): with LuGre the bristle state
    makes Tsit5 take ~5× more steps (three joints, hybrid law: Tsit5 run 1.52 s / 48 011 steps,
    KenCarp5 with ``DiagonalNewton`` 0.77 s / 9 424 steps, Kvaerno5 3.3 s; KenCarp5 with the
    closed-form stage solves of ``AffineKenCarp`` then took 0.477 s / 6 773 steps); without internal
    friction states Tsit5 is the fastest (ideal joints, Coulomb-type friction). Since each stage
    solves and evaluates in one pass (``dynamics._equations.implicit_stage``) KenCarp4's six
    stages beat KenCarp5's eight: L-N + LuGre, three joints (case c), run 0.236–0.331 s against
    0.270–0.361 s over rtol × 0.8 … 1.25 (7 955–10 988 and 7 455–9 804 steps); the default run
    0.521 s / 6 487 steps against 0.651 s / 6 002 steps, the pin-on-rod example 0.870 s against
    1.002 s. Over the first contacts both take the same branch of the first stick phase as before
    (docs/solvers.md, "Accuracy").
    """
    stiff = any(joint.friction_law.num_states > 0 for joint in mechanism.clearance_joints)
    return PRESETS["imex" if stiff else "fast"]


GRADIENT_MAX_STEPS = 200_000
"""Step budget of ``gradient_solver``: one revolution at 5000 rpm took 15 300 steps (one joint,
Coulomb-type friction) to about 115 000 (three joints, LuGre) at its settings. Reverse mode stores
every step (``checkpoints = max_steps - 1``); for longer solves raise both with
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

    Measured on the benchmark slider–crank at 5000 rpm, loss = squared residuals of slider x, slider
    acceleration and crank torque at 120 instants of one revolution (12 ms) against the ideal-joint
    responses, derivatives with respect to clearance, restitution, friction coefficient and rod mass
    (``python benchmarks/gradient_accuracy.py``; table in docs/differentiation.md, "Settings for
    gradients"):

    - Tolerance. diffrax differentiates the steps taken, not the step-size choices: the gradient is
      that of the discrete solve, and its error is not controlled. One joint (B), modified Coulomb:
      over the revolution Lawson–Tsit5 was within 0.33 % (reverse) and 0.14 % (forward) of converged
      central differences at rtol 1e-12, off by up to 2.1 % at 1e-11; Tsit5 at 1e-10 by up to 12 %.
      One joint, LuGre: Tsit5 (steps ≤ 1 µs) within 0.34 % at rtol 1e-12; at 1e-11 reverse mode was
      within 0.5 % but forward mode, on another step sequence, off by up to 14 %. The error of the
      discrete gradient changes erratically with the step sequence, so the margin is wanted.
    - Method. Taking the impact-memory decay exactly, Lawson–Tsit5 needs 15 300 steps per
      revolution at rtol 1e-12 where Tsit5 needs 48 700. With LuGre the stiff bristle state, not the
      memory, sets the step: Tsit5 took 31 300 steps (one joint); KenCarp5 at rtol 1e-11 took
      37 800 and was off by up to 2.5 %.
    - Reverse mode stores every step (``checkpoints = max_steps - 1``). With fewer checkpoints the
      backward pass recomputes runs of steps from the stored ones, in differently compiled code; on
      these solves the recomputed steps need not retrace the forward pass (a rounding-level change
      alters the step and contact sequence, docs/model.md §5b) and the gradient then depended on
      the count: one joint, Coulomb, loss over the first 4 ms, these settings, d loss / d clearance
      by forward mode −122 189, by reverse mode −122 139 with every step stored and −122 190, +1.2e6,
      −9.0e7, +5.7e5, −40 454 and −2.5e7 with 30, 300, 632, 1000, 3000 checkpoints and diffrax's
      default (632 here); converged central differences −1.22e5
      (``python benchmarks/gradient_accuracy.py --cases B-coulomb --windows 4 --checkpoints
      30,300,632,1000,3000,default,199999``).
    - Step bound with LuGre. Reverse mode through Tsit5 gave NaN gradients with LuGre friction over
      3 ms (finite over 0.5 ms), while forward mode and finite differences stayed finite; presumably
      a trial step far outside Tsit5's stability region (bristle and memory decay rates ~1e6 1/s),
      rejected in the forward pass, still contributes 0 · inf to the backward pass. Steps of at
      most 1 µs (2 µs too) removed the NaN; they cost 7 % more steps.

    Cost over one revolution relative to a primal solve at these settings (``python
    benchmarks/gradient_cost.py``, loaded 2-core machine): reverse mode 12–13.5× (one joint,
    Coulomb, Lawson–Tsit5) and 4.3–5.1× (three joints, LuGre, Tsit5) for 1 to 16 parameters;
    forward mode 5.5×, 10.4×, 33× (one joint) and 2.9×, 5.3×, 5.8× (three joints) for 1, 4, 16;
    gradient compilation 16–50 s.

    Over a revolution the three-joint mechanisms are chaotic: converged central differences of the
    loss exist only over the first 4–5 ms (docs/differentiation.md), though forward and reverse mode
    agree with each other over the whole revolution. Fit over windows (multiple shooting) there.

    Args:
        mechanism: the ``Mechanism`` to differentiate (its friction laws decide).

    Returns:
        A ``SolverConfig`` (static: build it once and reuse it).
    """
    stiff = any(joint.friction_law.num_states > 0 for joint in mechanism.clearance_joints)
    budget = dict(max_steps=GRADIENT_MAX_STEPS, checkpoints=GRADIENT_MAX_STEPS - 1)
    if stiff:
        return SolverConfig(method="tsit5", rtol=1e-12, atol=1e-15, dtmax=1e-6, **budget)
    # lawson-tsit5 needs impact-memory rows; ideal joints have none
    method = "lawson-tsit5" if mechanism.clearance_joints else "tsit5"
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
