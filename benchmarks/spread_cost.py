"""Cost of ``--spread K`` (``simulate_revolutions(companions=K)``) against the nominal run alone,
in one process after a warm-up of both programs (issue 24 target: ``--spread 8`` <= 2x a run).

    python benchmarks/spread_cost.py [--companions 8] [--revolutions 4] [--joints O,A,B]
"""

import argparse
import time

from jaxclear.mechanisms import slider_crank
from jaxclear.studies import simulate_revolutions


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--companions", type=int, default=8)
    parser.add_argument("--revolutions", type=float, default=4)
    parser.add_argument("--joints", default="O,A,B")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    mechanism = slider_crank(clearance_joints=tuple(args.joints.split(",")))
    simulate_revolutions(mechanism, 1, companions=args.companions, skip=0)  # compile both
    times = {}
    for k in (0, args.companions):
        best = float("inf")
        for _ in range(args.repeats):
            start = time.perf_counter()
            run = simulate_revolutions(mechanism, args.revolutions, companions=k)
            best = min(best, time.perf_counter() - start)
        times[k] = best
        print(
            f"companions {k}: {best:.3f} s (best of {args.repeats}), {int(run.trajectory.num_steps)} nominal steps"
        )
    print(
        f"ratio with {args.companions} companions / nominal alone: {times[args.companions] / times[0]:.2f}"
    )


if __name__ == "__main__":
    main()
