"""Impact-memory relaxation rate k_m: how much it changes the model, and what it costs Tsit5.

Usage:
    python benchmarks/memory_rate_study.py [--joints B] [--rates 1e5,1e6,1e7]

The benchmark slider–crank (5000 rpm, c = 0.5 mm, Lankarani–Nikravesh c_e = 0.9, modified Coulomb
μ = 0.01, no gravity: ``slider_crank``'s default) with ``Smoothing(memory_rate=k_m)``:
    model    journal-centre orbits over the first 1.5 ms at each k_m (Dopri8, rtol 1e-11), max
             distance from the run with k_m = 1e6 (the default, docs/model.md §5) in µm;
    cost     Tsit5 (``fast``) over 2 revolutions at rtol 1e-6: steps, rejected steps, wall time of
             the second call (the first compiles).
The memory's relaxation −k_m (m − δ̇) in free flight is a stiff linear term: an explicit method is
stable only for steps below ~3/k_m. Prints figures only.
"""

import argparse
import time

import numpy as np


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--joints", default="B")
    p.add_argument(
        "--rates", default="1e5,1e6,1e7", help="comma list of k_m, 1/s (1e6 is the reference)"
    )
    a = p.parse_args()

    import jax

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh, Smoothing
    from jaxclear.friction import ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    names = a.joints.split(",")
    rates = [float(r) for r in a.rates.split(",")]

    def mechanism(rate):
        return slider_crank(
            clearance_joints=a.joints,
            clearance=5e-4,
            contact_law=LankaraniNikravesh(restitution=0.9),
            friction_law=ModifiedCoulomb(0.01),
            smoothing=Smoothing(memory_rate=rate),
        )

    ts = np.linspace(0.0, 1.5e-3, 61)
    tight = jaxclear.SolverConfig(method="dopri8", rtol=1e-11, atol=1e-14, max_steps=5_000_000)
    orbits = {}
    for rate in sorted(set(rates) | {1e6}):
        tr = jaxclear.simulate(mechanism(rate), ts[-1], ts=ts, solver=tight)
        orbits[rate] = np.stack(
            [
                np.stack(
                    [np.asarray(tr.clearance[j]["ecc_x"]), np.asarray(tr.clearance[j]["ecc_y"])], -1
                )
                for j in names
            ],
            1,
        )
    print(
        f"joints {a.joints}; model: first 1.5 ms, Dopri8 rtol 1e-11; cost: Tsit5 rtol 1e-6, 2 revolutions"
    )
    print(f"{'k_m 1/s':>9} {'orbit diff vs 1e6 um':>21} {'steps':>7} {'rej':>6} {'run s':>7}")
    for rate in rates:
        diff = 1e6 * float(np.max(np.linalg.norm(orbits[rate] - orbits[1e6], axis=-1)))
        mech = mechanism(rate)
        jaxclear.simulate(mech, 2 * 60 / 5000, num_points=721, solver="fast")
        t0 = time.perf_counter()
        tr = jaxclear.simulate(mech, 2 * 60 / 5000, num_points=721, solver="fast")
        jax.block_until_ready(tr.q)
        wall = time.perf_counter() - t0
        st = tr.stats()
        print(
            f"{rate:9.0e} {diff:21.4g} {st['num_steps']:7d} {st['num_rejected_steps']:6d} {wall:7.3f}"
        )


if __name__ == "__main__":
    main()
