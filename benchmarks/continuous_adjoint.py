"""A continuous adjoint over the stored forward solution, measured against jaxclear's sensitivities.

Usage:
    python benchmarks/continuous_adjoint.py [--windows 0.3,0.5,1,2,3] [--rtols 1e-6,1e-8]
        [--parameters 1,4,16] [--repeats 3] [--no-accuracy] [--no-cost] [--no-anatomy]

Issue 22, part 3, asks for reverse mode by a continuous adjoint (CVODES ASA, SciMLSensitivity's
InterpolatingAdjoint): solve the state forward and keep its dense output, then integrate the
adjoint λ and the parameter quadrature μ backwards over it, with their own error control,

    λ' = -(∂f/∂y)ᵀ λ,   μ' = -(∂f/∂θ)ᵀ λ,   λ(T) = ∂L/∂y(T),  μ(T) = 0,
    dL/dθ = μ(0) + (dy0/dθ)ᵀ λ(0),

so that its cost would not grow with the number of parameters p, as the forward sensitivities'
(``jax.grad`` of ``simulate``, docs/differentiation.md) does. This script builds that adjoint from
the public model (``jaxclear.dynamics.vector_field``, ``jaxclear.assemble``, the solver
settings' own ``make_solver``/``make_controller``) and diffrax, and measures whether it would pay,
before it is built into ``simulate``:

- the forward solve: Tsit5 at the "fast" preset's settings (what ``simulate``'s ``auto`` picks for
  this case), rtol as given (atol = rtol·1e-3, as the preset's 1e-6 / 1e-9), dense output kept;
- the backward solve: Tsit5 on (λ, μ) with the same tolerances, the state read from the forward
  solve's dense output at each stage; either stepping freely ("free") or made to stop at each of
  the forward solve's step times ("clipped": ``diffrax.ClipStepSizeController(step_ts=...)``, so
  that no backward step spans a contact that the forward solve resolved, and each lies inside one
  interpolating polynomial);
- the quantity: d(slider x)/dc at the end of each window, issue 22's case (``gradient_defaults``:
  one clearance joint B, L-N restitution 0.9, modified Coulomb 0.01, gravity on, 5000 rpm,
  c = 0.5 mm, journal centred), against central differences at ``gradient_solver`` settings;
- the cost over the longest window for p = 1, 4, 16 scalar leaves (the journal radius first, as
  in ``gradient_defaults``): the adjoint (forward with dense output, then backward) and
  ``jax.grad`` of ``simulate`` at the same settings, both against the primal solve in the same
  process;
- the per-call cost of a backward stage's parts (the vector field, the dense output, its JVP
  and VJP), in a ``lax.scan`` of sequential calls.

Public API only; prints figures, asserts nothing.
"""

import argparse
import resource
import time

import diffrax
import jax
import jax.numpy as jnp
from gradient_defaults import (
    NOMINAL,
    build,
    header,
    scaled_leaves,
    slider_x,
    timed,
)  # issue 22's case

import jaxclear
from jaxclear.dynamics import vector_field
from jaxclear.solve import solver_config

jax.config.update("jax_enable_x64", True)

SLIDER_X = 6  # slider x in the state (q first: crank, rod, slider; x, y, angle each)
MAX_STEPS = 20_000  # the dense output is stored for this many steps
START_GAP = 1e-9
"""The backward solve stops at START_GAP·t1, not at 0: at t = 0 the journal is exactly centred, where
the contact normal e/|e| has no derivative and the vector field's VJP is NaN (docs/differentiation.md,
"Limits"); the NaN in the last stage's error estimate would reject every step. What the
quadrature leaves out is START_GAP·t1 times a bounded integrand."""


def _config(rtol):
    return solver_config("fast", build(NOMINAL)).replace(rtol=rtol, atol=rtol * 1e-3)


def forward(make, theta, y0, t1, config, dense):
    """The forward solve of ``make(theta)`` from ``y0`` to ``t1``."""
    mechanism = make(theta)
    return diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field),
        config.make_solver(),
        0.0,
        t1,
        None,
        y0,
        args=mechanism,
        saveat=diffrax.SaveAt(t1=True, dense=dense),
        stepsize_controller=config.make_controller(mechanism.memory_rows),
        max_steps=MAX_STEPS,
        throw=False,
    )


