"""Lane refilling against lockstep chunks (issue 25, part 1): members per second of
``jaxclear.solve.solve_members`` and of the ensemble engine's vmapped chunks.

Usage:
    python benchmarks/lane_refill.py [--case a,c] [--members 128] [--lanes 8,32] [--repeats 2]
        [--revolutions 2] [--cores 1] [--events 256] [--json PATH]
        [--engine lockstep,refill] [--chunk 64]

The benchmark slider–crank at 5000 rpm (Lankarani–Nikravesh c_e = 0.9, no gravity; case a:
clearance joint B, modified Coulomb μ = 0.01; case c: O, A, B, LuGre), as in
benchmarks/bench_ensemble.py: ``--revolutions`` revolutions, extremes from the second on, every
member's clearances drawn uniformly from 0.5 mm ± 10 % (seed 0; seed 1 for the warm-up), solver
``auto`` (case a: tsit5; case c: the ``imex`` preset), ``--events`` contact events per joint
(``run_ensemble``'s default for 2 revolutions).

One process (``XLA_FLAGS`` as the ``jaxclear`` command sets them, one CPU device, pinned to
``--cores`` cores). For each size S in ``--lanes``:
- lockstep: ``map_members`` (``jaxclear.studies``, the engine of ``run_ensemble``) over
  chunks of S members, each member a ``simulate`` with extremes and contact events and 2 saved points; once
  in index order (random costs, as drawn) and once with the members sorted by their step counts
  (the order ``order="cost"`` aims at, known here in advance: lockstep's best case);
- lanes: ``solve_members`` with S lanes, members in index order; "lanes-lpt": the queue sorted
  longest member first (known in advance here: the best case of a cost order for lanes, the
  longest-processing-time-first rule that leaves the shortest tail).
Both return the same per member: steps, result, y(t_final) and the whole ``Extremes`` (a
lockstep member returning less would let XLA drop the unused part of its solver state).

With ``--engine``: ``run_ensemble`` itself (``jaxclear.studies``, the work of an ensemble member:
the member's solve with 360 saved points per revolution, its ideal mechanism's solve, the
statistics, deviations and contact modes) with ``EnsembleSettings.engine`` set to each engine
named, ``order="cost"`` (the default): for each size S in ``--lanes``, "lockstep" in chunks of S
members and "refill" on S lanes in chunks of ``--chunk`` members; and "lockstep" in chunks of
``--chunk`` (the default settings). Each setting runs once on ``max(chunk)`` other members
(compilation), then timed on ``--members`` members; members/s, the ratios refill / lockstep of the
same round, and how far the two engines' member tables part (statistics of the same member).
Each program is compiled and run once on other members of the same count (warm-up), then timed;
``--repeats`` rounds of all timed runs, interleaved, so that a load on the machine falls on all of
them alike. Prints members per second, the ratios lanes / lockstep per round, the loop iterations
(lockstep: sum over chunks of the slowest member's steps; lanes: loop iterations) and the steps.
Asserts nothing.
"""

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_ensemble import RPM, _mechanism  # noqa: E402  (the same cases a and c)


def _values(mechanism, n, seed):
    import numpy as np

    rng = np.random.default_rng(seed)
    return {
        f"{j.name}.clearance": 5e-4 * rng.uniform(0.9, 1.1, n) for j in mechanism.clearance_joints
    }


def _lockstep_member(v, mechanism, names, config, t1, start, events):
    """One member as a lockstep chunk solves it: ``simulate`` of the member, vmapped by
    ``map_members``."""
    import jaxclear

    m = jaxclear.with_parameters(mechanism, {n: v[k] for k, n in enumerate(names)})
    traj = jaxclear.simulate(
        m,
        t1,
        num_points=2,
        solver=config,
        statistics_start=start,
        contact_events=events,
        throw=False,
    )
    # everything solve_members returns: XLA drops the parts of the solver state (the tracked
    # extremes, the contact-event buffers) whose results are not used, which would flatter lockstep
    return {
        "num_steps": traj.num_steps,
        "result": traj.result._value,  # pyright: ignore[reportAttributeAccessIssue]
        "t_final": traj.t_final,
        "y_final": traj.y_final,
        "extremes": traj.extremes,
    }


