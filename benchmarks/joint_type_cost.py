"""Cost per crank revolution of each joint type against a dry revolute clearance joint (issue 26).

    python benchmarks/joint_type_cost.py [--repeats 5] [--revolutions 2] [--solvers auto,imex]
        [--cases ideal,dry,oil-0.4,oil-1.2,guide]

The benchmark slider–crank at 5000 rpm, no gravity, revolute joints ideal except where a case
says otherwise:

- ``ideal``: ideal joints.
- ``dry``: dry revolute clearance joint B, c = 0.5 mm, Lankarani–Nikravesh (restitution 0.9) and
  modified Coulomb friction μ = 0.01 (notebook 01, bench_clearance.py's case a). The baseline.
- ``oil-0.4``, ``oil-1.2``: the same joint with the film of notebook 09 and of the shipped
  example ``slider_crank_lubricated.toml`` (long bearing, L = 40 mm, ε₀ = 0.9, Δ = 0.05): 0.4 Pa s
  (the journal still rides the wall) and 1.2 Pa s (the film carries the load).
- ``guide``: ideal revolute joints and a translational clearance joint at the slider guide with
  the values of the shipped example ``slider_crank_translational_clearance.toml`` (a = 50 mm,
  b = 25 mm, c = 1 mm, Flores law K = 1e10 N/m^1.5, restitution 0.4, Coulomb μ = 0.01).

Each case with each solver (``auto``: the default, Tsit5 for all these cases; ``imex``: KenCarp4
implicit in the impact memories, the preset the lubricated example uses) in one process:

1. revolution 0 from the centred start (``assemble``), timed twice: compile = first call minus
   the second;
2. from the state at the end of revolution 0 (``y_final``), ``--revolutions`` revolutions, timed
   ``--repeats`` times: run = the best, divided by the revolutions; steps and rejected steps per
   revolution of that window.

Extremes are tracked (``simulate``'s default, as ``jaxclear run``), 361 output points per call.
The ratios are against ``dry`` with ``auto`` measured in the same process. Prints figures only.
"""

import argparse
import os
import platform
import time

import jax

import jaxclear
from jaxclear.contact import Flores, LankaraniNikravesh
from jaxclear.friction import Coulomb, ModifiedCoulomb
from jaxclear.mechanisms import slider_crank

RPM = 5000.0
PERIOD = 60.0 / RPM  # s
CLEARANCE = 5e-4  # m, joint B
POINTS = 361  # output points per call
BASELINE = ("dry", "auto")
# same topology, another viscosity: the compiled solve is reused
SAME_PROGRAM = {"oil-1.2": "oil-0.4"}


def dry_laws():
    return dict(
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )


def lubricated(viscosity):
    film = jaxclear.Lubrication(
        viscosity, 0.04, theory="long", transition_eccentricity=0.9, transition_width=0.05
    )
    return slider_crank(
        rpm=RPM, clearance_joints={"B": {**dry_laws(), "lubrication": film}}, clearance=CLEARANCE
    )


CASES = {
    "ideal": lambda: slider_crank(rpm=RPM),
    "dry": lambda: slider_crank(rpm=RPM, clearance_joints={"B": dry_laws()}, clearance=CLEARANCE),
    "oil-0.4": lambda: lubricated(0.4),
    "oil-1.2": lambda: lubricated(1.2),
    "guide": lambda: slider_crank(
        rpm=RPM,
        translational_clearance=dict(
            clearance=1e-3,
            half_length=0.05,
            half_height=0.025,
            contact_law=Flores(stiffness=1e10, restitution=0.4),
            friction_law=Coulomb(friction_coefficient=0.01),
        ),
    ),
}


def timed(call):
    start = time.perf_counter()
    traj = call()
    jax.block_until_ready(traj.y_final)
    return traj, time.perf_counter() - start


