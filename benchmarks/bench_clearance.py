"""Slider–crank with clearance joints (docs/model.md §6): jaxclear solvers against the SciPy reference.

Usage:
    python benchmarks/bench_clearance.py [--quick] [--cases a,b,c] [--solvers lawson-tsit5,tsit5,kencarp5,kvaerno5]
                                         [--repeats N] [--max-wall S] [--compile-method aot|first-call]
                                         [--no-scipy] [--scipy-method Radau] [--rhs-cost] [--agreement]
                                         [--pin-cpu K] [--compile-cache DIR] [--fast-compile]
                                         [--first-contact]

Cases (5000 rpm, 2 revolutions, c = 0.5 mm, R_B = 10 mm, steel, c_e = 0.9, no gravity, 360 output points
per revolution, rtol 1e-6, atol 1e-9, all smoothing widths at their defaults):
    a  one clearance joint B, Lankarani–Nikravesh, modified Coulomb μ = 0.01;
    b  three clearance joints O, A, B, Lankarani–Nikravesh, modified Coulomb μ = 0.01;
    c  three clearance joints O, A, B, Lankarani–Nikravesh, LuGre (defaults).
``--quick`` simulates 0.25 revolution instead of 2.

Reference figures from the issue (a 2-core machine, 2 revolutions):
    SUNDIALS CVODES BDF with a compiled C right-hand side: 0.10 s (case a), 0.15 s (case b), 0.12 s (case c);
    SciPy Radau ≈ 6 s (case a).

What is measured, per case and jaxclear solver, each in its own subprocess (so a hung or very slow
solve is killed after ``--max-wall`` seconds and reported as skipped, and no compiled code is shared):
    compile  ``--compile-method aot`` (default): ahead-of-time ``jax.jit(solve).lower(...)`` of a function
             calling the public ``jaxclear.simulate`` (tracing and lowering to StableHLO) and
             ``.compile()`` (XLA), timed separately; the run times are then calls of that compiled
             executable. ``first-call``: first ``jaxclear.simulate`` call minus
             the median of the steady-state calls (includes Python dispatch, assembly).
    run      median (and min) wall time of ``--repeats`` calls after compilation, including the output
             post-processing on the 721-point grid; ``us/step`` = run / steps.
    steps    diffrax ``num_steps`` (accepted + rejected) and ``num_rejected_steps``.
    rhs      (``--rhs-cost``) cost of one right-hand-side evaluation, and of one Jacobian (jacfwd), in
             a compiled ``fori_loop`` of 2000 calls: how much of a step is model evaluation.
    first contact  (``--first-contact``) max distance (µm) of each solver's journal orbits from a
             converged solution (Dopri8, rtol 1e-12) over the first 1.5 ms: the first contacts and,
             with LuGre, the first stick phase. Whether a solver run at rtol 1e-6 follows the
             converged solution there, or has already switched to another branch of the motion.
The SciPy reference (tests/reference/scipy_slider_crank.py, independent NumPy code, same model:
``smoothing_variant="jaxclear"``, jaxclear's Baumgarte gains) runs in smooth mode with ``--scipy-method`` (Radau) at the same
tolerances, without its contact-onset events; wall time of the integration only, nfev, njev and all
right-hand-side calls including finite-difference Jacobian columns.

Cycle statistics (to show the compared runs are the same model; they do not agree pointwise over two
revolutions, docs/model.md §5b): RMS slider acceleration and RMS crank torque over the last revolution
(over the whole window with --quick), peak normal force per clearance joint over the whole run. The
RMS values are sampled at 360 points/rev (33 µs) through impact spikes of 10–50 µs, so they scatter
by ±20 % between correct solvers; the peak forces agree to 0.1 %. ``--agreement`` adds the pointwise
check that is meaningful: first 1 ms (1/12 revolution, the first contacts), rtol 1e-10, jaxclear
Dopri8 against SciPy Radau, max distance between the journal-centre orbits per joint (µm) and max
normal-force difference relative to the peak.
The machine may be shared: the 1-minute load average is printed with every row. On an oversubscribed
machine XLA's CPU thread pool hurts these small, latency-bound loops: ``--pin-cpu K`` pins every
worker to CPU K (``os.sched_setaffinity`` before JAX starts, like ``taskset -c K``), which made the
runs up to 2x faster and far less variable on a loaded 2-core machine. ``--compile-cache DIR`` turns
on JAX's persistent compilation cache (the XLA part of the compile time is then paid once across
processes; tracing is not cached). It needs ``EQX_ON_ERROR=nan``, which the workers then set: JAX
refuses to cache executables with host callbacks, and diffrax's runtime checks (``eqx.error_if``)
are host callbacks otherwise. ``--fast-compile`` sets XLA_FLAGS=--xla_cpu_use_fusion_emitters=false
in the workers (what ``jaxclear run`` does by default). Prints figures only; no assertions.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import numpy as np

RPM = 5000.0
CLEARANCE = 5e-4
POINTS_PER_REVOLUTION = 360
RTOL, ATOL = 1e-6, 1e-9
CASES = {
    "a": dict(joints="B", friction="modified-coulomb", label="1 joint B, LN, mod. Coulomb mu=0.01"),
    "b": dict(
        joints="OAB", friction="modified-coulomb", label="3 joints OAB, LN, mod. Coulomb mu=0.01"
    ),
    "c": dict(joints="OAB", friction="lugre", label="3 joints OAB, LN, LuGre (defaults)"),
}
ISSUE_CVODES_S = {"a": 0.10, "b": 0.15, "c": 0.12}
ISSUE_SCIPY_RADAU_S = {"a": 6.0}
HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)


def load():
    return os.getloadavg()[0]


def case_mechanism(case: str):
    """The benchmark slider–crank of a case in ``CASES`` (L-N contact, c_e = 0.9, no gravity)."""
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    spec = CASES[case]
    friction = ModifiedCoulomb(0.01) if spec["friction"] == "modified-coulomb" else LuGre()
    return slider_crank(
        rpm=RPM,
        clearance_joints=",".join(spec["joints"]),
        clearance=CLEARANCE,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=friction,
        gravity=False,
    )


def grid(revolutions):
    t1 = revolutions * 60.0 / RPM
    n = int(round(revolutions * POINTS_PER_REVOLUTION)) + 1
    return t1, np.linspace(0.0, t1, n)


def cycle_stats(t, acc, torque, normal_forces, revolutions):
    """RMS slider acceleration / torque over the last revolution (whole window if < 2) and peak F_N."""
    t = np.asarray(t)
    period = 60.0 / RPM
    sel = t >= t[-1] - period - 1e-12 if revolutions >= 2 else np.ones(t.shape, bool)
    rms = lambda x: float(np.sqrt(np.mean(np.asarray(x)[sel] ** 2)))  # noqa: E731
    return dict(
        rms_acc=rms(acc),
        rms_torque=rms(torque),
        peak_fn={j: float(np.max(np.asarray(f))) for j, f in normal_forces.items()},
    )


# ----------------------------------------------------------------------------------- workers
def jax_worker(
    case,
    solver,
    revolutions,
    repeats,
    compile_method,
    max_steps,
    rhs_cost,
    run_budget,
    first_contact=None,
    extremes=True,
):
    t_import = time.perf_counter()
    import jax
    import jax.numpy as jnp

    import jaxclear

    t_import = time.perf_counter() - t_import
    spec = CASES[case]
    mech = case_mechanism(case)
    config = jaxclear.SolverConfig(method=solver, rtol=RTOL, atol=ATOL, max_steps=max_steps)
    t1, ts = grid(revolutions)
    out = dict(case=case, solver=solver, compile_method=compile_method, import_s=t_import)

    def block(traj):
        jax.block_until_ready(traj.t)
        jax.block_until_ready(traj.num_steps)
        return traj

    if compile_method == "aot":
        y0 = jaxclear.assemble(mech, 0.0)

        def solve(mech, ts, t1, y0):
            return jaxclear.simulate(
                mech, t1, ts=ts, y0=y0, solver=config, throw=False, extremes=extremes
            )

        args = (mech, jnp.asarray(ts), jnp.asarray(t1), y0)
        t0 = time.perf_counter()
        lowered = jax.jit(solve).lower(*args)
        out["trace_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        compiled = lowered.compile()
        out["xla_s"] = time.perf_counter() - t0
        out["compile_s"] = out["trace_s"] + out["xla_s"]

        def call():
            return block(compiled(*args))
    else:

        def call():
            return block(
                jaxclear.simulate(mech, t1, ts=ts, solver=config, throw=False, extremes=extremes)
            )

    runs = []
    t0 = time.perf_counter()
    traj = call()
    first = time.perf_counter() - t0
    if compile_method == "aot":
        runs.append(first)  # already compiled: the first call is a run
    spent = first
    while len(runs) < repeats and spent + (runs[-1] if runs else first) < run_budget:
        t0 = time.perf_counter()
        traj = call()
        runs.append(time.perf_counter() - t0)
        spent += runs[-1]
    if not runs:
        runs = [first]  # no steady-state call fitted in the budget: run time is an upper bound
        out["run_is_first_call"] = True
    out["run_s"] = statistics.median(runs)
    out["run_min_s"] = min(runs)
    out["n_runs"] = len(runs)
    if compile_method == "first-call":
        out["compile_s"] = first - out["run_s"]
    st = traj.stats()
    out.update(
        steps=st["num_steps"],
        rejected=st["num_rejected_steps"],
        succeeded=bool(st["succeeded"]),
        t_final=st["t_final"],
    )
    out["stats"] = cycle_stats(
        ts,
        np.asarray(traj.accelerations("slider")[:, 0]),
        np.asarray(traj.input_torque),
        {j: np.asarray(traj.clearance[j]["normal_force"]) for j in spec["joints"]},
        revolutions,
    )
    if rhs_cost:
        out.update(rhs_cost_us(mech, np.asarray(traj.y_final), t1))
    if first_contact:
        # Same shapes as the timed runs (only t1 and the grid values change): no new compile.
        ref = np.load(first_contact)
        ts_fc = jnp.asarray(ref["t"])
        if compile_method == "aot":
            fc = compiled(mech, ts_fc, jnp.asarray(float(ref["t"][-1])), y0)
        else:
            fc = jaxclear.simulate(
                mech, float(ref["t"][-1]), ts=np.asarray(ref["t"]), solver=config, throw=False
            )
        out["first_contact_um"] = {
            j: 1e6
            * float(
                np.max(
                    np.hypot(
                        np.asarray(fc.clearance[j]["ecc_x"]) - ref[j + "_ecc_x"],
                        np.asarray(fc.clearance[j]["ecc_y"]) - ref[j + "_ecc_y"],
                    )
                )
            )
            for j in spec["joints"]
        }
    return out


FIRST_CONTACT_S = 1.5e-3  # first contacts of every case and, with LuGre, the first stick phase
FIRST_CONTACT_RTOL = 1e-12


def first_contact_reference(case, path):
    """Converged journal orbits over the first ``FIRST_CONTACT_S`` (Dopri8, rtol 1e-12), saved to ``path``
    on a grid of the timed runs' size (so each solver reuses its compiled code)."""
    import jaxclear

    spec = CASES[case]
    mech = case_mechanism(case)
    n = grid(2.0)[1].size
    ts = np.linspace(0.0, FIRST_CONTACT_S, n)
    cfg = jaxclear.SolverConfig(
        method="dopri8",
        rtol=FIRST_CONTACT_RTOL,
        atol=FIRST_CONTACT_RTOL * 1e-3,
        max_steps=5_000_000,
    )
    t0 = time.perf_counter()
    tr = jaxclear.simulate(mech, FIRST_CONTACT_S, ts=ts, solver=cfg)
    arrays = {"t": ts}
    for j in spec["joints"]:
        arrays[j + "_ecc_x"] = np.asarray(tr.clearance[j]["ecc_x"])
        arrays[j + "_ecc_y"] = np.asarray(tr.clearance[j]["ecc_y"])
    np.savez(path, **arrays)
    return dict(
        case=case, path=path, steps=tr.stats()["num_steps"], wall_s=time.perf_counter() - t0
    )


