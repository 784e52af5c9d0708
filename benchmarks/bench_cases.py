"""The three benchmark cases in one run: ``auto`` against the fastest method and the CVODES reference.

Usage:
    python benchmarks/bench_cases.py [--cases a,b,c] [--methods lawson-tsit5,tsit5,kencarp5]
                                     [--repeats 3] [--pin-cpu K] [--xla-default] [--no-compile]
                                     [--cvodes auto|measure|quote] [--cvodes-jit] [--json PATH]

For each case of ``bench_clearance.py`` (benchmark slider–crank, 5000 rpm, 2 revolutions,
c = 0.5 mm, rtol 1e-6, atol 1e-9; a: joint B, L-N, modified Coulomb; b: O, A, B, same laws;
c: O, A, B, L-N, LuGre) every method runs in its own process (``bench_clearance.py``'s worker:
``jax.jit`` of a function calling ``jaxclear.simulate`` with its defaults, extremes tracked, 721
output points; run = median of ``--repeats`` calls after compilation). The table gives, per case:

- the method ``auto`` picks (``jaxclear.recommended_solver``) and its run time, steps and µs/step;
- ``bare``: ``auto``'s run time with ``extremes=False`` (no per-step observations: the same work
  as the CVODES reference, which integrates the equations only);
- the fastest of ``--methods`` (``auto``'s included) and its run time;
- the SUNDIALS CVODES figure the run is read against and the ratios: **measured in this run**
  when CasADi is installed (``pip install casadi``; ``cvodes_reference.py``: CVODES BDF through
  CasADi on the same smooth model, checked against the SciPy reference, same tolerances and grid,
  in its own process pinned like the workers; ``--cvodes-jit``: its functions compiled to C),
  else quoted from the project's issue 13 (BDF with a compiled C right-hand side, one pinned core
  of this 2-core machine; ``--cvodes quote`` forces the quoted figures);
- compile time of ``auto``'s solve, cold and warm: two more fresh processes sharing an empty
  cache folder with both of ``jaxclear run``'s caches on (JAX's persistent compilation cache and
  jaxclear's store of whole programs, ``jaxclear.enable_compilation_cache``), each timing an eager
  ``simulate`` call's first call minus its later run time (assembly, tracing, lowering and XLA
  compile when cold; loading the stored programs when warm).

Like ``jaxclear run``, workers compile with XLA's CPU fusion emitters off unless ``--xla-default``.
Figures only, no assertions; timings depend on the load (printed) and on ``--pin-cpu``.
"""

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_clearance as bc  # noqa: E402  (the workers live there)

CVODES_S = {"a": 0.075, "b": 0.111, "c": 0.102}
"""CVODES BDF + compiled C right-hand side, 2 revolutions, rtol 1e-6, atol 1e-9, one pinned core of
the project's 2-core machine (issue 13's table): what the run is read against without CasADi."""


def _cvodes(case, repeats, pin_cpu, jit, timeout=600.0):
    """CVODES through ``cvodes_reference.py`` in its own process: its result dict, or None."""
    cmd = [sys.executable, os.path.join(HERE, "cvodes_reference.py"), "--json", "--cases", case]
    cmd += ["--repeats", str(repeats)] + (["--jit"] if jit else [])
    if pin_cpu is not None:
        cmd = ["taskset", "-c", str(pin_cpu), *cmd]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=bc.REPO)
    except subprocess.TimeoutExpired:
        return None
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        err = (proc.stderr.strip().splitlines() or ["?"])[-1]
        print(f"case {case} CVODES failed: {err[:160]}", flush=True)
        return None
    return json.loads(lines[-1])


def _job(case, method, repeats):
    return dict(
        kind="jax",
        case=case,
        solver=method,
        revolutions=2.0,
        repeats=repeats,
        compile_method="aot",
        max_steps=200_000,
        rhs_cost=False,
        run_budget=120.0,
        first_contact=None,
    )