def bench(case: str, solver: str, revolutions: float, repeats: int, compiled: set) -> dict:
    mechanism = CASES[case]()
    program = (SAME_PROGRAM.get(case, case), solver)
    shared = program in compiled
    compiled.add(program)
    y0 = jaxclear.assemble(mechanism)

    def window(t0, t1, y):
        return lambda: jaxclear.simulate(
            mechanism, t1, t0=t0, y0=y, num_points=POINTS, solver=solver
        )

    first_call = window(0.0, PERIOD, y0)
    rev0, first = timed(first_call)
    _, second = timed(first_call)
    settled = window(PERIOD, (1.0 + revolutions) * PERIOD, rev0.y_final)
    best = float("inf")
    for _ in range(repeats):
        traj, seconds = timed(settled)
        best = min(best, seconds)
    stats = traj.stats()
    acc = abs(traj.accelerations("slider")[:, 0]).max()
    return dict(
        case=case,
        solver=solver,
        method=jaxclear.recommended_solver(mechanism).method
        if solver == "auto"
        else jaxclear.PRESETS[solver].method,
        compile=None if shared else first - second,
        shared=SAME_PROGRAM.get(case) if shared else None,
        rev0_run=second,
        rev0_steps=int(rev0.num_steps),
        run=best / revolutions,
        steps=stats["num_steps"] / revolutions,
        rejected=stats["num_rejected_steps"] / revolutions,
        acc=float(acc),
        succeeded=bool(stats["succeeded"]),
    )


def compile_text(row: dict, unit: str = " s") -> str:
    return f"as {row['shared']}" if row["compile"] is None else f"{row['compile']:.2f}{unit}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed settled runs (best kept)")
    parser.add_argument("--revolutions", type=float, default=2.0, help="settled window length")
    parser.add_argument("--solvers", default="auto,imex")
    parser.add_argument("--cases", default=",".join(CASES))
    args = parser.parse_args()
    cases = args.cases.split(",")
    solvers = args.solvers.split(",")
    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, {platform.machine()}, "
        f"{os.cpu_count()} CPUs, load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )
    print(
        f"slider-crank at {RPM:g} rpm; compile = first call of revolution 0 minus its second; run "
        f"= best of {args.repeats} over revolutions 1..{args.revolutions:g} (from the end of "
        f"revolution 0), per revolution; extremes tracked, {POINTS} points per call"
    )
    rows = []
    compiled = set()
    for case in cases:
        for solver in solvers:
            row = bench(case, solver, args.revolutions, args.repeats, compiled)
            rows.append(row)
            print(
                f"  {case:<8} {solver:<5} {row['method']:<9} compile {compile_text(row):>9}, "
                f"revolution 0 {row['rev0_run']:.3f} s / {row['rev0_steps']} steps, settled "
                f"{1e3 * row['run']:.1f} ms/rev, {row['steps']:.0f} steps/rev, peak |a_slider| "
                f"{row['acc']:.0f} m/s^2{'' if row['succeeded'] else ' FAILED'}  "
                f"(load {os.getloadavg()[0]:.2f})",
                flush=True,
            )
    base = next((r for r in rows if (r["case"], r["solver"]) == BASELINE), None)
    print()
    head = (
        f"{'case':<8} {'solver':<6} {'method':<9} {'compile s':>9} {'ms/rev':>8} {'steps/rev':>9} "
        f"{'rej/rev':>7} {'us/step':>7} {'run x':>6} {'steps x':>7} {'compile x':>9}"
    )
    print(head)
    print("-" * len(head))
    for r in rows:
        if base is None:
            ratios = f"{'-':>6} {'-':>7} {'-':>9}"
        else:
            compile_ratio = "-" if r["compile"] is None else f"{r['compile'] / base['compile']:.2f}"
            ratios = (
                f"{r['run'] / base['run']:>6.2f} {r['steps'] / base['steps']:>7.2f} "
                f"{compile_ratio:>9}"
            )
        print(
            f"{r['case']:<8} {r['solver']:<6} {r['method']:<9} {compile_text(r, unit=''):>9} "
            f"{1e3 * r['run']:>8.1f} {r['steps']:>9.0f} {r['rejected']:>7.0f} "
            f"{1e6 * r['run'] / r['steps']:>7.1f} {ratios}"
        )
    print(
        f"\nratios: against {BASELINE[0]} with {BASELINE[1]}; 'as X': the compiled solve of case X "
        f"is reused (same topology); final load average "
        f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )


if __name__ == "__main__":
    main()