def rhs_cost_us(mech, y, t):
    """Microseconds per vector-field evaluation and per jacfwd, inside a compiled loop."""
    import jax
    import jax.numpy as jnp

    from jaxclear.dynamics import vector_field

    n = 2000
    y = jnp.asarray(y)

    def loop(f):
        @jax.jit
        def run(y):
            def body(i, acc):
                return acc + f(jnp.asarray(t) + 1e-12 * i, y + 1e-15 * acc[: y.shape[0]].sum())

            return jax.lax.fori_loop(0, n, body, jnp.zeros_like(f(jnp.asarray(t), y)))

        jax.block_until_ready(run(y))
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            jax.block_until_ready(run(y))
            best = min(best, time.perf_counter() - t0)
        return 1e6 * best / n

    rhs = loop(lambda tt, yy: vector_field(tt, yy, mech))
    jac = loop(lambda tt, yy: jax.jacfwd(lambda z: vector_field(tt, z, mech))(yy).reshape(-1))
    return dict(rhs_us=rhs, jac_us=jac, n_state=int(y.shape[0]))


def baumgarte_gains():
    """jaxclear's default Baumgarte (alpha, beta), passed to the reference so both run the same model."""
    from jaxclear.mechanisms import slider_crank

    mech = slider_crank()
    return float(mech.baumgarte_alpha), float(mech.baumgarte_beta)


