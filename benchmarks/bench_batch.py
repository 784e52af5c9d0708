"""Vectorised Monte Carlo over a clearance tolerance: throughput of ``simulate_batch`` on one core.

Usage:
    python benchmarks/bench_batch.py [--case a|b|c] [--solvers tsit5,lawson-tsit5] [--sizes 1,4,16,64]
                                     [--revolutions 2] [--pin-cpu K] [--fast-compile]

The benchmark slider–crank of ``bench_clearance.py`` (5000 rpm, Lankarani–Nikravesh c_e = 0.9, no
gravity, rtol 1e-6; case a: clearance at B, modified Coulomb μ = 0.01; b: O, A, B, same laws;
c: O, A, B with LuGre) with every member's clearance drawn uniformly from 0.5 mm ± 10 %
(seed 0), 360 output points per revolution. One ``jaxclear.simulate_batch`` call per batch size:
compile = first call minus the median of the timed calls; run = median of 3 calls. The vmapped
solve steps all members together until the last one finishes, so a batch costs its slowest
member's step count times the cost of one vectorised step. Prints, per size: run time, time per
member, speed-up per member against batch size 1 (same process), and the members' step counts.
Prints figures only.
"""

import argparse
import os
import statistics
import time

import numpy as np


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default="a", choices=("a", "b", "c"))
    p.add_argument("--solvers", default="tsit5,lawson-tsit5")
    p.add_argument("--sizes", default="1,4,16,64")
    p.add_argument("--revolutions", type=float, default=2.0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument(
        "--pin-cpu", type=int, default=None, help="pin the process to this CPU (before JAX starts)"
    )
    p.add_argument(
        "--fast-compile", action="store_true", help="XLA_FLAGS=--xla_cpu_use_fusion_emitters=false"
    )
    a = p.parse_args()
    if a.pin_cpu is not None:
        os.sched_setaffinity(0, {a.pin_cpu})
    if a.fast_compile:
        os.environ["XLA_FLAGS"] = (
            os.environ.get("XLA_FLAGS", "") + " --xla_cpu_use_fusion_emitters=false"
        ).strip()

    import jax
    import jax.numpy as jnp

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    joints = "B" if a.case == "a" else "O,A,B"
    friction = LuGre() if a.case == "c" else ModifiedCoulomb(0.01)

    def build(c):
        return slider_crank(
            rpm=5000.0,
            clearance_joints=joints,
            clearance=c,
            contact_law=LankaraniNikravesh(restitution=0.9),
            friction_law=friction,
            gravity=False,
        )

    t1 = a.revolutions * 60.0 / 5000.0
    n = int(round(a.revolutions * 360)) + 1
    sizes = [int(s) for s in a.sizes.split(",")]
    rng = np.random.default_rng(0)
    print(
        f"case {a.case} (joints {joints}, {type(friction).__name__}), {a.revolutions:g} revolutions, clearance "
        f"0.5 mm +- 10 %, rtol 1e-6, pinned CPU {a.pin_cpu}, fast compile {a.fast_compile}, jax {jax.__version__}"
    )
    print(
        f"{'solver':<13} {'batch':>5} {'compile s':>9} {'run s':>8} {'s/member':>9} {'speed-up':>8}  member steps "
        "(min / median / max)"
    )
    for solver in a.solvers.split(","):
        config = jaxclear.SolverConfig(method=solver, max_steps=1_000_000)
        per_member_1 = None
        for size in sizes:
            clearances = jnp.asarray(5e-4 * rng.uniform(0.9, 1.1, size))

            def call():
                tr = jaxclear.simulate_batch(build, clearances, t1, num_points=n, solver=config)
                jax.block_until_ready(tr.q)
                return tr

            t0 = time.perf_counter()
            tr = call()
            first = time.perf_counter() - t0
            runs = []
            for _ in range(a.repeats):
                t0 = time.perf_counter()
                tr = call()
                runs.append(time.perf_counter() - t0)
            run = statistics.median(runs)
            steps = np.asarray(tr.num_steps)
            ok = np.asarray(tr.succeeded)
            per_member = run / size
            if per_member_1 is None:
                per_member_1 = per_member
            print(
                f"{solver:<13} {size:5d} {first - run:9.1f} {run:8.3f} {per_member:9.4f} "
                f"{per_member_1 / per_member:7.1f}x  {steps.min()} / {int(np.median(steps))} / {steps.max()}"
                + ("" if ok.all() else f"  ({(~ok).sum()} failed)"),
                flush=True,
            )


if __name__ == "__main__":
    main()
