"""Where a step's time goes: diffrax's loop, the right-hand sides, the extremes (issue 13).

For each benchmark case (``bench_clearance.py``'s, 2 revolutions at 5000 rpm, rtol 1e-6, atol
1e-9, 721 output points) and the method ``auto`` picks, prints in one process:

- ``run``: ``jaxclear.simulate`` with its defaults (extremes tracked), median of ``--repeats``;
- ``bare``: the same with ``extremes=False`` (the equations only: what CVODES does);
- ``floor``: diffrax's own loop with the same state size, the same output grid and the same
  number of steps (``dtmax`` forces it) on a trivial vector field (dy/dt = −1e-3 y): what a step
  costs before any model evaluation (Tsit5; the step's arithmetic over the stages is in it);
- ``rhs``: one evaluation of ``jaxclear.dynamics.vector_field`` inside a compiled loop;
- per step: bare − floor (the model's share), run − bare (the extremes' share).

    python benchmarks/step_anatomy.py [--cases a,b,c] [--repeats 5]

Pin it to one core for steadier figures (``taskset -c 1 python ...``). Figures only.
"""

import argparse
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_clearance as bc  # noqa: E402  (the cases and the right-hand-side timer)


def _median_time(call, repeats):
    call()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def loop_floor(n_state, steps, t1, ts, repeats):
    """Seconds of a diffrax Tsit5 solve of a trivial vector field taking ``steps`` steps."""
    import diffrax
    import jax
    import jax.numpy as jnp

    saveat = diffrax.SaveAt(
        subs=[diffrax.SubSaveAt(ts=jnp.asarray(ts)), diffrax.SubSaveAt(t1=True)]
    )
    controller = diffrax.PIDController(rtol=bc.RTOL, atol=bc.ATOL, dtmax=t1 / steps)

    @jax.jit
    def solve(y0):
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(lambda t, y, args: -1e-3 * y),
            diffrax.Tsit5(),
            0.0,
            t1,
            t1 / steps,
            y0,
            saveat=saveat,
            stepsize_controller=controller,
            max_steps=4 * steps,
            throw=False,
        )
        return sol.ys[1], sol.stats["num_steps"]

    y0 = jnp.ones((n_state,))
    seconds = _median_time(lambda: jax.block_until_ready(solve(y0)), repeats)
    return seconds, int(solve(y0)[1])


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default="a,b,c")
    p.add_argument("--repeats", type=int, default=5)
    a = p.parse_args()

    import jax

    import jaxclear

    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, XLA_FLAGS="
        f"{os.environ.get('XLA_FLAGS', '')!r}, load average "
        + " ".join(f"{x:.2f}" for x in os.getloadavg())
    )
    print(
        f"{'case':<5}{'auto':<10}{'steps':>7}{'run s':>8}{'bare s':>8}{'floor s':>8}"
        f"{'rhs us':>8}  per step, us: {'run':>5}{'bare':>6}{'floor':>6}{'model':>6}{'extr.':>6}"
    )
    for case in [c.strip() for c in a.cases.split(",") if c.strip()]:
        mech = bc.case_mechanism(case)
        config = jaxclear.recommended_solver(mech).replace(rtol=bc.RTOL, atol=bc.ATOL)
        t1, ts = bc.grid(2.0)

        def solve(extremes):
            traj = jaxclear.simulate(mech, t1, ts=ts, solver=config, throw=False, extremes=extremes)
            jax.block_until_ready(traj.q)
            return traj

        run = _median_time(lambda: solve(True), a.repeats)
        bare = _median_time(lambda: solve(False), a.repeats)
        traj = solve(False)
        steps = int(traj.num_steps)
        floor, floor_steps = loop_floor(mech.state_size, steps, t1, ts, a.repeats)
        rhs = bc.rhs_cost_us(mech, traj.y_final, t1)["rhs_us"]
        per = lambda s, k=steps: 1e6 * s / k  # noqa: E731
        print(
            f"{case:<5}{config.method:<10}{steps:>7}{run:8.3f}{bare:8.3f}{floor:8.3f}{rhs:8.2f}"
            f"  {'':>14}{per(run):5.1f}{per(bare):6.1f}{per(floor, floor_steps):6.1f}"
            f"{per(bare) - per(floor, floor_steps):6.1f}{per(run) - per(bare):6.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
