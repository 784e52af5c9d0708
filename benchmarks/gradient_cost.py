"""Cost of gradients through one crank revolution relative to a primal solve at the same settings.

Usage:
    python benchmarks/gradient_cost.py [--cases B-coulomb,OAB-lugre] [--params 1,4,16]
        [--modes reverse,forward] [--repeats 3] [--fast-compile]

Cases (benchmark slider–crank, 5000 rpm, one revolution = 12 ms, Lankarani–Nikravesh c_e = 0.9):
``B-coulomb`` (clearance at B, modified Coulomb μ = 0.01) and ``OAB-lugre`` (clearance at O, A
and B, LuGre), both at ``jaxclear.gradient_solver`` settings; the loss is the identification loss
of ``benchmarks/gradient_accuracy.py`` (slider x, slider acceleration and crank torque residuals at
120 instants). Gradients with respect to 1, 4 or 16 parameters (distinct array leaves of the
mechanism) by reverse mode (``jax.grad``, ``adjoint=config.reverse_adjoint()``: every step stored)
and forward mode (``jax.jacfwd``, ``adjoint="forward"``).

Each configuration runs in a fresh subprocess, which times in one process: the jitted primal loss
(first call and the best of ``--repeats`` warm calls) and the jitted gradient (the same), and
reports its peak resident memory (``resource.getrusage`` max RSS, compilation included). Printed:
warm gradient / warm primal, compile time (first call minus warm call) and peak RSS; a
``primal`` row gives the baseline RSS. Targets (issue 10; printed, not asserted): reverse ≤ 5×
the primal, forward ≤ (1 + 0.5 p)× for p parameters, gradient compile ≤ 15 s.

``--fast-compile`` sets XLA_FLAGS=--xla_cpu_use_fusion_emitters=false in the workers (as
``jaxclear run`` does by default). Public API only; prints figures, asserts nothing.
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import time

PARAMETER_SETS = {
    "B-coulomb": [
        "clearance",
        "restitution",
        "friction_coefficient",
        "rod_mass",
        "lower_velocity",
        "upper_velocity",
        "exponent",
        "crank_mass",
        "slider_mass",
        "crank_inertia",
        "rod_inertia",
        "slider_inertia",
        "crank_length",
        "rod_length",
        "rpm",
        "initial_angle",
    ],
    "OAB-lugre": [
        "clearance_O",
        "clearance_A",
        "clearance_B",
        "restitution_O",
        "restitution_A",
        "restitution_B",
        "kinetic_friction_O",
        "kinetic_friction_A",
        "kinetic_friction_B",
        "crank_mass",
        "rod_mass",
        "slider_mass",
        "crank_inertia",
        "rod_inertia",
        "slider_inertia",
        "rod_length",
    ],
}
"""16 distinct leaves per case; the first 1 and 4 are the smaller sets (for ``OAB-lugre`` the 1- and
4-parameter sets use shared values instead: clearance; clearance, restitution, μ_k, rod mass)."""
NOMINAL = {
    "clearance": 5e-4,
    "restitution": 0.9,
    "friction_coefficient": 0.01,
    "kinetic_friction": 0.1,
    "lower_velocity": 1e-4,
    "upper_velocity": 1e-3,
    "exponent": 1.5,
    "crank_mass": 0.30,
    "rod_mass": 0.21,
    "slider_mass": 0.14,
    "crank_inertia": 1.0e-4,
    "rod_inertia": 2.5e-4,
    "slider_inertia": 1.0e-4,
    "crank_length": 0.05,
    "rod_length": 0.12,
    "rpm": 5000.0,
    "initial_angle": 0.0,
}
BODY_KEYS = (
    "crank_mass",
    "rod_mass",
    "slider_mass",
    "crank_inertia",
    "rod_inertia",
    "slider_inertia",
    "crank_length",
    "rod_length",
    "rpm",
    "initial_angle",
)


def parameter_names(case: str, count: int) -> list[str]:
    if case == "OAB-lugre" and count == 1:
        return ["clearance"]
    if case == "OAB-lugre" and count == 4:
        return ["clearance", "restitution", "kinetic_friction", "rod_mass"]
    return PARAMETER_SETS[case][:count]


def nominal(name: str) -> float:
    return NOMINAL[name.rsplit("_", 1)[0] if name[-2:] in ("_O", "_A", "_B") else name]


def build(case: str, p: dict):
    """The case's mechanism; parameters absent from ``p`` take their nominal values."""
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    def get(name):
        return p.get(name, nominal(name))

    body = {k: get(k) for k in BODY_KEYS}
    if case == "B-coulomb":
        return slider_crank(
            **body,
            clearance_joints="B",
            clearance=get("clearance"),
            contact_law=LankaraniNikravesh(
                restitution=get("restitution"), exponent=get("exponent")
            ),
            friction_law=ModifiedCoulomb(
                friction_coefficient=get("friction_coefficient"),
                lower_velocity=get("lower_velocity"),
                upper_velocity=get("upper_velocity"),
            ),
        )
    joints = {}
    for j in "OAB":

        def shared_or_own(name, j=j):
            return p.get(f"{name}_{j}", get(name))

        mu = shared_or_own("kinetic_friction")
        joints[j] = dict(
            clearance=shared_or_own("clearance"),
            contact_law=LankaraniNikravesh(restitution=shared_or_own("restitution")),
            friction_law=LuGre(kinetic_friction=mu, static_friction=1.5 * mu),
        )
    return slider_crank(**body, clearance_joints=joints)


