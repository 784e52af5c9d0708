"""Every target of issue 25 measured in one run, in one table.

Single runs against compiled CVODES, ensembles (lockstep and refilled lanes), the 1000-member
Monte Carlo, throughput against a serial loop, compile cold and warm, the cost of the extremes.

Usage:
    python benchmarks/throughput.py [--quick] [--json PATH] [--pin-cpu 1] [--skip PART,...]

Runs the existing benchmarks, each in its own process(es) as they run alone, and reads their
figures (their ``--json`` files); their own output is shown as it comes:

- ``cases``: ``bench_cases.py`` (cases a, b, c; ``auto``'s method with extremes and without, each
  in a worker process pinned to ``--pin-cpu``; CVODES measured in this run through CasADi with
  C-compiled functions when CasADi is installed, else issue 13's quoted figures; compile cold and
  warm as ``jaxclear run`` sees it);
- ``extremes``: ``extremes_overhead.py`` pinned to ``--pin-cpu`` (extremes on against off, one
  process, best of the repeats);
- ``lanes``: ``lane_refill.py`` pinned to ``--pin-cpu`` (``solve_members``' refilled lanes
  against lockstep chunks of ``map_members``, cases a and c, one core);
- ``ensemble``: ``bench_ensemble.py`` (``run_ensemble`` against a serial loop, 1 and 2 devices);
- ``montecarlo``: ``bench_ensemble.py --montecarlo N --devices 2`` twice on one empty folder,
  JAX's compilation cache and jaxclear's store of compiled programs both in it (as ``jaxclear
  montecarlo`` keeps them; ``EQX_ON_ERROR=nan``, as ``jaxclear run`` sets it so that the solve
  can be stored): cold, then warm (the chunk's programs loaded, not traced or compiled).

Then prints one table: every target of issue 25, the measured value, the target and met / NOT
met, with the machine state (load average, CPUs, versions, git commit). ``--quick`` cuts members,
repeats and lane widths (a smoke run of a few minutes, not the targets' figures); the full run
takes 15-20 minutes on the 2-core machine. Figures only; asserts nothing.
"""

import argparse
import importlib.metadata
import importlib.util
import json
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

PARTS = ("cases", "extremes", "lanes", "ensemble", "montecarlo")
SETTINGS = {
    # part: (quick, full) arguments
    "cases": (["--repeats", "1"], ["--repeats", "3"]),
    "extremes": (["--repeats", "1"], ["--repeats", "5"]),
    "lanes": (
        ["--members", "16", "--lanes", "8", "--repeats", "1"],
        ["--members", "128", "--lanes", "8,32", "--repeats", "1"],
    ),
    "ensemble": (
        ["--chunks", "16", "--members", "16", "--serial", "2", "--devices", "1"],
        ["--chunks", "16,64", "--members", "64", "--serial", "6", "--devices", "1,2"],
    ),
    "montecarlo": (["--montecarlo", "64"], ["--montecarlo", "1000"]),
}


def _git(*args):
    done = subprocess.run(["git", *args], capture_output=True, text=True, cwd=REPO)
    return done.stdout.strip()


def _code():
    """The commit, and whether jaxclear/ has uncommitted changes (others may edit it meanwhile)."""
    dirty = _git("status", "--short", "jaxclear")
    return _git("rev-parse", "--short", "HEAD") + (" + jaxclear/ modified" if dirty else "")


def _load(values=None):
    return " ".join(f"{x:.2f}" for x in (values or os.getloadavg()))


def _version(name):
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


def _run_part(name, script, args, out, log, pin=None, env=None):
    """Runs one benchmark script with ``--json``; its figures, or None when it failed. Keeps the
    code it ran (``_code()`` at its start), its wall time and the load in ``log[name]``."""
    path = os.path.join(out, f"{name}.json")
    cmd = [sys.executable, os.path.join(HERE, script), *args, "--json", path]
    if pin is not None:
        cmd = ["taskset", "-c", str(pin), *cmd]
    shown = shlex.join(os.path.relpath(c, REPO) if c.startswith(HERE) else c for c in cmd[:-2])
    log[name] = dict(code=_code(), load_start=os.getloadavg())
    print(f"\n=== {name}: {shown}  (git {log[name]['code']}, load average {_load()})", flush=True)
    t = time.perf_counter()
    done = subprocess.run(cmd, cwd=REPO, env=env)
    log[name].update(wall_s=time.perf_counter() - t, load_end=os.getloadavg())
    print(
        f"=== {name}: {log[name]['wall_s']:.0f} s, exit {done.returncode}, load average {_load()}",
        flush=True,
    )
    if done.returncode or not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


