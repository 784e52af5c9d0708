"""Ensemble throughput: members per second of ``jaxclear.run_ensemble`` against a serial loop.

Usage:
    python benchmarks/bench_ensemble.py [--case a|c] [--chunks 1,16,64,256,1024] [--members 64]
        [--devices 1,2] [--serial 8] [--revolutions 2] [--order cost] [--solver auto]
        [--montecarlo 1000] [--json PATH]

The benchmark slider–crank at 5000 rpm (Lankarani–Nikravesh c_e = 0.9, no gravity; case a:
clearance joint B, modified Coulomb μ = 0.01; c: O, A, B, LuGre), 2 revolutions, statistics from
the second, 360 output points per revolution, every member's clearances drawn uniformly from
0.5 mm ± 10 % (seed 0).

Each device count runs in a fresh subprocess with
``XLA_FLAGS=--xla_force_host_platform_device_count=D --xla_cpu_use_fusion_emitters=false``
(the ``jaxclear`` command's flags), pinned to D cores. In it:
- serial loop: ``--serial`` members one after the other, each a ``jaxclear.simulate`` of the
  member and of its ideal mechanism plus the statistics (the work of one ensemble member), after
  a warm-up call; seconds per member;
- per chunk size C: a warm-up ``run_ensemble`` over C members (compilation), then a timed run
  over max(C, ``--members``) members (a multiple of C); members per second and the speed-up per
  member against the serial loop of the same process;
- ``--montecarlo N``: a Monte Carlo of N members at the default chunk size (``--mc-chunk K``
  for another) in a fresh process,
  wall time including compilation (the "1000 members" target of issue 11). With
  ``JAX_COMPILATION_CACHE_DIR`` set, jaxclear's store of compiled programs uses that folder too
  (``jaxclear.enable_compilation_cache``, as ``jaxclear montecarlo`` does by default), so a
  second run loads the refilled chunk's programs instead of tracing and compiling them.
Prints figures only; asserts nothing.
"""

import argparse
import json
import os
import subprocess
import sys
import time

RPM = 5000.0


def _mechanism(case):
    import jaxclear  # noqa: F401
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    return slider_crank(
        rpm=RPM,
        clearance_joints="B" if case == "a" else "O,A,B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(0.01) if case == "a" else LuGre(),
        gravity=False,
    )


def _values(mechanism, n):
    import numpy as np

    rng = np.random.default_rng(0)
    return {
        f"{j.name}.clearance": 5e-4 * rng.uniform(0.9, 1.1, n) for j in mechanism.clearance_joints
    }


