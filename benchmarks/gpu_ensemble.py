"""Ensembles and a vmapped gradient batch on a GPU, against one CPU core of the same machine.

Usage (on a machine with a CUDA GPU and ``jax[cuda]``; nothing in the test suite needs one):
    python benchmarks/gpu_ensemble.py [--members 4096] [--cases a,c] [--gradient 1024]
        [--cpu-members 16] [--json PATH]

Cases as in ``bench_ensemble.py``: the benchmark slider–crank at 5000 rpm, 2 revolutions,
statistics from the second, 721 output points, clearances drawn uniformly from 0.5 mm ± 10 %
(seed 0); a: joint B, L-N c_e = 0.9, modified Coulomb μ = 0.01; c: O, A, B, LuGre.

- **GPU**: ``jaxclear.run_ensemble`` of ``--members`` members in one chunk
  (``EnsembleSettings(chunk_size=members)``): the first call (compilation and run) and a second,
  timed call (members per second); then ``jax.jit(jax.vmap(jax.grad(loss)))`` over ``--gradient``
  clearances of case a, loss = the crank torque's RMS over one revolution (``simulate``'s default
  solver and error-controlled sensitivities).
- **One CPU core** (``JAX_PLATFORMS=cpu``, one subprocess per case pinned to its own core, run
  while the GPU works): the serial loop of ``bench_ensemble.py`` (a member's ``simulate`` and its
  ideal mechanism plus the statistics, after a warm-up), ``run_ensemble`` in chunks of
  ``--cpu-members`` (after a warm-up chunk), and the gradient, one member at a time and vmapped
  over ``--cpu-members``. A core's rate is the better of its serial loop and its chunks.

Prints one JSON line per measurement as it goes, then a table of members per second and the ratio
GPU / one CPU core. Figures only; asserts nothing.
"""

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_ensemble import RPM, _mechanism, _values  # noqa: E402

PERIOD = 60.0 / RPM
T1 = 2 * PERIOD
POINTS = 721


def _emit(record, sink):
    line = json.dumps(record)
    print(line, flush=True)
    if sink is not None:
        sink.write(line + "\n")
        sink.flush()


def _ensemble(mech, n, chunk):
    import numpy as np

    import jaxclear

    settings = jaxclear.EnsembleSettings(chunk_size=chunk, progress=False)
    t = time.perf_counter()
    r = jaxclear.run_ensemble(
        mech, _values(mech, n), T1, statistics_start=PERIOD, num_points=POINTS, settings=settings
    )
    wall = time.perf_counter() - t
    steps = np.asarray(r.num_steps)[np.asarray(r.succeeded)]
    return (
        wall,
        int((~np.asarray(r.succeeded)).sum()),
        ([int(steps.min()), int(np.median(steps)), int(steps.max())] if steps.size else []),
    )


def _loss():
    import jaxclear

    base = _mechanism("a")

    def loss(c):
        m = jaxclear.with_parameters(base, {"B.clearance": c})
        traj = jaxclear.simulate(m, PERIOD, num_points=2)
        return jaxclear.analysis.statistics(traj)["crank_torque_rms"]

    return loss


def _gradient_batch(n):
    import jax
    import jax.numpy as jnp
    import numpy as np

    cs = jnp.asarray(5e-4 * np.random.default_rng(1).uniform(0.9, 1.1, n))
    batch = jax.jit(jax.vmap(jax.grad(_loss())))
    t = time.perf_counter()
    g = np.asarray(batch(cs))
    first = time.perf_counter() - t
    t = time.perf_counter()
    g = np.asarray(batch(cs))
    run = time.perf_counter() - t
    return first, run, int(np.sum(~np.isfinite(g))), float(np.median(g))


