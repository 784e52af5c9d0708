"""Ideal-joint slider–crank, 2 revolutions at 5000 rpm: compile and run time per solver preset.

Usage: python benchmarks/bench_ideal.py [--repeats N]

For each preset the first ``simulate`` call is timed (tracing + compilation + run), then ``N``
identical calls (compiled code reused). Run time is reported as mean, median and minimum of the
repeats; compile time is the first call minus the median repeat (the median resists the outliers a
shared, loaded machine produces; compare mean and min to judge the noise). Ratios are against the
``fast`` preset measured in the same process, on compile time, median run time and steps. Prints
figures only.
"""

import argparse
import platform
import statistics
import time

import jax

import jaxclear

RPM = 5000.0
REVOLUTIONS = 2.0
POINTS_PER_REVOLUTION = 360
SOLVERS = ("fast", "robust")
BASELINE = "fast"


def timed(fn):
    start = time.perf_counter()
    out = fn()
    jax.block_until_ready(out.t)
    return out, time.perf_counter() - start


def bench(solver: str, repeats: int) -> dict:
    mechanism = jaxclear.mechanisms.slider_crank(rpm=RPM)
    t1 = REVOLUTIONS * 60.0 / RPM
    num_points = int(REVOLUTIONS * POINTS_PER_REVOLUTION) + 1

    def call():
        return jaxclear.simulate(mechanism, t1, num_points=num_points, solver=solver)

    traj, first = timed(call)
    runs = [timed(call)[1] for _ in range(repeats)]
    run = statistics.median(runs)
    stats = traj.stats()
    acc = traj.accelerations("slider")[:, 0]
    return dict(
        solver=solver,
        method=jaxclear.PRESETS[solver].method,
        first=first,
        compile=first - run,
        run=run,
        run_mean=statistics.mean(runs),
        run_min=min(runs),
        steps=stats["num_steps"],
        rejected=stats["num_rejected_steps"],
        acc_min=float(acc.min()),
        acc_max=float(acc.max()),
        torque_min=float(traj.input_torque.min()),
        torque_max=float(traj.input_torque.max()),
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--repeats", type=int, default=7, help="repeat calls timed after the first (default 7)"
    )
    args = parser.parse_args()
    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, backend {jax.default_backend()}, {platform.processor() or platform.machine()}"
    )
    print(
        f"ideal slider-crank, {REVOLUTIONS:g} revolutions at {RPM:g} rpm, {POINTS_PER_REVOLUTION} points/rev, {args.repeats} repeats"
    )
    rows = [bench(s, args.repeats) for s in SOLVERS]
    base = next(r for r in rows if r["solver"] == BASELINE)
    head = (
        f"{'solver':<8} {'method':<9} {'compile s':>10} {'median ms':>10} {'mean ms':>9} {'min ms':>8} {'steps':>6} "
        f"{'rej':>4} {'compile x':>10} {'run x':>7} {'steps x':>8}"
    )
    print(head)
    print("-" * len(head))
    for r in rows:
        print(
            f"{r['solver']:<8} {r['method']:<9} {r['compile']:>10.2f} {1e3 * r['run']:>10.2f} {1e3 * r['run_mean']:>9.2f} "
            f"{1e3 * r['run_min']:>8.2f} "
            f"{r['steps']:>6} {r['rejected']:>4} {r['compile'] / base['compile']:>10.2f} {r['run'] / base['run']:>7.2f} "
            f"{r['steps'] / base['steps']:>8.2f}"
        )
    print()
    for r in rows:
        print(
            f"{r['solver']:<8} slider acceleration {r['acc_min']:.1f} .. {r['acc_max']:.1f} m/s^2, "
            f"crank torque {r['torque_min']:.2f} .. {r['torque_max']:.2f} N m"
        )


if __name__ == "__main__":
    main()
