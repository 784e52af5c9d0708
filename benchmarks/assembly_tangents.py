"""The start's tangents and the sensitivity solve's steps: a design parameter through a fit variable.

Usage:
    python benchmarks/assembly_tangents.py [--window 12] [--value -5.9554e-3]

One clearance joint B on the benchmark slider–crank at 5000 rpm (Lankarani–Nikravesh contact,
restitution 0.9, modified Coulomb μ = 0.01), the torque's standard deviation over ``--window`` ms
(401 saved points) as a function of ``rod_com_x`` (which moves the rod's centre of mass, its
joint points and its initial position guess: 7 perturbed scalars). ``jax.jacfwd`` at
``simulate``'s default settings (the error-controlled sensitivities) along

- ``literal``: x itself, at x = ``--value``;
- ``sigmoid``: u with x = −0.04 + 0.08 σ(u), the bounded fit variable of ``jaxclear.optimize``
  and ``jaxclear.identify`` for bounds ±40 mm, at the u that gives ``--value`` (rounded otherwise).

Printed per case: the derivative along x (the sigmoid case divided by dx/du), the augmented
solve's steps (accepted and rejected) and the warm time; then the two derivatives' relative
difference. Before the assembled positions were differentiated by the implicit function theorem
the sigmoid case's start tangents were the damped Newton loop's (docs/differentiation.md).
Public API only; prints figures, asserts nothing.
"""

import argparse
import time

import jax
import jax.numpy as jnp

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb

LOWER, UPPER = -0.04, 0.04


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=float, default=12.0, help="ms")
    parser.add_argument("--value", type=float, default=-5.9554e-3, help="rod_com_x, m")
    args = parser.parse_args()
    mechanism = jaxclear.mechanisms.slider_crank(
        rpm=5000.0,
        clearance_joints="B",
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )
    t1 = args.window * 1e-3

    def objective(x):
        traj = jaxclear.simulate(
            jaxclear.with_parameters(mechanism, {"rod_com_x": x}), t1, num_points=401
        )
        return jnp.std(traj.input_torque), (traj.num_steps, traj.num_rejected_steps)

    def via_sigmoid(u):
        return objective(LOWER + (UPPER - LOWER) * jax.nn.sigmoid(u))

    fraction = (args.value - LOWER) / (UPPER - LOWER)
    u0 = jnp.asarray(jnp.log(fraction / (1 - fraction)))
    slope = float((UPPER - LOWER) * jax.nn.sigmoid(u0) * (1 - jax.nn.sigmoid(u0)))
    cases = {
        "literal": (objective, jnp.asarray(args.value), 1.0),
        "sigmoid": (via_sigmoid, u0, slope),
    }
    print(f"window {args.window} ms, rod_com_x {args.value} m")
    derivatives = {}
    for name, (fn, point, scale) in cases.items():
        f = jax.jit(jax.jacfwd(fn, has_aux=True))
        jax.block_until_ready(f(point))
        start = time.perf_counter()
        grad, (steps, rejected) = jax.block_until_ready(f(point))
        warm = time.perf_counter() - start
        derivatives[name] = float(grad) / scale
        print(
            f"{name:8s} d std(torque) / d rod_com_x {derivatives[name]:.6g} N m/m, "
            f"{int(steps)} steps ({int(rejected)} rejected), {warm:.2f} s warm"
        )
    a, b = derivatives.values()
    print(f"relative difference {abs(a - b) / abs(a):.2e}")


if __name__ == "__main__":
    main()
