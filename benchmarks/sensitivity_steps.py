"""Where the error-controlled sensitivity solve's steps go: accepted and rejected steps of
``jax.jvp`` of ``simulate`` under variants of its settings, against the primal solve's.

Usage:
    python benchmarks/sensitivity_steps.py [--windows 3,12] [--repeats 3] [--reference]

Issue 22's case (one clearance joint B, Lankarani–Nikravesh c_e = 0.9, modified Coulomb
μ = 0.01, gravity on, 5000 rpm, journal centred, c = 0.5 mm); the derivative is d x_slider / d c
at the end of each window (ms). Variants (all through ``SolverConfig``, public settings):

- ``primal``: ``simulate`` at its defaults (solver ``"auto"``), no derivative;
- ``default``: ``jax.jvp`` at the defaults (the sensitivity solve: Lawson–Tsit5 at rtol 1e-8,
  tangents in the step-size controller's norm, slip reversals resolved);
- ``state-norm``: ``sensitivity_error_control=False`` (the same solve with the state's error
  alone in the norm: diffrax's behaviour, for comparison; its derivative is not controlled);
- ``no-slip-steps``: ``sensitivity_slip_steps=False``;
- ``pid-0.3-0.4``: PID gains pcoeff 0.3, icoeff 0.4 (default 0.1 / 0.7);
- ``dopri8``, ``dopri5``: ``sensitivity_method`` instead of Lawson–Tsit5;
- ``rtol-1e-7``: ``sensitivity_rtol=1e-7``.

Printed per window and variant: steps (total, accepted, rejected), the derivative, the warm time
(best of ``--repeats``) and its ratio to the primal solve's. ``--reference`` adds the central
difference at ``gradient_solver`` settings (relative step 1e-6). Public API only; prints figures,
asserts nothing.
"""

import argparse
import dataclasses
import subprocess
import time

import jax
import jax.numpy as jnp

jax.config.update("jax_enable_x64", True)

import jaxclear  # noqa: E402
from jaxclear.contact import LankaraniNikravesh  # noqa: E402
from jaxclear.friction import ModifiedCoulomb  # noqa: E402

CLEARANCE = 5e-4
VARIANTS = {
    "default": {},
    "state-norm": {"sensitivity_error_control": False},
    "no-slip-steps": {"sensitivity_slip_steps": False},
    "pid-0.3-0.4": {"pcoeff": 0.3, "icoeff": 0.4},
    "dopri8": {"sensitivity_method": "dopri8"},
    "dopri5": {"sensitivity_method": "dopri5"},
    "rtol-1e-7": {"sensitivity_rtol": 1e-7},
}


def mechanism(c):
    return jaxclear.mechanisms.slider_crank(
        rpm=5000.0,
        gravity=True,
        clearance_joints="B",
        clearance=c,
        contact_law=LankaraniNikravesh(),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )


def response(c, t1, solver):
    traj = jaxclear.simulate(mechanism(c), t1, num_points=2, solver=solver)
    steps = jnp.stack([traj.num_steps, traj.num_accepted_steps, traj.num_rejected_steps])
    return traj.q[-1, 6], steps


def best_time(fn, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return min(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--windows", default="3,12", help="ms, comma list")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--reference", action="store_true")
    args = parser.parse_args()
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    print(f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, commit {commit}")
    base = jaxclear.recommended_solver(mechanism(CLEARANCE))
    c = jnp.asarray(CLEARANCE)
    for window in [float(w) for w in args.windows.split(",")]:
        t1 = window * 1e-3
        print(f"\nwindow {window:g} ms")
        print(
            f"{'variant':15s} {'steps':>7s} {'accepted':>9s} {'rejected':>9s} "
            f"{'dx/dc':>12s} {'warm s':>8s} {'ratio':>6s}"
        )
        primal = jax.jit(lambda c: response(c, t1, base))
        _, steps = jax.block_until_ready(primal(c))
        primal_time = best_time(lambda: primal(c), args.repeats)
        n, a, r = (int(s) for s in steps)
        print(f"{'primal':15s} {n:7d} {a:9d} {r:9d} {'':>12s} {primal_time:8.3f} {1.0:6.2f}")
        for name in args.variants.split(","):
            solver = dataclasses.replace(base, **VARIANTS[name])
            tangent = jax.jit(lambda c: jax.jvp(lambda c: response(c, t1, solver), (c,), (1.0,)))
            (_, steps), (derivative, _) = jax.block_until_ready(tangent(c))
            seconds = best_time(lambda: tangent(c), args.repeats)
            n, a, r = (int(s) for s in steps)
            print(
                f"{name:15s} {n:7d} {a:9d} {r:9d} {float(derivative):12.7g} {seconds:8.3f} "
                f"{seconds / primal_time:6.2f}",
                flush=True,
            )
        if args.reference:
            tight = jaxclear.gradient_solver(mechanism(CLEARANCE))
            x = jax.jit(lambda c: response(c, t1, tight)[0])
            h = 1e-6 * CLEARANCE
            print(
                f"{'central diff.':15s} {'':>7s} {'':>9s} {'':>9s} "
                f"{float((x(c + h) - x(c - h)) / (2 * h)):12.7g}"
            )


if __name__ == "__main__":
    main()