def scipy_worker(case, revolutions, method):
    alpha, beta = baumgarte_gains()
    sys.path.insert(0, os.path.join(REPO, "tests"))
    from reference.scipy_slider_crank import simulate

    spec = CASES[case]
    friction = ("modified-coulomb", 0.01) if spec["friction"] == "modified-coulomb" else ("lugre",)
    r = simulate(
        tuple(spec["joints"]),
        RPM,
        revolutions,
        POINTS_PER_REVOLUTION,
        mode="smooth",
        method=method,
        rtol=RTOL,
        atol=ATOL,
        restitution=0.9,
        friction=friction,
        gravity=False,
        clearance=CLEARANCE,
        count_onsets=False,
        smoothing_variant="jaxclear",
        alpha=alpha,
        beta=beta,
    )
    s = r["stats"]
    return dict(
        case=case,
        solver="scipy-" + method,
        run_s=s["wall_time"],
        nfev=s["nfev"],
        njev=s["njev"],
        rhs_evals=s["rhs_evals"],
        succeeded=True,
        stats=cycle_stats(
            r["t"],
            r["slider_a"],
            r["crank_torque"],
            {j: r[j + "_normal_force"] for j in spec["joints"]},
            revolutions,
        ),
    )


def agreement_worker(case, rtol=1e-10, revolutions=1.0 / 12.0):
    """Pointwise agreement over the first contacts at tight tolerances (same model, docs/model.md §5b)."""
    import jax

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    sys.path.insert(0, os.path.join(REPO, "tests"))
    from reference.scipy_slider_crank import simulate

    spec = CASES[case]
    lugre = spec["friction"] == "lugre"
    ppr = 3600
    t1 = revolutions * 60.0 / RPM
    ts = np.linspace(0.0, t1, int(round(revolutions * ppr)) + 1)
    out = dict(case=case, rtol=rtol, t1=t1)
    alpha, beta = baumgarte_gains()
    for variant in ("jaxclear", "original"):
        r = simulate(
            tuple(spec["joints"]),
            RPM,
            revolutions,
            ppr,
            mode="smooth",
            method="Radau",
            rtol=rtol,
            atol=rtol * 1e-3,
            friction=("lugre",) if lugre else ("modified-coulomb", 0.01),
            clearance=CLEARANCE,
            count_onsets=False,
            smoothing_variant=variant,
            alpha=alpha,
            beta=beta,
        )
        if variant == "jaxclear":
            ref = r
        else:
            out["variant_um"] = {
                j: 1e6
                * float(
                    np.max(
                        np.hypot(
                            r[j + "_ecc_x"] - ref[j + "_ecc_x"], r[j + "_ecc_y"] - ref[j + "_ecc_y"]
                        )
                    )
                )
                for j in spec["joints"]
            }
    mech = slider_crank(
        rpm=RPM,
        clearance_joints=",".join(spec["joints"]),
        clearance=CLEARANCE,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=LuGre() if lugre else ModifiedCoulomb(0.01),
    )
    cfg = jaxclear.SolverConfig(method="dopri8", rtol=rtol, atol=rtol * 1e-3, max_steps=2_000_000)
    tr = jaxclear.simulate(mech, t1, ts=ts, solver=cfg)
    jax.block_until_ready(tr.t)
    out["orbit_um"], out["dfn_rel"], out["peak_fn"] = {}, {}, {}
    for j in spec["joints"]:
        c = tr.clearance[j]
        out["orbit_um"][j] = 1e6 * float(
            np.max(
                np.hypot(
                    np.asarray(c["ecc_x"]) - ref[j + "_ecc_x"],
                    np.asarray(c["ecc_y"]) - ref[j + "_ecc_y"],
                )
            )
        )
        peak = float(np.max(ref[j + "_normal_force"]))
        out["peak_fn"][j] = peak
        out["dfn_rel"][j] = (
            float(np.max(np.abs(np.asarray(c["normal_force"]) - ref[j + "_normal_force"]))) / peak
        )
    tau = float(np.max(np.abs(ref["crank_torque"])))
    out["dtorque_rel"] = (
        float(np.max(np.abs(np.asarray(tr.input_torque) - ref["crank_torque"]))) / tau
    )
    return out