def adjoint_gradient(make, theta, start, t1, config, clip):
    """d(slider x at t1)/dθ by the continuous adjoint from ``start`` = (y0, dy0/dθ) (``_start``);
    also each solve's steps."""
    y0, dy0 = start
    sol = forward(make, theta, y0, t1, config, dense=True)
    y_end = sol.ys[-1]
    lam = jnp.zeros_like(y_end).at[SLIDER_X].set(1.0)

    def rhs(t, state, args):
        lam, _ = state
        y = sol.evaluate(t)
        _, pull = jax.vjp(lambda y, theta: vector_field(t, y, make(theta)), y, theta)
        d_y, d_theta = pull(lam)
        return -d_y, -d_theta

    controller = config.make_controller()  # state-sized atol rows do not fit (λ, μ)
    if clip:  # stop at every forward step time (unused buffer entries are inf: moved to t1)
        grid = jnp.where(jnp.isfinite(sol.interpolation.ts), sol.interpolation.ts, t1)
        controller = diffrax.ClipStepSizeController(controller, step_ts=grid)
    back = diffrax.diffeqsolve(
        diffrax.ODETerm(rhs),
        config.make_solver(),
        t1,
        START_GAP * t1,
        None,
        (lam, jnp.zeros_like(theta)),
        stepsize_controller=controller,
        max_steps=4 * MAX_STEPS,
        throw=False,
    )
    lam0, mu0 = (x[-1] for x in back.ys)
    ok = (sol.result == diffrax.RESULTS.successful) & (back.result == diffrax.RESULTS.successful)
    steps = (sol.stats["num_accepted_steps"], back.stats["num_accepted_steps"])
    return jnp.where(ok, mu0 + dy0 @ lam0, jnp.nan), steps


def _start(make, theta):
    """The assembled start of ``make(theta)`` and its derivative dy0/dθ (p, N) by central
    differences of the (eager) assembly, relative step 1e-6 (absolute where θ_k = 0): the assembly is a smooth solve of
    the constraints, and it runs once, outside the timed gradient."""
    y0 = jaxclear.assemble(make(theta))
    rows = []
    for k in range(theta.size):
        h = 1e-6 * (abs(float(theta[k])) or 1.0)  # relative (absolute 1e-6 at 0)
        plus = jaxclear.assemble(make(theta.at[k].add(h)))
        minus = jaxclear.assemble(make(theta.at[k].add(-h)))
        rows.append((plus - minus) / (2 * h))
    return y0, jnp.stack(rows)


def accuracy(windows, rtols):
    tight = jaxclear.gradient_solver(build(NOMINAL))
    c0 = NOMINAL["clearance"]
    with_c = lambda c: build({**NOMINAL, "clearance": c[0]})  # noqa: E731
    reference = jax.jit(lambda c, t1: slider_x({**NOMINAL, "clearance": c}, t1, solver=tight))
    sensitivity = jax.jit(jax.grad(lambda c, t1: slider_x({**NOMINAL, "clearance": c}, t1)))
    print("\nd x_slider / d c, error % against central differences at gradient_solver (step 1e-6)")
    print("window   reference (FD 1e-5 / 1e-6)   grad of simulate (error-controlled sensitivities)")
    refs = {}
    for w in windows:
        t1 = jnp.asarray(w * 1e-3)
        fds = [
            float((reference(c0 * (1 + h), t1) - reference(c0 * (1 - h), t1)) / (2 * h * c0))
            for h in (1e-5, 1e-6)
        ]
        refs[w] = fds[-1]
        g = float(sensitivity(jnp.asarray(c0), t1))
        err = 100 * (g - fds[-1]) / abs(fds[-1])
        print(f"{w:5.2f} ms  {fds[0]:12.6g} / {fds[1]:12.6g}  {g:12.6g} ({err:+8.3f} %)")
    start = _start(with_c, jnp.asarray([c0]))
    for rtol in rtols:
        config = _config(rtol)
        runs = {
            clip: jax.jit(
                lambda c, t1, clip=clip: adjoint_gradient(with_c, c, start, t1, config, clip)
            )
            for clip in (False, True)
        }
        print(f"\ncontinuous adjoint, forward and backward at rtol {rtol:g}, atol {rtol * 1e-3:g}")
        print("window   free backward steps (err %)   steps fwd/back   clipped to forward steps")
        for w in windows:
            cells = []
            for clip in (False, True):
                g, (nf, nb) = runs[clip](jnp.asarray([c0]), jnp.asarray(w * 1e-3))
                g = float(g[0])
                err = 100 * (g - refs[w]) / abs(refs[w])
                cells.append(f"{g:12.6g} ({err:+9.3f} %)  {int(nf):5d}/{int(nb):5d}")
            print(f"{w:5.2f} ms  " + "   ".join(cells))


