"""Run-time cost of tracking extremes (``simulate(..., extremes=True)``, the default) against
``extremes=False``, in one process, on the benchmark slider–crank (2 revolutions at 5000 rpm,
721 output points, solver 'auto').

    python benchmarks/extremes_overhead.py [--repeats 5] [--solver auto] [--json PATH]

Case a: clearance at B, Lankarani–Nikravesh contact, modified Coulomb friction μ = 0.01 (Tsit5).
Case c: clearance at O, A, B, hybrid contact, LuGre friction (KenCarp5). Prints the best of the
repeats for each setting and their ratio; compilation (first call) is not timed. ``--solver``
runs both cases with another method or preset (e.g. lawson-tsit5, imex) instead of 'auto'.
"""

import argparse
import json
import time

import jax

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
from jaxclear.mechanisms import slider_crank

RPM = 5000.0
T_END = 2 * 60.0 / RPM
POINTS = 721


def best_time(mechanism, repeats: int, extremes: bool, solver="auto") -> tuple[float, int]:
    run = lambda: jaxclear.simulate(  # noqa: E731
        mechanism, T_END, num_points=POINTS, extremes=extremes, solver=solver
    )
    traj = run()
    jax.block_until_ready(traj.q)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        traj = run()
        jax.block_until_ready(traj.q)
        best = min(best, time.perf_counter() - start)
    return best, int(traj.num_steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--solver", default="auto", help="method or preset (default: auto)")
    parser.add_argument("--json", default=None, help="also write the figures to this file")
    args = parser.parse_args()
    cases = {
        "a": slider_crank(
            rpm=RPM,
            clearance_joints="B",
            friction_law=ModifiedCoulomb(0.01),
            contact_law=LankaraniNikravesh(),
        ),
        "c": slider_crank(rpm=RPM, clearance_joints=("O", "A", "B")),
    }
    solver = f", solver {args.solver}" if args.solver != "auto" else ""
    print(f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, best of {args.repeats}{solver}")
    print("case  steps  extremes off  extremes on  ratio")
    figures = {}
    for name, mechanism in cases.items():
        off, steps = best_time(mechanism, args.repeats, extremes=False, solver=args.solver)
        on, _ = best_time(mechanism, args.repeats, extremes=True, solver=args.solver)
        print(f"{name:>4}  {steps:5d}  {off:10.3f} s  {on:9.3f} s  {on / off:5.2f}")
        figures[name] = dict(steps=steps, off_s=off, on_s=on)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(figures, f)


if __name__ == "__main__":
    main()
