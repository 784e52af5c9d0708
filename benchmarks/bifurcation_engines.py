"""``bifurcation_points`` by its two engines: refilled lanes against lockstep chunks.

A bifurcation diagram of case a (benchmark slider–crank, clearance joint B, Lankarani–Nikravesh
c_e = 0.9, modified Coulomb μ = 0.01, no gravity) over the crank speed or the clearance:
``--values`` members, ``--revolutions`` section points after ``--skip`` revolutions. For each
engine, in one process: a first call (compilation and solve), then a timed call on the same
values (solve only), best of ``--repeats``; and how far the two engines' points are apart
(members whose sections agree to 1e-6 of the signal's scale, and the largest difference). The
members' step costs differ (chaotic members take more steps), which the refilled lanes absorb.

    python benchmarks/bifurcation_engines.py --param rpm --low 2000 --high 6000 --values 64

Set ``XLA_FLAGS=--xla_force_host_platform_device_count=D`` for D devices (default one). Figures
only; asserts nothing.
"""

import argparse
import os
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--param", default="rpm")
    p.add_argument("--low", type=float, default=2000.0)
    p.add_argument("--high", type=float, default=6000.0)
    p.add_argument("--values", type=int, default=64)
    p.add_argument("--revolutions", type=int, default=20)
    p.add_argument("--skip", type=int, default=5)
    p.add_argument("--chunk", type=int, default=64)
    p.add_argument("--lanes", type=int, default=8)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--engines", default="refill,lockstep")
    a = p.parse_args()

    import bench_ensemble
    import jax

    import jaxclear
    from jaxclear.studies import bifurcation_points

    mechanism = bench_ensemble._mechanism("a")
    values = np.linspace(a.low, a.high, a.values)
    print(
        f"case a, {a.param} {a.low:g}..{a.high:g} ({a.values} values), {a.revolutions} "
        f"revolutions after {a.skip}; chunks of {a.chunk}, {a.lanes} lanes; "
        f"{len(jax.local_devices())} device(s), load {os.getloadavg()[0]:.2f}"
    )
    diagrams = {}
    for engine in a.engines.split(","):
        settings = jaxclear.EnsembleSettings(
            chunk_size=a.chunk, engine=engine, lanes=a.lanes, progress=False
        )

        def call(settings=settings):
            return bifurcation_points(
                mechanism,
                a.param,
                values,
                a.revolutions,
                skip_revolutions=a.skip,
                settings=settings,
            )

        t = time.perf_counter()
        diagrams[engine] = call()
        first = time.perf_counter() - t
        best = np.inf
        for _ in range(a.repeats):
            t = time.perf_counter()
            call()
            best = min(best, time.perf_counter() - t)
        ok = diagrams[engine].succeeded.sum()
        print(f"{engine:9s} first call {first:6.1f} s, then {best:6.2f} s ({ok}/{a.values} ok)")
    if len(diagrams) == 2:
        one, two = diagrams.values()
        for name in one.points:
            x, y = one.points[name], two.points[name]
            scale = np.nanmax(np.abs(x))
            diff = np.nanmax(np.abs(x - y), axis=1) / scale
            counts = ", ".join(
                f"{int(np.sum(diff < tol))} to {tol:g}" for tol in (1e-9, 1e-6, 1e-3)
            )
            print(
                f"{name}: members agreeing (of {len(diff)}, relative to its largest value): "
                f"{counts}; median difference {np.nanmedian(diff):.1e}, "
                f"largest {np.nanmax(diff):.1e}"
            )


if __name__ == "__main__":
    main()