SPAWN_OPTIONS = {}


def spawn(job, timeout):
    """Run one job in a subprocess; returns its result dict, or a dict with 'skipped'."""
    job = dict(job, **SPAWN_OPTIONS)
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", json.dumps(job)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=REPO)
    except subprocess.TimeoutExpired:
        return dict(job, skipped=f"timeout after {timeout:.0f} s", wall_s=time.perf_counter() - t0)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    if proc.returncode != 0 or not lines:
        err = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return dict(job, skipped=f"error: {err[:120]}", wall_s=time.perf_counter() - t0)
    res = json.loads(lines[-1][len("RESULT ") :])
    res["wall_s"] = time.perf_counter() - t0
    return res


# ----------------------------------------------------------------------------------- printing
def fmt_stats(r, joints):
    s = r["stats"]
    peaks = " ".join(f"{j}:{s['peak_fn'][j]:8.0f}" for j in joints)
    return f"{s['rms_acc']:9.0f} {s['rms_torque']:8.2f}  {peaks}"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default="a,b,c", help="comma list among a, b, c (default all)")
    p.add_argument(
        "--solvers",
        default="lawson-tsit5,tsit5,kencarp5,kvaerno5",
        help="comma list of jaxclear methods",
    )
    p.add_argument(
        "--repeats", type=int, default=3, help="steady-state calls timed per solver (default 3)"
    )
    p.add_argument("--quick", action="store_true", help="0.25 revolution instead of 2")
    p.add_argument(
        "--revolutions", type=float, default=None, help="override the simulated revolutions"
    )
    p.add_argument(
        "--max-wall",
        type=float,
        default=None,
        help="seconds per (case, solver) subprocess, compile included (default 900, 300 with --quick)",
    )
    p.add_argument("--compile-method", choices=("aot", "first-call"), default="aot")
    p.add_argument("--max-steps", type=int, default=1_000_000)
    p.add_argument("--no-scipy", action="store_true", help="skip the SciPy reference")
    p.add_argument("--scipy-method", default="Radau")
    p.add_argument(
        "--rhs-cost", action="store_true", help="also time one RHS and one Jacobian evaluation"
    )
    p.add_argument(
        "--agreement",
        action="store_true",
        help="also check pointwise agreement with the reference over the first 1 ms at rtol 1e-10",
    )
    p.add_argument("--pin-cpu", type=int, default=None, help="pin each worker process to this CPU")
    p.add_argument(
        "--compile-cache", default=None, help="directory for JAX's persistent compilation cache"
    )
    p.add_argument(
        "--fast-compile",
        action="store_true",
        help="workers compile with XLA_FLAGS=--xla_cpu_use_fusion_emitters=false (as the CLI default)",
    )
    p.add_argument(
        "--first-contact",
        action="store_true",
        help="also measure each solver's distance from a converged solution over the first 1.5 ms",
    )
    p.add_argument("--worker", help=argparse.SUPPRESS)
    a = p.parse_args()

    if a.worker:
        job = json.loads(a.worker)
        if job.get("pin_cpu") is not None:
            os.sched_setaffinity(0, {job["pin_cpu"]})  # before JAX creates its thread pool
        if job.get("fast_compile"):
            os.environ["XLA_FLAGS"] = (
                os.environ.get("XLA_FLAGS", "") + " --xla_cpu_use_fusion_emitters=false"
            ).strip()
        if job.get("compile_cache"):
            # JAX does not cache executables with host callbacks; jaxclear's own input checks are
            # values (Trajectory.input_error), but diffrax's checks (eqx.error_if on the save
            # times) are host callbacks unless EQX_ON_ERROR=nan.
            os.environ["EQX_ON_ERROR"] = "nan"
            import jax

            jax.config.update("jax_compilation_cache_dir", job["compile_cache"])
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
            jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
            if job.get("store"):  # jaxclear's store of whole programs too, as `jaxclear run`
                import jaxclear

                jaxclear.enable_compilation_cache(job["compile_cache"])
        if job["kind"] == "jax":
            res = jax_worker(
                job["case"],
                job["solver"],
                job["revolutions"],
                job["repeats"],
                job["compile_method"],
                job["max_steps"],
                job["rhs_cost"],
                job["run_budget"],
                job.get("first_contact"),
                job.get("extremes", True),
            )
        elif job["kind"] == "fcref":
            res = first_contact_reference(job["case"], job["path"])
        elif job["kind"] == "agree":
            res = agreement_worker(job["case"])
        else:
            res = scipy_worker(job["case"], job["revolutions"], job["method"])
        print("RESULT " + json.dumps(res))
        return

    revolutions = a.revolutions if a.revolutions is not None else (0.25 if a.quick else 2.0)
    max_wall = a.max_wall if a.max_wall is not None else (300.0 if a.quick else 900.0)
    SPAWN_OPTIONS.update(
        pin_cpu=a.pin_cpu, compile_cache=a.compile_cache, fast_compile=a.fast_compile
    )
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    solvers = [s.strip() for s in a.solvers.split(",") if s.strip()]
    import jax

    import jaxclear

    dirty = subprocess.run(
        ["git", "status", "--short", "jaxclear"], capture_output=True, text=True, cwd=REPO
    ).stdout
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=REPO
    ).stdout
    print(
        f"jaxclear {jaxclear.__version__} (git {head.strip()}{', jaxclear/ modified' if dirty.strip() else ''}), "
        f"jax {jax.__version__}, backend {jax.default_backend()}, {platform.machine()}, "
        f"{os.cpu_count()} CPUs, load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )
    print(
        f"{revolutions:g} revolutions at {RPM:g} rpm, c = {CLEARANCE * 1e3:g} mm, no gravity, "
        f"{POINTS_PER_REVOLUTION} points/rev, rtol {RTOL:g}, atol {ATOL:g}; compile time: "
        + (
            "AOT lower (trace) + XLA compile of jax.jit(jaxclear.simulate)"
            if a.compile_method == "aot"
            else "first simulate() call minus median steady-state call"
        )
        + f"; run: median of up to {a.repeats} calls; max {max_wall:.0f} s per solver"
        + (
            f"; workers pinned to CPU {a.pin_cpu}"
            if a.pin_cpu is not None
            else "; workers not pinned"
        )
        + (f"; persistent compilation cache {a.compile_cache}" if a.compile_cache else "")
        + ("; XLA CPU fusion emitters off (--fast-compile)" if a.fast_compile else "")
    )
    print(
        "issue figures (2 revolutions, 2 cores): CVODES BDF + C RHS 0.10 / 0.15 / 0.12 s (a / b / c); "
        "SciPy Radau ~6 s (a)"
    )
    print(
        "cycle stats: RMS slider acceleration (m/s^2) and RMS torque (N m) over "
        + ("the last revolution" if revolutions >= 2 else "the whole window")
        + "; peak F_N (N) per joint"
    )
    sys.stdout.flush()

    all_rows = {}
    for case in cases:
        spec = CASES[case]
        print(f"\ncase {case}: {spec['label']}")
        hdr = (
            f"{'solver':<13} {'compile s':>9} {'(trace':>7} {'xla)':>6} {'run s':>8} {'min s':>8} {'steps':>7} "
            f"{'rej':>6} {'us/step':>8} {'scipy/jax':>9} {'load':>5}  {'rms acc':>9} {'rms tau':>8}  peak F_N"
        )
        print(hdr)
        print("-" * (len(hdr) + 20))
        rows = []
        sci = None
        fc_path = None
        if a.first_contact:
            import tempfile

            fc_path = os.path.join(
                tempfile.mkdtemp(prefix="jaxclear-fc-"), f"first_contact_{case}.npz"
            )
            ref = spawn(dict(kind="fcref", case=case, path=fc_path), max_wall)
            if "skipped" in ref:
                print(f"first-contact reference skipped ({ref['skipped']})")
                fc_path = None
        if not a.no_scipy:
            l0 = load()
            sci = spawn(
                dict(kind="scipy", case=case, revolutions=revolutions, method=a.scipy_method),
                max_wall,
            )
            sci["load"] = max(l0, load())
            rows.append(sci)
        for solver in solvers:
            l0 = load()
            job = dict(
                kind="jax",
                case=case,
                solver=solver,
                revolutions=revolutions,
                repeats=a.repeats,
                compile_method=a.compile_method,
                max_steps=a.max_steps,
                rhs_cost=a.rhs_cost,
                run_budget=0.5 * max_wall,
                first_contact=fc_path,
            )
            r = spawn(job, max_wall)
            r["load"] = max(l0, load())
            rows.append(r)
            if "skipped" in r:
                print(f"{solver:<13} skipped ({r['skipped']})  {'':>40} {r['load']:>5.2f}")
            else:
                ratio = (
                    f"{sci['run_s'] / r['run_s']:9.1f}"
                    if sci and "skipped" not in sci
                    else f"{'-':>9}"
                )
                trace = (
                    f"{r['trace_s']:7.1f} {r['xla_s']:6.1f}"
                    if "xla_s" in r
                    else f"{'-':>7} {'-':>6}"
                )
                flag = "" if r["succeeded"] else f"  FAILED at t={r['t_final']:.3g}"
                print(
                    f"{solver:<13} {r['compile_s']:9.1f} {trace} {r['run_s']:8.3f} {r['run_min_s']:8.3f} "
                    f"{r['steps']:7d} {r['rejected']:6d} {1e6 * r['run_s'] / max(r['steps'], 1):8.1f} {ratio} "
                    f"{r['load']:5.2f}  {fmt_stats(r, spec['joints'])}{flag}"
                )
                if "first_contact_um" in r:
                    print(
                        f"  {'':<11} first {1e3 * FIRST_CONTACT_S:g} ms vs Dopri8 rtol {FIRST_CONTACT_RTOL:g}: max orbit "
                        "distance (um) "
                        + ", ".join(f"{j} {d:.3g}" for j, d in r["first_contact_um"].items())
                    )
            sys.stdout.flush()
        if sci is not None:
            if "skipped" in sci:
                print(
                    f"{sci.get('solver', 'scipy-' + a.scipy_method):<13} skipped ({sci['skipped']})"
                )
            else:
                evals = f"nfev {sci['nfev']}, njev {sci['njev']}, all RHS calls {sci['rhs_evals']}"
                print(
                    f"{sci['solver']:<13} {'-':>9} {'':>14} {sci['run_s']:8.3f} {'':>8} {evals:<33} "
                    f"{sci['load']:5.2f}  {fmt_stats(sci, spec['joints'])}"
                )
        if a.rhs_cost:
            for r in rows:
                if "rhs_us" in r:
                    print(
                        f"  {r['solver']:<11} one RHS {r['rhs_us']:.2f} us, one jacfwd ({r['n_state']} states) "
                        f"{r['jac_us']:.2f} us; run / steps / RHS = {1e6 * r['run_s'] / max(r['steps'], 1) / r['rhs_us']:.1f} RHS-equivalents per step"
                    )
        if a.agreement:
            g = spawn(dict(kind="agree", case=case), max_wall)
            if "skipped" in g:
                print(f"  agreement check skipped ({g['skipped']})")
            else:
                print(
                    f"  agreement, first {1e3 * g['t1']:.0f} ms at rtol {g['rtol']:g} (jaxclear dopri8 vs SciPy Radau, "
                    f"same model): max orbit distance (um) "
                    + ", ".join(f"{j} {g['orbit_um'][j]:.4f}" for j in spec["joints"])
                    + "; max |dF_N| / peak F_N "
                    + ", ".join(f"{j} {g['dfn_rel'][j]:.1e}" for j in spec["joints"])
                    + f"; max |d torque| / peak {g['dtorque_rel']:.1e}"
                )
                print(
                    "  (for scale: the reference with its 'original' smoothing variant differs from the default by "
                    + ", ".join(f"{j} {g['variant_um'][j]:.3f}" for j in spec["joints"])
                    + " um)"
                )
        all_rows[case] = rows
        sys.stdout.flush()
    print(f"\nfinal load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