def worker(a):
    import jax
    import numpy as np

    import jaxclear

    mech = _mechanism(a.case)
    period = 60.0 / RPM
    t1 = a.revolutions * period
    start = period
    points = int(round(a.revolutions * 360)) + 1
    options = dict(statistics_start=start, num_points=points, solver=a.solver)
    out = {"devices": len(jax.local_devices()), "chunks": [], "engine": a.engine}
    if a.montecarlo:
        folder = os.environ.get("JAX_COMPILATION_CACHE_DIR")
        if folder:  # as `jaxclear montecarlo` does: whole compiled programs kept there too
            jaxclear.enable_compilation_cache(folder)
        quiet = jaxclear.EnsembleSettings(progress=False, engine=a.engine, chunk_size=a.mc_chunk)
        t = time.perf_counter()
        r = jaxclear.run_ensemble(mech, _values(mech, a.montecarlo), t1, settings=quiet, **options)
        out["montecarlo"] = {
            "members": a.montecarlo,
            "chunk_size": jaxclear.studies.chunk_size_of(quiet),
            "wall_s": time.perf_counter() - t,
            "failed": int((~r.succeeded).sum()),
        }
        print(json.dumps(out))
        return
    # serial loop of single runs: the work of one member each
    ideal = jaxclear.ideal_mechanism
    solver = jaxclear.recommended_solver(mech) if a.solver == "auto" else a.solver
    vals = _values(mech, a.serial + 1)

    def single(i):
        m = jaxclear.with_parameters(mech, {k: v[i] for k, v in vals.items()})
        tr = jaxclear.simulate(m, t1, num_points=points, statistics_start=start, solver=solver)
        jaxclear.simulate(ideal(m), t1, num_points=points, solver="fast", extremes=False)
        return {k: float(v) for k, v in jaxclear.analysis.statistics(tr).items()}

    single(a.serial)
    t = time.perf_counter()
    for i in range(a.serial):
        single(i)
    out["serial_s_per_member"] = (time.perf_counter() - t) / a.serial
    for chunk in a.chunks:
        n = max(chunk, -(-a.members // chunk) * chunk)
        warm = jaxclear.EnsembleSettings(chunk_size=chunk, progress=False, engine=a.engine)
        t = time.perf_counter()
        jaxclear.run_ensemble(mech, _values(mech, chunk), t1, settings=warm, **options)
        first = time.perf_counter() - t
        settings = jaxclear.EnsembleSettings(
            chunk_size=chunk, order=a.order, progress=False, engine=a.engine
        )
        t = time.perf_counter()
        r = jaxclear.run_ensemble(mech, _values(mech, n), t1, settings=settings, **options)
        run = time.perf_counter() - t
        steps = r.num_steps[r.succeeded]
        out["chunks"].append(
            {
                "chunk": chunk,
                "members": n,
                "compile_s": first - run * chunk / n,
                "run_s": run,
                "steps": [int(steps.min()), int(np.median(steps)), int(steps.max())],
                "failed": int((~r.succeeded).sum()),
            }
        )
    print(json.dumps(out))


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default="a", choices=("a", "c"))
    p.add_argument("--chunks", default="1,16,64,256,1024")
    p.add_argument("--members", type=int, default=64)
    p.add_argument("--devices", default="1,2")
    p.add_argument("--serial", type=int, default=8)
    p.add_argument("--revolutions", type=float, default=2.0)
    p.add_argument("--order", default="cost", choices=("cost", "index"))
    p.add_argument("--solver", default="auto")
    p.add_argument(
        "--engine",
        default="refill",
        choices=("lockstep", "refill"),
        help="run_ensemble's engine (EnsembleSettings.engine, default refill as the library's: "
        "8 lanes per device share)",
    )
    p.add_argument("--montecarlo", type=int, default=0)
    p.add_argument(
        "--mc-chunk",
        type=int,
        default=None,
        help="chunk size of --montecarlo (default: the engine's, DEFAULT_CHUNKS)",
    )
    p.add_argument("--json", default=None, help="also write each device count's figures here")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args()
    a.chunks = [int(c) for c in a.chunks.split(",") if c]
    if a.worker:
        worker(a)
        return
    print(
        f"case {a.case}, {a.revolutions:g} revolutions at {RPM:g} rpm, clearances 0.5 mm +- 10 %, "
        f"solver {a.solver}, order {a.order}; {os.cpu_count()} CPUs"
    )
    figures = {}
    for d in [int(x) for x in a.devices.split(",")]:
        env = dict(
            os.environ,
            XLA_FLAGS=f"--xla_force_host_platform_device_count={d} "
            "--xla_cpu_use_fusion_emitters=false",
        )
        cores = sorted(os.sched_getaffinity(0))[:d]
        args = [sys.executable, __file__, "--worker", *sys.argv[1:]]
        t = time.perf_counter()
        done = subprocess.run(
            args,
            env=env,
            capture_output=True,
            text=True,
            preexec_fn=lambda cores=cores: os.sched_setaffinity(0, cores),
        )
        if done.returncode:
            print(done.stderr[-3000:])
            continue
        r = json.loads(done.stdout.strip().splitlines()[-1])
        figures[d] = dict(r, cores=len(cores), process_s=time.perf_counter() - t)
        if a.montecarlo:
            m = r["montecarlo"]
            print(
                f"{d} device(s) on {len(cores)} core(s): Monte Carlo of {m['members']} members "
                f"(chunks of {m['chunk_size']}) in "
                f"{m['wall_s']:.1f} s wall including compilation ({m['failed']} failed); "
                f"process {time.perf_counter() - t:.1f} s"
            )
            continue
        serial = r["serial_s_per_member"]
        print(
            f"\n{r['devices']} device(s) on {len(cores)} core(s): serial loop {serial:.4f} s/member "
            f"({1 / serial:.2f} members/s)"
        )
        print(
            f"{'chunk':>6} {'members':>7} {'compile s':>9} {'run s':>8} {'members/s':>9} "
            f"{'vs serial':>9} {'per core':>8}  steps min/median/max"
        )
        for c in r["chunks"]:
            rate = c["members"] / c["run_s"]
            print(
                f"{c['chunk']:6d} {c['members']:7d} {c['compile_s']:9.1f} {c['run_s']:8.2f} "
                f"{rate:9.2f} {rate * serial:8.2f}x {rate * serial / d:7.2f}x  "
                f"{'/'.join(map(str, c['steps']))}"
                + (f"  ({c['failed']} failed)" if c["failed"] else "")
            )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(figures, f)


if __name__ == "__main__":
    main()
