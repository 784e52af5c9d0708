"""The constraint solve's two ways, unrolled Gauss–Jordan against LAPACK Cholesky, per solve.

``jaxclear.dynamics.spd_solve`` (the constraint solve of the equations of motion) unrolls
systems of up to ``UNROLLED_SOLVE_MAX`` rows. This prints the time per solve of each way, inside
one compiled ``fori_loop`` of 20 000 iterations, for one lane and vmapped over several (as in
ensembles), on random SPD matrices. Pin it to one core for figures that compare (``taskset -c 1``)::

    python benchmarks/spd_solve.py --rows 7,9,12 --lanes 1,8,64
"""

import argparse
import time

import jax
import numpy as np

import jaxclear  # noqa: F401  (float64)
from jaxclear.dynamics import UNROLLED_SOLVE_MAX, spd_solve

ITERATIONS = 20_000


def per_solve(rows: int, lanes: int, unrolled: bool, seed: int = 0) -> float:
    """Seconds per solve (best of 3 timed calls after a warm-up call)."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(lanes, rows, rows))
    s = a @ a.transpose(0, 2, 1) + rows * np.eye(rows)
    b = rng.normal(size=(lanes, rows))
    solve = jax.vmap(lambda m, r: spd_solve(m, r, unrolled=unrolled))

    @jax.jit
    def loop(s, b):
        return jax.lax.fori_loop(0, ITERATIONS, lambda i, x: solve(s + 1e-9 * i, x + b) * 1e-3, b)

    jax.block_until_ready(loop(s, b))
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        jax.block_until_ready(loop(s, b))
        best = min(best, time.perf_counter() - t)
    return best / ITERATIONS / lanes


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", default="3,7,9,12")
    p.add_argument("--lanes", default="1,8,64")
    a = p.parse_args()
    print(f"jax {jax.__version__}, UNROLLED_SOLVE_MAX = {UNROLLED_SOLVE_MAX}; µs per solve")
    print("rows  lanes  unrolled  LAPACK  ratio")
    for rows in (int(x) for x in a.rows.split(",")):
        for lanes in (int(x) for x in a.lanes.split(",")):
            u, c = (1e6 * per_solve(rows, lanes, flag) for flag in (True, False))
            print(f"{rows:4d}  {lanes:5d}  {u:8.3f}  {c:6.3f}  {u / c:5.2f}")


if __name__ == "__main__":
    main()
