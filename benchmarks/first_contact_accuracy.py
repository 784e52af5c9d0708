"""How far solvers at everyday tolerances stay from the converged solution over the first contacts.

Usage:
    python benchmarks/first_contact_accuracy.py [--joints O,A,B] [--friction lugre|modified-coulomb]
                                                [--duration 1.5e-3] [--runs "tsit5:1e-6,kvaerno5:1e-6"]
                                                [--spread]

The benchmark slider–crank (5000 rpm, c = 0.5 mm, Lankarani–Nikravesh c_e = 0.9, no gravity) from
centred journals over the first ``--duration`` seconds: free flight, first impacts and, with LuGre
friction, the first stick phase. Each run is compared with Dopri8 at rtol 1e-12 (atol 1e-15) on 61
points: max distance of the journal-centre orbits (µm), and the first saved time at which it
exceeds 1 µm. Prints figures only.

What it showed (docs/solvers.md, "Accuracy"): with Coulomb-type friction
every solver at rtol 1e-6 stays within ~0.1 µm; with LuGre the first stick phase is a fork — a tiny
difference decides whether the journal sticks or slips through — and only some runs at rtol 1e-6
take the converged branch, while explicit solvers need rtol ~1e-10.
"""

import argparse
import time

import numpy as np

DEFAULT_RUNS = (
    "lawson-tsit5:1e-6,tsit5:1e-6,tsit5:1e-8,tsit5:1e-9,tsit5:1e-10,kencarp5:1e-6,kencarp5:1e-8,"
    "kvaerno3:1e-6,kvaerno4:1e-6,kvaerno5:1e-5,kvaerno5:1e-6,kvaerno5:1e-7"
)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--joints", default="O,A,B")
    p.add_argument("--friction", default="lugre", choices=("lugre", "modified-coulomb"))
    p.add_argument("--duration", type=float, default=1.5e-3, help="s (default 1.5e-3)")
    p.add_argument(
        "--runs", default=DEFAULT_RUNS, help="comma list of method:rtol (atol = rtol/1000)"
    )
    p.add_argument(
        "--spread",
        action="store_true",
        help="run each method:rtol at rtol x (0.8, 0.9, 1, 1.1, 1.25) and print the range: one run's "
        "distance depends on its step sequence",
    )
    a = p.parse_args()

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    law = LuGre() if a.friction == "lugre" else ModifiedCoulomb(0.01)
    mech = slider_crank(
        clearance_joints=a.joints,
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=law,
    )
    names = a.joints.split(",")
    ts = np.linspace(0.0, a.duration, 61)

    def orbits(tr):
        return np.stack(
            [
                np.stack(
                    [np.asarray(tr.clearance[j]["ecc_x"]), np.asarray(tr.clearance[j]["ecc_y"])], -1
                )
                for j in names
            ],
            1,
        )

    ref_cfg = jaxclear.SolverConfig(method="dopri8", rtol=1e-12, atol=1e-15, max_steps=5_000_000)
    ref = orbits(jaxclear.simulate(mech, a.duration, ts=ts, solver=ref_cfg))
    print(
        f"joints {a.joints}, {a.friction} friction, first {a.duration * 1e3:g} ms, reference Dopri8 rtol 1e-12"
    )
    print(
        f"{'method':<10} {'rtol':>7} {'steps':>7} {'wall s':>7}  {'max dist um':>11}  first > 1 um at"
    )
    for item in a.runs.split(","):
        method, rtol = item.split(":")
        factors = (0.8, 0.9, 1.0, 1.1, 1.25) if a.spread else (1.0,)
        results = []
        for factor in factors:
            r = float(rtol) * factor
            cfg = jaxclear.SolverConfig(method=method, rtol=r, atol=r * 1e-3, max_steps=5_000_000)
            t0 = time.perf_counter()
            tr = jaxclear.simulate(mech, a.duration, ts=ts, solver=cfg, throw=False)
            wall = time.perf_counter() - t0
            dist = np.max(np.linalg.norm(orbits(tr) - ref, axis=-1), axis=1)
            results.append((tr.stats()["num_steps"], wall, dist))
        if a.spread:
            steps = [x[0] for x in results]
            worst = [1e6 * x[2].max() for x in results]
            print(
                f"{method:<10} {float(rtol):7.0e} {min(steps):5d}-{max(steps):<5d} over rtol x (0.8 .. 1.25): "
                f"max dist {min(worst):.2g}-{max(worst):.2g} um"
            )
            continue
        steps, wall, dist = results[0]
        late = np.flatnonzero(dist > 1e-6)
        when = f"{1e3 * ts[late[0]]:.3f} ms" if late.size else "-"
        print(
            f"{method:<10} {float(rtol):7.0e} {steps:7d} {wall:7.1f}  {1e6 * dist.max():11.4g}  {when}"
        )


if __name__ == "__main__":
    main()