def run_engines(case, a):
    """``run_ensemble`` with each engine of ``--engine`` (module doc)."""
    import jax
    import numpy as np

    import jaxclear
    from jaxclear.studies import EnsembleSettings

    mech = _mechanism(case)
    period = 60.0 / RPM
    t1, start = a.revolutions * period, period
    points = int(round(a.revolutions * 360)) + 1
    n = a.members
    device = jax.local_devices()[:1]
    options = dict(statistics_start=start, num_points=points, contact_events=a.events)
    settings = {}
    for size in a.sizes:
        for engine in a.engines:
            chunk = size if engine == "lockstep" else a.chunk
            settings[(engine, size)] = (chunk, size)
    if "lockstep" in a.engines:
        settings[("lockstep", a.chunk)] = (a.chunk, a.chunk)

    def run(key, members, seed):
        chunk, lanes = settings[key]
        s = EnsembleSettings(
            chunk_size=chunk, devices=device, progress=False, engine=key[0], lanes=lanes
        )
        return jaxclear.run_ensemble(mech, _values(mech, members, seed), t1, settings=s, **options)

    config = jaxclear.recommended_solver(mech)
    print(
        f"\ncase {case}: run_ensemble, {config.method}, {n} members, {a.revolutions:g} "
        f"revolutions, {points} points, {a.events} events per joint"
    )
    compile_s = {}
    for key in settings:
        t = time.perf_counter()
        run(key, settings[key][0], 1)
        compile_s[key] = time.perf_counter() - t
    print(
        "compile + first chunk, s: "
        + ", ".join(
            f"{k[0]} {'chunk' if k[0] == 'lockstep' else 'lanes'} {k[1]}: {v:.1f}"
            for k, v in compile_s.items()
        )
    )
    rates, tables = {}, {}
    for _ in range(a.repeats):
        for key in settings:
            t = time.perf_counter()
            r = run(key, n, 0)
            rates.setdefault(key, []).append(n / (time.perf_counter() - t))
            tables.setdefault(key, r)
    print(f"{'engine':>9} {'chunk':>5} {'lanes':>5} {'members/s per round':>20}  ratio per round")
    for key in settings:
        chunk, lanes = settings[key]
        ratio = ""
        if key[0] == "refill" and ("lockstep", key[1]) in rates:
            mine = np.asarray(rates[key]) / np.asarray(rates[("lockstep", key[1])])
            ratio += f" /lockstep chunk {key[1]} " + " ".join(f"{x:.2f}" for x in mine)
        if key[0] == "refill" and ("lockstep", a.chunk) in rates and key[1] != a.chunk:
            mine = np.asarray(rates[key]) / np.asarray(rates[("lockstep", a.chunk)])
            ratio += f" /lockstep chunk {a.chunk} " + " ".join(f"{x:.2f}" for x in mine)
        lanes_text = "-" if key[0] == "lockstep" else str(lanes)
        print(
            f"{key[0]:>9} {chunk:5d} {lanes_text:>5} "
            f"{' '.join(f'{x:6.2f}' for x in rates[key]):>20} {ratio}"
        )
    # each refilled run against the lockstep run of the same vector width (chunk = lanes): the
    # programs then round alike; across widths, rounding differs and impacts magnify it
    for key in (k for k in settings if k[0] == "refill"):
        ref_key = ("lockstep", key[1])
        if ref_key not in tables:
            continue
        mine, theirs = tables[key], tables[ref_key]
        same = mine.num_steps == theirs.num_steps
        worst = {}
        for name, v in mine.statistics.items():
            u = theirs.statistics[name]
            ok = np.isfinite(u) & np.isfinite(v)
            if np.any(ok):
                scale = max(float(np.max(np.abs(u[ok]))), 1e-300)  # the statistic's largest
                worst[name] = float(np.max(np.abs(v[ok] - u[ok]))) / scale
        top = sorted(worst.items(), key=lambda kv: -kv[1])[:3]
        print(
            f"refill lanes {key[1]} against lockstep chunk {key[1]}: same step count in "
            f"{int(same.sum())} of {n} members; statistics bitwise equal in "
            f"{sum(v == 0 for v in worst.values())} of {len(worst)}; largest differences "
            "relative to the statistic's largest value: "
            + ", ".join(f"{k} {v:.1e}" for k, v in top)
        )
    return {
        "method": config.method,
        "members": n,
        "members_per_s": {f"{k[0]} {k[1]}": v for k, v in rates.items()},
        "compile_s": {f"{k[0]} {k[1]}": v for k, v in compile_s.items()},
    }


