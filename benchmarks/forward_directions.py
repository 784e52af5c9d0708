"""Forward-mode cost follows the directions, not the leaves they move: design parameters of several leaves.

Usage:
    python benchmarks/forward_directions.py [--window 3] [--repeats 3]

Issue 22's case (benchmarks/gradient_defaults.py: one clearance joint B, 5000 rpm, L-N
restitution 0.9, modified Coulomb μ = 0.01, gravity on, c = 0.5 mm), slider x at the end of
``--window`` ms, differentiated at ``simulate``'s default settings along

- ``clearance``: B.clearance (1 perturbed scalar, the journal radius);
- ``rod_com_x``: the rod's centre of mass along its axis (7 perturbed scalars: its joint points,
  the clearance joint's journal, the rod's position guess);
- ``both``: the two (2 directions, 8 perturbed scalars).

Printed per parameter set: the warm time over the primal's (same process, best of
``--repeats``) of

- ``jax.jit(jax.jacfwd(f))``: the forward rule, one tangent per direction;
- ``jax.jacfwd(jax.jit(f))``: the rule that serves both modes (the jit hides the transformation),
  one tangent per perturbed scalar, contracted: what ``jax.jacfwd`` integrated before;
- ``jax.jit(jax.jacrev(f))``: reverse mode, one tangent per perturbed scalar;

their first calls (compilation and one run), and the largest relative difference of the two
others from the first. Public API only; prints figures, asserts nothing.
"""

import argparse
import resource

import jax
import jax.numpy as jnp
import numpy as np
from gradient_defaults import NOMINAL, build, header, timed

import jaxclear

ROD_COM_X = -5.9554e-3
"""m: the benchmark rod's centre of mass along its axis (jaxclear.mechanisms.slider_crank)."""

SETS = {
    "clearance": ("B.clearance",),
    "rod_com_x": ("rod_com_x",),
    "both": ("rod_com_x", "B.clearance"),
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=float, default=3.0, help="ms")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    print(header())
    t1 = args.window * 1e-3
    base = build({k: jnp.asarray(v) for k, v in NOMINAL.items()})
    nominal = {"B.clearance": NOMINAL["clearance"], "rod_com_x": ROD_COM_X}

    def slider_x(names, u):
        m = jaxclear.with_parameters(base, {n: nominal[n] + u[i] for i, n in enumerate(names)})
        return jaxclear.simulate(m, t1, num_points=2).q[-1, 6]

    first, primal = timed(
        jax.jit(lambda u: slider_x(("B.clearance",), u)), jnp.zeros(1), repeats=args.repeats
    )
    print(f"slider x over {args.window} ms: primal {primal:.3f} s warm (first call {first:.1f} s)")
    print(
        "set        jacfwd: ratio  first   jacfwd outside jit: ratio  first  apart   "
        "jacrev: ratio  first  apart"
    )
    for label, names in SETS.items():
        u = jnp.zeros(len(names))
        f = lambda u, names=names: slider_x(names, u)  # noqa: E731
        cells, values = [], []
        for fn in (jax.jit(jax.jacfwd(f)), jax.jacfwd(jax.jit(f)), jax.jit(jax.jacrev(f))):
            start, warm = timed(fn, u, repeats=args.repeats)
            values.append(np.asarray(fn(u)))
            cells.append((warm / primal, start))
        apart = [np.max(np.abs(v - values[0])) / np.max(np.abs(values[0])) for v in values[1:]]
        print(
            f"{label:10s} {cells[0][0]:12.2f} {cells[0][1]:5.1f} s"
            f"  {cells[1][0]:24.2f} {cells[1][1]:5.1f} s {apart[0]:6.1e}"
            f"  {cells[2][0]:12.2f} {cells[2][1]:5.1f} s {apart[1]:6.1e}"
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process: {peak:.0f} MB")


if __name__ == "__main__":
    main()