def cost(window, sizes, repeats, rtol):
    t1 = window * 1e-3
    config = _config(rtol)
    base = build(NOMINAL)
    names, scaled = scaled_leaves(base)
    primal = jax.jit(
        lambda: jaxclear.simulate(base, t1, num_points=2, solver=config).q[-1, SLIDER_X]
    )
    first, warm = timed(primal, repeats=repeats)
    y_base = jaxclear.assemble(base)
    own = jax.jit(
        lambda: forward(lambda _: base, None, y_base, t1, config, dense=False).ys[-1, SLIDER_X]
    )
    _, own_warm = timed(own, repeats=repeats)
    print(
        f"\ncost over {window} ms at rtol {rtol:g}: primal simulate {warm:.3f} s warm (first call "
        f"{first:.1f} s), the script's own forward solve {own_warm:.3f} s"
    )
    print(
        "p   adjoint warm  ratio  first  steps fwd/back    grad of simulate  ratio  first"
        "   apart (max |difference| / max |grad|)"
    )
    for p in sizes:
        if p > len(names):
            print(f"{p:<3d} only {len(names)} nonzero scalar leaves")
            continue
        scales = jnp.ones((p,))
        start = _start(scaled, scales)
        adj = jax.jit(lambda s, start=start: adjoint_gradient(scaled, s, start, t1, config, True))
        grad = jax.jit(
            jax.grad(
                lambda s: jaxclear.simulate(scaled(s), t1, num_points=2, solver=config).q[
                    -1, SLIDER_X
                ]
            )
        )
        a_first, a_warm = timed(adj, scales, repeats=repeats)
        g_first, g_warm = timed(grad, scales, repeats=repeats)
        g_adj, (nf, nb) = adj(scales)
        g_sim = grad(scales)
        apart = float(jnp.max(jnp.abs(g_adj - g_sim)) / jnp.max(jnp.abs(g_sim)))
        print(
            f"{p:<3d} {a_warm:9.3f} s {a_warm / warm:6.2f} {a_first:6.1f} s  {int(nf):5d}/{int(nb):5d}"
            f"   {g_warm:9.3f} s {g_warm / warm:6.2f} {g_first:6.1f} s   {apart:.1e}"
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process: {peak:.0f} MB")


def anatomy(window, repeats, rtol, calls=12_000):
    """Per-call cost of what a backward step evaluates: the vector field, the dense output, and
    the vector field's JVP and VJP at the dense output (p = 1), each in a ``lax.scan`` of
    ``calls`` sequential calls over the second half of the window."""
    t1 = window * 1e-3
    config = _config(rtol)
    names, scaled = scaled_leaves(build(NOMINAL))
    s = jnp.ones((1,))
    y0, _ = _start(scaled, s)
    sol = jax.jit(lambda s: forward(scaled, s, y0, t1, config, dense=True))(s)
    ts = jnp.linspace(0.5 * t1, t1, calls)

    def in_scan(body):  # each call depends on the last (no vectorising across calls)
        def run(s):
            def step(c, t):
                return c + 1e-30 * body(t, 1e-30 * c, s), None

            return jax.lax.scan(step, jnp.zeros_like(y0), ts)[0]

        return jax.jit(run)

    def jvp(t, c, s):
        y = sol.evaluate(t)
        return jax.jvp(lambda y: vector_field(t, y, scaled(s)), (y,), (jnp.ones_like(y) + c,))[1]

    def vjp(t, c, s):
        y = sol.evaluate(t)
        _, pull = jax.vjp(lambda y, s: vector_field(t, y, scaled(s)), y, s)
        return pull(jnp.ones_like(y) + c)[0]

    bodies = {
        "vector field": lambda t, c, s: vector_field(t, y0 + c, scaled(s)),
        "dense output": lambda t, c, s: sol.evaluate(t) + c,
        "vector field at the dense output": lambda t, c, s: vector_field(
            t, sol.evaluate(t) + c, scaled(s)
        ),
        "its JVP": jvp,
        "its VJP (the adjoint's)": vjp,
    }
    print(
        f"\nper call, {calls} calls in a scan over {window / 2:g}-{window:g} ms at rtol {rtol:g}:"
    )
    for name, body in bodies.items():
        _, warm = timed(in_scan(body), s, repeats=repeats)
        print(f"  {name:34s} {warm / calls * 1e6:7.2f} us")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--windows", default="0.3,0.5,1,2,3", help="comma list, ms")
    p.add_argument("--rtols", default="1e-6,1e-8", help="comma list (accuracy)")
    p.add_argument("--parameters", default="1,4,16", help="comma list of p (cost)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-accuracy", action="store_true")
    p.add_argument("--no-cost", action="store_true")
    p.add_argument("--no-anatomy", action="store_true")
    a = p.parse_args()
    windows = [float(w) for w in a.windows.split(",")]
    print(header())
    start = time.perf_counter()
    if not a.no_accuracy:
        accuracy(windows, [float(r) for r in a.rtols.split(",")])
    if not a.no_cost:
        cost(max(windows), [int(x) for x in a.parameters.split(",")], a.repeats, 1e-6)
    if not a.no_anatomy:
        anatomy(max(windows), a.repeats, 1e-6)
    print(f"\ntotal {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