class Table:
    """Rows of targets: value, target, status (met, NOT met, not measured, not comparable: a quick
    run's smaller Monte Carlo; "-" for a figure without a target) and a note."""

    def __init__(self):
        self.rows = []

    def add(self, target, value, unit, limit=None, at_least=False, note="", comparable=True):
        goal, status = "-", "-"
        if limit is not None:
            goal = f"{'>=' if at_least else '<='} {limit:g}{unit}"
            if value is None:
                status = "not measured"
            elif not comparable:
                status = "not comparable"
            else:
                status = "met" if (value >= limit if at_least else value <= limit) else "NOT met"
        self.rows.append(
            dict(target=target, value=value, unit=unit, goal=goal, status=status, note=note)
        )

    def print(self):
        print(f"\n{'target':<44}{'measured':>11}  {'goal':<10}{'status':<15}note")
        for r in self.rows:
            value = "-" if r["value"] is None else f"{r['value']:.3g}{r['unit']}"
            print(f"{r['target']:<44}{value:>11}  {r['goal']:<10}{r['status']:<15}{r['note']}")


def _ok(r):
    return r is not None and "skipped" not in r and r["succeeded"]


def _cases_rows(table, cases):
    """Single runs against CVODES and compile cold / warm; the CVODES time per case."""
    cvodes = {}
    if cases is None:
        return cvodes
    single = {"a": 1.5, "b": 1.5, "c": 2.5}
    for row in cases["rows"]:
        case, auto = row["case"], row["auto"]
        measured = row["cvodes"] is not None
        cv = row["cvodes"]["run_s"] if measured else cases["cvodes_quoted"][case]
        cvodes[case] = (cv, measured)
        run, bare = row["runs"].get(auto), row["bare"]
        if _ok(run):
            note = f"{auto}, {run['run_s']:.3f} s, {run['steps']} steps; CVODES {cv:.3f} s"
            note += " (measured)" if measured else " (quoted, issue 13)"
            if _ok(bare):
                note += (
                    f"; bare {bare['run_s'] / cv:.2f}x, extremes "
                    f"+{100 * (run['run_s'] / bare['run_s'] - 1):.0f} %"
                )
            table.add(
                f"single run {case}, extremes on, vs CVODES",
                run["run_s"] / cv,
                "x",
                single[case],
                note=note,
            )
        else:
            table.add(
                f"single run {case}, extremes on, vs CVODES", None, "x", single[case], note="failed"
            )
    for kind, limit in (("cold", 5.0), ("warm", 1.0)):
        for row in cases["rows"]:
            r = row[kind]
            table.add(
                f"compile {kind}, case {row['case']} ({row['auto']})",
                r["compile_s"] if _ok(r) else None,
                " s",
                limit,
                note="eager first call minus run, JAX cache + jaxclear store"
                + (", empty folder" if kind == "cold" else ", folder of the cold run"),
            )
    return cvodes


def _lanes_rows(table, lanes, cvodes):
    if lanes is None:
        return
    for case, fig in lanes.items():
        rates = {k: statistics.median(v) for k, v in fig["members_per_s"].items()}
        sizes = sorted({int(k.split()[1]) for k in rates})
        best = max(sizes, key=lambda s: rates[f"lanes {s}"])
        rate = rates[f"lanes {best}"]
        if case in cvodes:
            cv, measured = cvodes[case]
            table.add(
                f"ensemble member refilled, case {case}, vs CVODES",
                1.0 / rate / cv,
                "x",
                0.5,
                note=f"{fig['method']}, {best} lanes, {rate:.2f} members/s on 1 core "
                f"({fig['members']} members), {1 / rate:.3f} s/member; CVODES {cv:.3f} s"
                + ("" if measured else " (quoted)"),
            )
        for size in sizes:
            lanes_rate, lockstep = rates[f"lanes {size}"], rates[f"lockstep {size}"]
            note = f"member order; {lanes_rate / rates[f'sorted {size}']:.2f}x cost-sorted lockstep"
            if case in cvodes:
                note += f"; a lockstep member {1 / lockstep / cvodes[case][0]:.2f}x CVODES"
            table.add(
                f"refilled / lockstep, case {case}, {size} lanes",
                lanes_rate / lockstep,
                "x",
                note=note,
            )


def _ensemble_rows(table, ensemble):
    if ensemble is None:
        return
    for d, fig in sorted(ensemble.items()):
        serial = fig["serial_s_per_member"]
        per_core = {c["chunk"]: c["members"] / c["run_s"] * serial / int(d) for c in fig["chunks"]}
        chunk = max(per_core, key=per_core.get)
        table.add(
            f"ensemble throughput per core, {d} device(s)",
            per_core[chunk],
            "x",
            5.0,
            at_least=True,
            note=f"run_ensemble ({fig.get('engine', 'lockstep')}), best chunk {chunk} of "
            + ", ".join(map(str, per_core))
            + f"; serial loop {serial:.3f} s/member on {fig['cores']} core(s)",
        )


