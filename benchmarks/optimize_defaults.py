"""``jaxclear.optimize`` at ``gradient_solver`` settings (its default) against ``simulate``'s own.

Usage:
    python benchmarks/optimize_defaults.py [--quick] [--iterations 15] [--starts 4]
        [--settings gradient,sensitivities]

The design of notebooks/08_design_optimisation.ipynb: the benchmark slider–crank at 5000 rpm with
one clearance joint B (Lankarani–Nikravesh contact, restitution 0.9, modified Coulomb μ = 0.01),
objective ``"torque_fluctuation"`` over the last two thirds of one revolution, averaged over
``--starts`` starts, design parameter ``rod_com_x`` in ±40 mm, Adam with learning rate 0.3
(``--quick``: a quarter revolution, 3 iterations, 2 starts, as the notebook's quick mode).

For each setting, in one process and in this order:

- ``gradient``: ``optimize`` with no ``solver`` argument, i.e. ``jaxclear.gradient_solver``
  (Lawson–Tsit5 at rtol 1e-12 with diffrax's discrete derivatives);
- ``sensitivities``: ``solver=jaxclear.recommended_solver(mechanism)``, ``simulate``'s settings
  (Tsit5 at rtol 1e-6), differentiated by its error-controlled sensitivities: the objective and
  its gradient from the sensitivity solve (Lawson–Tsit5 at rtol 1e-8).

Both are verified by the same independent runs (``verify_solver``: the recommended method at
rtol 1e-10, atol 1e-13). Printed: wall time (compilation included, and a second call with the
programs compiled), iterations, each iterate's value and objective, the best design, the verified
objectives and improvement; then the largest difference between the two settings' iterates.
Public API only; prints figures, asserts nothing.
"""

import argparse
import os
import sys
import time

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gradient_defaults import header  # noqa: E402  (versions and commit)

RPM = 5000.0
PERIOD = 60.0 / RPM


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--iterations", type=int, default=None)
    parser.add_argument("--starts", type=int, default=None)
    parser.add_argument("--settings", default="gradient,sensitivities")
    args = parser.parse_args()
    t1 = PERIOD * (0.25 if args.quick else 1.0)
    iterations = args.iterations or (3 if args.quick else 15)
    starts = args.starts or (2 if args.quick else 4)
    mechanism = jaxclear.mechanisms.slider_crank(
        rpm=RPM,
        clearance_joints="B",
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )
    verify = jaxclear.recommended_solver(mechanism).replace(
        rtol=1e-10, atol=1e-13, max_steps=200_000
    )
    solvers = {"gradient": None, "sensitivities": jaxclear.recommended_solver(mechanism)}
    print(header())
    print(
        f"t1 {t1 * 1e3:.2f} ms, objective window from {t1 / 3 * 1e3:.2f} ms, {starts} starts, "
        f"{iterations} iterations; verified at {verify.method} rtol {verify.rtol:g}"
    )
    results, times = {}, {}
    for name in args.settings.split(","):

        def run(name=name):
            return jaxclear.optimize(
                mechanism,
                "torque_fluctuation",
                {"rod_com_x": (0.0, -0.04, 0.04)},
                t1=t1,
                statistics_start=t1 / 3,
                starts=starts,
                max_iterations=iterations,
                learning_rate=0.3,
                solver=solvers[name],
                verify_solver=verify,
            )

        started = time.perf_counter()
        result = run()
        first = time.perf_counter() - started
        started = time.perf_counter()
        again = run()
        warm = time.perf_counter() - started
        results[name], times[name] = result, (first, warm)
        same = [h["objective"] for h in again.history] == [h["objective"] for h in result.history]
        print(
            f"\n{name}: solver {result.solver.method} rtol {result.solver.rtol:g}; "
            f"{result.iterations} iterations in {first:.1f} s (compilation included), "
            f"{warm:.1f} s compiled (same iterates: {same})"
        )
        for h in result.history:
            print(
                f"  {h['iteration']:2d}: rod_com_x {h['values']['rod_com_x'] * 1e3:+9.4f} mm, "
                f"objective {h['objective']:.6f} N m"
            )
        print(
            f"  best rod_com_x {result.values['rod_com_x'] * 1e3:+.4f} mm; verified "
            f"{result.verified_initial:.6f} -> {result.verified_final:.6f} N m, improvement "
            f"{result.improvement:.2%}"
        )
    if len(results) == 2:
        a, b = results.values()
        n = min(len(a.history), len(b.history))
        dx = max(
            abs(a.history[i]["values"]["rod_com_x"] - b.history[i]["values"]["rod_com_x"])
            for i in range(n)
        )
        dobj = max(
            abs(a.history[i]["objective"] - b.history[i]["objective"])
            / abs(b.history[i]["objective"])
            for i in range(n)
        )
        print(
            f"\nlargest difference over {n} iterates: rod_com_x {dx * 1e3:.3g} mm, objective "
            f"{100 * dobj:.3g} %; verified improvement {a.improvement:.2%} against "
            f"{b.improvement:.2%}"
        )
        (fa, wa), (fb, wb) = times.values()
        print(
            f"time sensitivities / gradient: {fb / fa:.2f} with compilation, {wb / wa:.2f} compiled"
        )


if __name__ == "__main__":
    main()