def cpu_worker(a, case, sink):
    """One core: the serial loop, chunks of ``cpu_members``; for ``case == "gradient"`` the
    gradient one member at a time and vmapped."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxclear

    if case == "gradient":
        grad = jax.jit(jax.grad(_loss()))
        cs = 5e-4 * np.random.default_rng(1).uniform(0.9, 1.1, 4)
        float(grad(jnp.asarray(cs[0])))
        t = time.perf_counter()
        for c in cs[1:]:
            float(grad(jnp.asarray(c)))
        serial = (time.perf_counter() - t) / (len(cs) - 1)
        _emit({"cpu": case, "serial_s_per_member": serial}, sink)
        first, run, bad, med = _gradient_batch(a.cpu_members)
        _emit(
            {
                "cpu": case,
                "batch": a.cpu_members,
                "compile_s": first - run,
                "run_s": run,
                "nonfinite": bad,
                "median_gradient": med,
            },
            sink,
        )
        return
    mech = _mechanism(case)
    vals = _values(mech, 4)
    solver = jaxclear.recommended_solver(mech)

    def single(i):
        m = jaxclear.with_parameters(mech, {k: v[i] for k, v in vals.items()})
        tr = jaxclear.simulate(m, T1, num_points=POINTS, statistics_start=PERIOD, solver=solver)
        jaxclear.simulate(
            jaxclear.ideal_mechanism(m), T1, num_points=POINTS, solver="fast", extremes=False
        )
        jaxclear.analysis.statistics(tr)

    single(3)
    t = time.perf_counter()
    for i in range(3):
        single(i)
    _emit({"cpu": case, "serial_s_per_member": (time.perf_counter() - t) / 3}, sink)
    k = a.cpu_members
    first, _, _ = _ensemble(mech, k, k)
    wall, failed, steps = _ensemble(mech, 2 * k, k)
    _emit(
        {
            "cpu": case,
            "chunk": k,
            "members": 2 * k,
            "run_s": wall,
            "compile_s": first - wall / 2,
            "failed": failed,
            "steps": steps,
        },
        sink,
    )


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--members", type=int, default=4096)
    p.add_argument("--cases", default="a,c")
    p.add_argument("--gradient", type=int, default=1024, help="0: no gradient batch")
    p.add_argument("--cpu-members", type=int, default=16)
    p.add_argument("--json", default=None, help="also write the JSON lines here")
    p.add_argument("--cpu-worker", default=None, help=argparse.SUPPRESS)
    a = p.parse_args()
    sink = open(a.json, "a") if a.json else None
    if a.cpu_worker:
        cpu_worker(a, a.cpu_worker, sink)
        return
    # the CPU baselines first, before this process imports JAX (no fork of a threaded process):
    # one core each, from the last cores (this process keeps the first ones for the GPU)
    cases = [c for c in a.cases.split(",") if c]
    cores = sorted(os.sched_getaffinity(0))
    workers = []
    jobs = cases + (["gradient"] if a.gradient else [])
    for k, job in enumerate(jobs):
        core = cores[-1 - k] if len(cores) > len(jobs) else cores[k % len(cores)]
        args = ["taskset", "-c", str(core), sys.executable, __file__, "--cpu-worker", job]
        args += ["--cpu-members", str(a.cpu_members)] + (["--json", a.json] if a.json else [])
        workers.append(
            subprocess.Popen(
                args,
                env=dict(os.environ, JAX_PLATFORMS="cpu"),
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
        )
    import jax

    import jaxclear

    _emit(
        {
            "jax": jax.__version__,
            "jaxclear": jaxclear.__version__,
            "backend": jax.default_backend(),
            "devices": [str(d) for d in jax.devices()],
            "cpus": os.cpu_count(),
        },
        sink,
    )
    results = {"gpu": {}, "cpu": {}}
    for case in cases:
        mech = _mechanism(case)
        first, _, _ = _ensemble(mech, a.members, a.members)
        wall, failed, steps = _ensemble(mech, a.members, a.members)
        rec = {
            "gpu": case,
            "members": a.members,
            "first_call_s": first,
            "run_s": wall,
            "members_per_s": a.members / wall,
            "failed": failed,
            "steps": steps,
        }
        results["gpu"][case] = rec
        _emit(rec, sink)
    if a.gradient:
        first, run, bad, med = _gradient_batch(a.gradient)
        rec = {
            "gpu": "gradient",
            "members": a.gradient,
            "first_call_s": first,
            "run_s": run,
            "members_per_s": a.gradient / run,
            "nonfinite": bad,
            "median_gradient": med,
        }
        results["gpu"]["gradient"] = rec
        _emit(rec, sink)
    for job, w in zip(jobs, workers):
        out, err = w.communicate()
        for line in out.splitlines():
            if line.startswith("{"):
                rec = json.loads(line)
                results["cpu"].setdefault(job, []).append(rec)
        if w.returncode:
            print(f"CPU worker {job} failed: {err.strip().splitlines()[-1:]}", flush=True)
    print(f"\n{'job':>8} {'GPU members/s':>13} {'CPU core members/s':>18}  {'ratio':>7}")
    for job, g in results["gpu"].items():
        rates = []
        for rec in results["cpu"].get(job, []):
            if "serial_s_per_member" in rec:
                rates.append(1.0 / rec["serial_s_per_member"])
            elif "run_s" in rec:
                rates.append(rec.get("members", rec.get("batch", 0)) / rec["run_s"])
        cpu = max(rates) if rates else float("nan")
        print(f"{job:>8} {g['members_per_s']:13.1f} {cpu:18.2f}  {g['members_per_s'] / cpu:6.1f}x")


if __name__ == "__main__":
    main()