def _spawn(job, options, timeout=600.0):
    bc.SPAWN_OPTIONS.clear()
    bc.SPAWN_OPTIONS.update(options)
    result = bc.spawn(job, timeout)
    result["load"] = bc.load()
    return result


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default="a,b,c")
    p.add_argument("--methods", default="lawson-tsit5,tsit5,kencarp5")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--pin-cpu", type=int, default=None, help="pin each worker to this CPU")
    p.add_argument("--xla-default", action="store_true", help="keep XLA's CPU fusion emitters")
    p.add_argument("--no-compile", action="store_true", help="skip the cold/warm compile runs")
    p.add_argument(
        "--cvodes",
        choices=("auto", "measure", "quote"),
        default="auto",
        help="CVODES reference: measured here through CasADi (auto: if installed) or quoted",
    )
    p.add_argument("--cvodes-jit", action="store_true", help="CVODES with C-compiled functions")
    p.add_argument("--json", default=None, help="also write the workers' results to this file")
    a = p.parse_args()
    measure = a.cvodes == "measure" or (
        a.cvodes == "auto" and importlib.util.find_spec("casadi") is not None
    )
    if a.cvodes == "measure" and importlib.util.find_spec("casadi") is None:
        p.error("--cvodes measure needs CasADi: pip install casadi")

    import jax

    import jaxclear

    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=bc.REPO
    ).stdout.strip()
    dirty = subprocess.run(
        ["git", "status", "--short", "jaxclear"], capture_output=True, text=True, cwd=bc.REPO
    ).stdout.strip()
    options = dict(pin_cpu=a.pin_cpu, fast_compile=not a.xla_default)
    print(
        f"jaxclear {jaxclear.__version__} (git {head}{', jaxclear/ modified' if dirty else ''}), "
        f"jax {jax.__version__}, {os.cpu_count()} CPUs, load average "
        + " ".join(f"{x:.2f}" for x in os.getloadavg())
        + f"; workers pinned to CPU {a.pin_cpu}; XLA fusion emitters "
        + ("on" if a.xla_default else "off")
    )
    print(
        "2 revolutions at 5000 rpm, rtol 1e-6, atol 1e-9, extremes tracked, 721 points; run = "
        f"median of {a.repeats}; CVODES = "
        + (
            "measured in this run (cvodes_reference.py, CasADi"
            + (", C-compiled functions" if a.cvodes_jit else "")
            + ")\n"
            if measure
            else "issue 13's figures (not measured here)\n"
        )
    )
    methods = [m.strip() for m in a.methods.split(",") if m.strip()]
    rows = []
    for case in [c.strip() for c in a.cases.split(",") if c.strip()]:
        auto = jaxclear.recommended_solver(bc.case_mechanism(case)).method
        runs = {}
        for method in dict.fromkeys([auto, *methods]):
            r = _spawn(_job(case, method, a.repeats), options)
            runs[method] = r
            status = r.get("skipped") or (
                f"run {r['run_s']:.3f} s, {r['steps']} steps ({r['rejected']} rejected), "
                f"{1e6 * r['run_s'] / r['steps']:.1f} us/step, compile {r['compile_s']:.1f} s"
                + ("" if r["succeeded"] else f", FAILED at t = {r['t_final']:.3g} s")
            )
            print(f"case {case} {method:<13} {status}  (load {r['load']:.2f})", flush=True)
        bare = _spawn(dict(_job(case, auto, a.repeats), extremes=False), options)
        if "skipped" not in bare:
            print(
                f"case {case} {auto:<13} without extremes: run {bare['run_s']:.3f} s, "
                f"{bare['steps']} steps  (load {bare['load']:.2f})",
                flush=True,
            )
        cvodes = None
        if measure:
            cvodes = _cvodes(case, a.repeats, a.pin_cpu, a.cvodes_jit)
            if cvodes is not None:
                print(
                    f"case {case} CVODES        run {cvodes['run_s']:.3f} s, "
                    f"{cvodes['steps']} steps  (load {bc.load():.2f})",
                    flush=True,
                )
        cold = warm = None
        if not a.no_compile:
            with tempfile.TemporaryDirectory(prefix="jaxclear-cache-") as cache:
                cold, warm = (
                    _spawn(
                        dict(_job(case, auto, 3), compile_method="first-call"),
                        dict(options, compile_cache=cache, store=True),
                    )
                    for _ in range(2)
                )
        rows.append((case, auto, runs, bare, cold, warm, cvodes))

    ok = lambda r: r is not None and "skipped" not in r and r["succeeded"]  # noqa: E731
    print(
        f"\n{'case':<5}{'auto':<14}{'run s':>7}{'steps':>7}{'us/step':>8}  {'fastest':<14}{'run s':>7}"
        f"  {'CVODES s':>8}{'auto/CV':>8}{'fast/CV':>8}  {'bare s':>7}{'bare/CV':>8}"
        f"  {'compile cold':>12}{'warm':>6}"
    )
    for case, auto, runs, bare, cold, warm, cvodes in rows:
        done = {m: r for m, r in runs.items() if ok(r)}
        if auto not in done or not done:
            print(f"{case:<5}{auto:<14} failed or skipped")
            continue
        r = done[auto]
        best = min(done, key=lambda m: done[m]["run_s"])
        cv = cvodes["run_s"] if cvodes is not None else CVODES_S[case]
        bare_text = (
            f"{bare['run_s']:7.3f}{bare['run_s'] / cv:8.2f}" if ok(bare) else f"{'-':>7}{'-':>8}"
        )
        compile_text = (
            f"{cold['compile_s']:11.1f}s{warm['compile_s']:5.1f}s"
            if ok(cold) and ok(warm)
            else f"{'-':>12}{'-':>6}"
        )
        print(
            f"{case:<5}{auto:<14}{r['run_s']:7.3f}{r['steps']:7d}{1e6 * r['run_s'] / r['steps']:8.1f}  "
            f"{best:<14}{done[best]['run_s']:7.3f}  {cv:8.3f}{' ' if cvodes else '*'}"
            f"{r['run_s'] / cv:7.2f}"
            f"{done[best]['run_s'] / cv:8.2f}  {bare_text}  {compile_text}"
        )
    if any(row[-1] is None for row in rows):
        print("* CVODES quoted from issue 13 (not measured in this run)")
    print(f"\nfinal load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if a.json:
        keys = ("case", "auto", "runs", "bare", "cold", "warm", "cvodes")
        with open(a.json, "w") as f:
            json.dump(dict(cvodes_quoted=CVODES_S, rows=[dict(zip(keys, r)) for r in rows]), f)


if __name__ == "__main__":
    main()