def worker(case: str, mode: str, count: int, repeats: int) -> dict:
    import jax
    import jax.numpy as jnp
    from gradient_accuracy import REVOLUTION, SCALES, responses, sample_times, targets

    import jaxclear

    ts = sample_times()
    target = jnp.asarray(targets(ts))
    names = parameter_names(case, count) if mode != "primal" else []
    p0 = {k: jnp.asarray(nominal(k)) for k in names}
    config = jaxclear.gradient_solver(build(case, p0))

    def loss(p, adjoint="auto"):
        traj = jaxclear.simulate(
            build(case, p), REVOLUTION, ts=ts, solver=config, adjoint=adjoint, extremes=False
        )
        scaled = (responses(traj) - target) / jnp.asarray(SCALES)[:, None]
        return jnp.mean(jnp.sum(scaled**2, axis=0)), traj.num_steps

    def timed(fn, arg):
        start = time.perf_counter()
        jax.block_until_ready(fn(arg))
        first = time.perf_counter() - start
        best = float("inf")
        for _ in range(repeats):
            start = time.perf_counter()
            out = fn(arg)
            jax.block_until_ready(out)
            best = min(best, time.perf_counter() - start)
        return first, best, out

    primal = jax.jit(loss)
    p_first, p_warm, (value, steps) = timed(primal, p0)
    result = dict(
        case=case,
        mode=mode,
        params=len(names),
        method=config.method,
        rtol=config.rtol,
        steps=int(steps),
        loss=float(value),
        primal_first=p_first,
        primal_warm=p_warm,
    )
    if mode != "primal":
        if mode == "reverse":
            gradient = jax.jit(jax.grad(lambda p: loss(p, config.reverse_adjoint()), has_aux=True))
        else:
            gradient = jax.jit(jax.jacfwd(lambda p: loss(p, "forward"), has_aux=True))
        g_first, g_warm, (grads, _) = timed(gradient, p0)
        _, p_warm2, _ = timed(primal, p0)  # the primal again, after: load drifts
        result.update(
            grad_first=g_first,
            grad_warm=g_warm,
            primal_warm2=p_warm2,
            finite=bool(all(bool(jnp.isfinite(g)) for g in jax.tree_util.tree_leaves(grads))),
        )
    result["max_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="B-coulomb,OAB-lugre")
    parser.add_argument("--params", default="1,4,16")
    parser.add_argument("--modes", default="reverse,forward")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--fast-compile", action="store_true")
    parser.add_argument(
        "--worker", nargs=3, metavar=("CASE", "MODE", "COUNT"), help=argparse.SUPPRESS
    )
    args = parser.parse_args()
    if args.worker:
        case, mode, count = args.worker
        print("RESULT " + json.dumps(worker(case, mode, int(count), args.repeats)), flush=True)
        return

    import jax

    import jaxclear

    env = dict(os.environ)
    if args.fast_compile:
        env["XLA_FLAGS"] = (
            env.get("XLA_FLAGS", "") + " --xla_cpu_use_fusion_emitters=false"
        ).strip()
    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, {os.cpu_count()} CPUs, "
        f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; fast compile {args.fast_compile}; "
        f"best of {args.repeats} warm calls; one revolution at 5000 rpm"
    )
    print(
        "case        mode     p  steps  primal s  grad s  ratio  target  compile s (primal, grad)  peak RSS MB"
    )
    for case in args.cases.split(","):
        configs = [("primal", 0)] + [
            (mode, int(count)) for mode in args.modes.split(",") for count in args.params.split(",")
        ]
        for mode, count in configs:
            command = [sys.executable, __file__, "--worker", case, mode, str(count)]
            command += ["--repeats", str(args.repeats)]
            proc = subprocess.run(command, capture_output=True, text=True, env=env)
            line = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
            if proc.returncode or not line:
                print(f"{case:11s} {mode:7s} {count:2d}  failed: {proc.stderr.strip()[-500:]}")
                continue
            r = json.loads(line[0][len("RESULT ") :])
            primal = min(r["primal_warm"], r.get("primal_warm2", r["primal_warm"]))
            if mode == "primal":
                print(
                    f"{case:11s} {mode:7s} {0:2d}  {r['steps']:5d}  {primal:8.3f}       -      -       -"
                    f"  {r['primal_first'] - r['primal_warm']:6.1f}        -          {r['max_rss_mb']:8.0f}"
                )
                continue
            ratio = r["grad_warm"] / primal
            target = 5.0 if mode == "reverse" else 1 + 0.5 * r["params"]
            finite = "" if r["finite"] else "  (non-finite gradient)"
            print(
                f"{case:11s} {mode:7s} {r['params']:2d}  {r['steps']:5d}  {primal:8.3f}  {r['grad_warm']:6.2f}"
                f"  {ratio:5.1f}  {target:5.1f}  {r['primal_first'] - r['primal_warm']:6.1f}"
                f"  {r['grad_first'] - r['grad_warm']:6.1f}          {r['max_rss_mb']:8.0f}{finite}"
            )


if __name__ == "__main__":
    main()