def _montecarlo_rows(table, runs):
    for label, fig, entries in runs:
        mc = None if fig is None else fig.get("2", {}).get("montecarlo")
        table.add(
            f"Monte Carlo case a, {'?' if mc is None else mc['members']} members, {label} cache",
            None if mc is None else mc["wall_s"],
            " s",
            30.0,
            comparable=mc is not None and mc["members"] == 1000,
            note="run_ensemble"
            + ("" if mc is None else f" ({fig['2'].get('engine', 'lockstep')})")
            + ", 2 devices on 2 cores, compilation included"
            + ("" if mc is None else f", {mc['members']} members, {mc['failed']} failed")
            + (f", chunks of {mc['chunk_size']}" if mc and "chunk_size" in mc else "")
            + f"; cache folder (JAX's and jaxclear's store) {entries} entries before",
        )


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="smoke run: fewer members and repeats")
    p.add_argument("--json", default=None, help="also write the table and the figures here")
    p.add_argument("--pin-cpu", type=int, default=1, help="CPU for the one-core parts")
    p.add_argument("--skip", default="", help=f"parts to leave out, of {','.join(PARTS)}")
    a = p.parse_args()
    skip = {s for s in a.skip.split(",") if s}
    if skip - set(PARTS):
        p.error(f"--skip takes parts of {','.join(PARTS)}, got {','.join(sorted(skip))}")
    mode = 0 if a.quick else 1
    machine = dict(
        commit=_code(),
        cpus=os.cpu_count(),
        load_start=os.getloadavg(),
        jax=_version("jax"),
        jaxclear=_version("jaxclear"),
        casadi=_version("casadi") if importlib.util.find_spec("casadi") else None,
        python=platform.python_version(),
        machine=platform.machine(),
        started=time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        quick=a.quick,
        pin_cpu=a.pin_cpu,
        parts={},
    )
    log = machine["parts"]
    t0 = time.perf_counter()
    parts = {}
    mc_runs = []
    with tempfile.TemporaryDirectory(prefix="jaxclear-throughput-") as out:
        if "cases" not in skip:
            args = ["--cases", "a,b,c", "--methods", "", "--pin-cpu", str(a.pin_cpu)]
            args += ["--cvodes-jit", *SETTINGS["cases"][mode]]
            parts["cases"] = _run_part("cases", "bench_cases.py", args, out, log)
        if "extremes" not in skip:
            args = SETTINGS["extremes"][mode]
            parts["extremes"] = _run_part(
                "extremes", "extremes_overhead.py", args, out, log, a.pin_cpu
            )
        if "lanes" not in skip:
            args = ["--case", "a,c", *SETTINGS["lanes"][mode]]
            parts["lanes"] = _run_part("lanes", "lane_refill.py", args, out, log, a.pin_cpu)
        if "ensemble" not in skip:
            args = ["--case", "a", *SETTINGS["ensemble"][mode]]
            parts["ensemble"] = _run_part("ensemble", "bench_ensemble.py", args, out, log)
        if "montecarlo" not in skip:
            cache = os.path.join(out, "jax-cache")
            os.makedirs(cache)
            env = dict(os.environ, JAX_COMPILATION_CACHE_DIR=cache, EQX_ON_ERROR="nan")
            args = ["--case", "a", "--devices", "2", *SETTINGS["montecarlo"][mode]]
            for label in ("cold", "warm"):
                entries = len(os.listdir(cache))
                fig = _run_part(f"montecarlo-{label}", "bench_ensemble.py", args, out, log, env=env)
                mc_runs.append((label, fig, entries))
                parts[f"montecarlo-{label}"] = fig
    machine["load_end"] = os.getloadavg()
    machine["wall_s"] = time.perf_counter() - t0

    table = Table()
    cvodes = _cases_rows(table, parts.get("cases"))
    if parts.get("extremes") is not None:
        for case, fig in parts["extremes"].items():
            table.add(
                f"extremes overhead, case {case}",
                100 * (fig["on_s"] / fig["off_s"] - 1),
                " %",
                8.0,
                note=f"{fig['steps']} steps, off {fig['off_s']:.3f} s, on {fig['on_s']:.3f} s, "
                "best of repeats, one process"
                + (", slider_crank's default laws at O, A, B" if case == "c" else ""),
            )
    _lanes_rows(table, parts.get("lanes"), cvodes)
    _ensemble_rows(table, parts.get("ensemble"))
    _montecarlo_rows(table, mc_runs)
    table.add(
        "GPU, 4096 members vs one CPU core",
        None,
        "x",
        100.0,
        at_least=True,
        note="not run by this command (issue 25, part 5: a lent GPU)",
    )

    print(
        f"\nissue 25 targets{' (QUICK: fewer members and repeats, not the figures)' if a.quick else ''}"
        f"; jaxclear {machine['jaxclear']} (git {machine['commit']}), jax {machine['jax']}, "
        f"python {machine['python']}, casadi {machine['casadi'] or 'absent'}, "
        f"{machine['cpus']} CPUs {machine['machine']}, one-core parts pinned to CPU {a.pin_cpu}"
    )
    print(
        f"started {machine['started']}, load average {_load(machine['load_start'])} at the start, "
        f"{_load(machine['load_end'])} at the end; "
        f"{machine['wall_s'] / 60:.1f} min"
    )
    codes = {part["code"] for part in log.values()} - {machine["commit"]}
    if codes:
        print(
            "the code changed during the run: "
            + ", ".join(f"{name} ran at {part['code']}" for name, part in log.items())
        )
    table.print()
    if a.json:
        with open(a.json, "w") as f:
            json.dump(dict(machine=machine, rows=table.rows, parts=parts), f, indent=1)


if __name__ == "__main__":
    main()