def run_case(case, a):
    import jax
    import numpy as np

    import jaxclear
    from jaxclear.solve import solve_members
    from jaxclear.studies import (
        EnsembleSettings,
        map_members,  # the engine of run_ensemble
    )

    mech = _mechanism(case)
    config = jaxclear.recommended_solver(mech)
    period = 60.0 / RPM
    t1, start = a.revolutions * period, period
    n = a.members
    names = tuple(_values(mech, 1, 0))
    rows = {seed: np.stack(list(_values(mech, n, seed).values()), axis=1) for seed in (0, 1)}
    device = jax.local_devices()[:1]

    def lockstep(size, seed, order=None):
        r = rows[seed] if order is None else rows[seed][order]
        settings = EnsembleSettings(chunk_size=size, devices=device, progress=False)
        args = (mech, names, config, jax.numpy.asarray(t1), jax.numpy.asarray(start), a.events)
        out = map_members(_lockstep_member, args, r, settings=settings)
        steps = np.empty(n, dtype=np.int64)
        steps[np.arange(n) if order is None else order] = out["num_steps"]
        return steps, out

    def lanes(size, seed, order=None):
        r = rows[seed] if order is None else rows[seed][order]
        values = dict(zip(names, r.T))
        out = solve_members(
            mech,
            values,
            t1,
            solver=config,
            lanes=size,
            statistics_start=start,
            contact_events=a.events,
        )
        jax.block_until_ready(out.y_final)
        steps = np.empty(n, dtype=np.int64)
        steps[np.arange(n) if order is None else order] = np.asarray(out.num_steps)
        return steps, out

    print(
        f"\ncase {case}: {config.method}, {n} members, {a.revolutions:g} revolutions, "
        f"{a.events} events per joint"
    )
    compile_s = {}
    order = None
    for size in a.sizes:
        t = time.perf_counter()
        lockstep(size, 1)
        compile_s[("lockstep", size)] = time.perf_counter() - t
        t = time.perf_counter()
        steps, _ = lanes(size, 1)
        compile_s[("lanes", size)] = time.perf_counter() - t
    # the warm-up members' step counts don't give the timed members' order: one lanes run does
    steps0, sol0 = lanes(a.sizes[0], 0)
    order = np.argsort(steps0, kind="stable")
    print(
        "compile+first run, s: "
        + ", ".join(f"{k[0]} {k[1]}: {v:.1f}" for k, v in compile_s.items())
    )
    print(
        f"steps per member (lanes): min {steps0.min()}, median {int(np.median(steps0))}, "
        f"max {steps0.max()}; failed {int(np.sum(np.asarray(sol0.result) != 0))}"
    )
    kinds = ("lockstep", "sorted", "lanes", "lanes-lpt")
    rates, kept = {}, {}
    for _ in range(a.repeats):
        for size in a.sizes:
            for kind in kinds:
                t = time.perf_counter()
                if kind.startswith("lanes"):
                    steps, out = lanes(size, 0, None if kind == "lanes" else order[::-1])
                    iterations = int(out.iterations)
                else:
                    steps, out = lockstep(size, 0, None if kind == "lockstep" else order)
                    chunks = (steps if kind == "lockstep" else steps[order]).reshape(-1, size)
                    iterations = int(chunks.max(axis=1).sum())
                wall = time.perf_counter() - t
                rates.setdefault((kind, size), []).append(n / wall)
                rates.setdefault(("iterations", kind, size), []).append(iterations)
                rates.setdefault(("steps", kind, size), []).append(steps)
                if kind in ("lanes", "lockstep"):  # both in index order
                    kept.setdefault((kind, size), out)
    print(
        "members/s per round; iterations: loop iterations (lockstep: the slowest member's steps "
        "summed over chunks); lane use: steps / (iterations x size)"
    )
    print(
        f"{'size':>5} {'kind':>9} {'members/s per round':>20} {'iterations':>10} {'lane use':>8}"
        f"  ratio per round"
    )
    for size in a.sizes:
        for kind in kinds:
            r = rates[(kind, size)]
            it = rates[("iterations", kind, size)][0]
            use = rates[("steps", kind, size)][0].sum() / (it * size)
            ratio = ""
            if kind.startswith("lanes"):
                for other in ("lockstep", "sorted"):
                    mine = np.asarray(r) / np.asarray(rates[(other, size)])
                    ratio += f" /{other} " + " ".join(f"{x:.2f}" for x in mine)
            print(
                f"{size:5d} {kind:>9} {' '.join(f'{x:6.2f}' for x in r):>20} {it:10d} "
                f"{use:8.3f} {ratio}"
            )
    for size in a.sizes:
        mine, theirs = kept[("lanes", size)], kept[("lockstep", size)]
        same = rates[("steps", "lanes", size)][0] == rates[("steps", "lockstep", size)][0]
        y, y_ref = np.asarray(mine.y_final), np.asarray(theirs["y_final"])
        dy = np.max(np.abs(y - y_ref), axis=1) / np.max(np.abs(y_ref), axis=1)
        peaks = {
            "input_torque_max": (
                mine.extremes.input_torque_max,
                theirs["extremes"].input_torque_max,
            ),
            **{
                f"{j}_normal_force_max": (
                    mine.extremes.normal_force_max[j],
                    theirs["extremes"].normal_force_max[j],
                )
                for j in mine.extremes.normal_force_max
            },
        }
        worst = {
            k: float(np.max(np.abs(np.asarray(u) - np.asarray(v)) / np.abs(np.asarray(v))))
            for k, (u, v) in peaks.items()
        }
        print(
            f"size {size}: members with the same step count in lanes and lockstep: "
            f"{int(same.sum())} of {n}; y(t1) bitwise equal in {int(np.sum(dy == 0))}, largest "
            f"|dy|/max|y| {dy.max():.1e}; largest relative difference of the peaks: "
            + ", ".join(f"{k} {v:.1e}" for k, v in worst.items())
        )
    return {
        "method": config.method,
        "members": n,
        "members_per_s": {
            f"{kind} {size}": rates[(kind, size)] for kind in kinds for size in a.sizes
        },
        "steps": [int(steps0.min()), int(np.median(steps0)), int(steps0.max())],
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default="a,c")
    p.add_argument("--members", type=int, default=128)
    p.add_argument("--lanes", default="8,32")
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--revolutions", type=float, default=2.0)
    p.add_argument("--cores", type=int, default=1)
    p.add_argument("--events", type=int, default=256)
    p.add_argument("--json", default=None, help="also write members/s per case to this file")
    p.add_argument(
        "--engine",
        default="",
        help="time run_ensemble with these engines (lockstep,refill) instead of the solves",
    )
    p.add_argument("--chunk", type=int, default=64, help="--engine: refill's chunk size")
    a = p.parse_args()
    a.sizes = [int(x) for x in a.lanes.split(",") if x]
    a.engines = [e for e in a.engine.split(",") if e]
    for e in a.engines:
        if e not in ("lockstep", "refill"):
            p.error(f"--engine takes lockstep and/or refill, got {e!r}")
    for size in a.sizes:
        if a.members % size:
            p.error(f"--members must be a multiple of every size in --lanes ({size})")
    if "jax" in sys.modules:
        raise RuntimeError("import this script before jax: it sets XLA_FLAGS")
    os.environ.setdefault(
        "XLA_FLAGS",
        "--xla_force_host_platform_device_count=1 --xla_cpu_use_fusion_emitters=false",
    )
    cores = sorted(os.sched_getaffinity(0))[: a.cores]
    os.sched_setaffinity(0, cores)
    print(
        f"lane refilling against lockstep chunks; {os.cpu_count()} CPUs, pinned to {len(cores)} "
        f"core(s); load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
        f"XLA_FLAGS={os.environ['XLA_FLAGS']!r}"
    )
    bench = run_engines if a.engines else run_case
    figures = {case: bench(case, a) for case in a.case.split(",")}
    print(f"\nload average at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(figures, f)


if __name__ == "__main__":
    main()
