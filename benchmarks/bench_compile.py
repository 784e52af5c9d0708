"""Compile time, cold and warm, with JAX's persistent compilation cache (issue 13, part 3).

Each case runs in fresh processes, one call each:
- ``no cache``: no cache at all;
- ``xla cold``/``xla warm``: JAX's persistent compilation cache only (``JAX_COMPILATION_CACHE_DIR``,
  equinox's runtime checks in NaN mode, ``EQX_ON_ERROR=nan``, without which JAX refuses to store
  the solve: diffrax checks its output times by host callbacks), first in an empty folder, then
  again: the warm call skips XLA's compilation, tracing and lowering remain;
- ``store cold``/``store warm``: as ``jaxclear run`` does, JAX's cache (every program stored,
  however short its compile) plus jaxclear's store of whole compiled programs
  (``jaxclear.enable_compilation_cache``) in one empty folder: a warm
  eager call loads the solve and its assembly without tracing. Calls under a transformation
  (``batch``: vmap; ``grad``) are not served by the store, only by JAX's cache.

Times are of the first call (its solve covers 1 % of a revolution: negligible), split by
``jax.monitoring`` into tracing, lowering and XLA compilation.

    python benchmarks/bench_compile.py [--cases run,batch,grad] [--fast-compile]

Cases (benchmark slider–crank, 5000 rpm):
- ``run``: the default run's solve, O, A, B with the hybrid law and LuGre friction, 721 points
  (``jaxclear run``'s grid, solver ``auto``: KenCarp4, KenCarp5 before commit 740849f);
- ``batch``: joint B, Lankarani–Nikravesh and modified Coulomb, 8 clearances in one vmapped solve;
- ``grad``: reverse-mode gradient of the slider position after 0.3 ms with respect to B's
  clearance (``jaxclear.gradient_solver``'s settings).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap

FAST_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"

CASES = {
    "run": """
        m = jaxclear.mechanisms.slider_crank(clearance_joints=("O", "A", "B"))
        T = 60 / 5000
        call = lambda: jaxclear.simulate(m, 0.01 * T, num_points=721, throw=False).t
    """,
    "batch": """
        build = lambda c: jaxclear.mechanisms.slider_crank(
            clearance_joints="B", clearance=c, contact_law=LankaraniNikravesh(),
            friction_law=ModifiedCoulomb(friction_coefficient=0.01))
        T = 60 / 5000
        cs = jnp.linspace(2e-4, 6e-4, 8)
        call = lambda: jaxclear.simulate_batch(build, cs, 0.01 * T, num_points=721).t
    """,
    "grad": """
        build = lambda c: jaxclear.mechanisms.slider_crank(
            clearance_joints="B", clearance=c, contact_law=LankaraniNikravesh(),
            friction_law=ModifiedCoulomb(friction_coefficient=0.01))
        config = jaxclear.gradient_solver(build(5e-4))
        x = lambda c: jaxclear.simulate(build(c), 3e-4, num_points=2, solver=config).q[-1, 6]
        g = jax.jit(jax.grad(x))
        call = lambda: g(5e-4)
    """,
}

CHILD = """
import json, time
import jax, jax.numpy as jnp, jax.monitoring as monitoring
import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
events = {{}}
monitoring.register_event_duration_secs_listener(
    lambda name, duration, **kw: events.__setitem__(name, events.get(name, 0.0) + duration))
if {store!r}:
    jaxclear.enable_compilation_cache({store!r})
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # as jaxclear run
{setup}
start = time.perf_counter()
jax.block_until_ready(call())
total = time.perf_counter() - start
print(json.dumps({{
    "total": total,
    "trace": events.get("/jax/core/compile/jaxpr_trace_duration", 0.0),
    "lower": events.get("/jax/core/compile/jaxpr_to_mlir_module_duration", 0.0),
    "xla": events.get("/jax/core/compile/backend_compile_duration", 0.0),
}}))
"""


def _child(case: str, cache: str | None, fast_compile: bool, store: bool = False) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "EQX_ON_ERROR")}
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    if fast_compile:
        env["XLA_FLAGS"] = FAST_COMPILE_FLAG
    if cache is not None:
        env["JAX_COMPILATION_CACHE_DIR"] = cache
        env["EQX_ON_ERROR"] = "nan"
    code = CHILD.format(setup=textwrap.dedent(CASES[case]), store=cache if store else "")
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=900
    )
    if out.returncode != 0:
        raise RuntimeError(f"case {case} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="run,batch,grad")
    parser.add_argument(
        "--fast-compile", action="store_true", help=f"XLA_FLAGS={FAST_COMPILE_FLAG}"
    )
    args = parser.parse_args()
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        parser.error(f"--cases: unknown {unknown}; choose among {', '.join(CASES)}")
    print(f"fast compile: {'on' if args.fast_compile else 'off'}; seconds of the first call")
    print(f"{'case':6s} {'run':>10s} {'total':>7s} {'trace':>7s} {'lower':>7s} {'xla':>7s}")
    for case in cases:
        with tempfile.TemporaryDirectory() as xla, tempfile.TemporaryDirectory() as store:
            runs = [("no cache", _child(case, None, args.fast_compile))]
            for label, folder, on in (("xla", xla, False), ("store", store, True)):
                runs.append((f"{label} cold", _child(case, folder, args.fast_compile, on)))
                runs.append((f"{label} warm", _child(case, folder, args.fast_compile, on)))
            for label, r in runs:
                print(
                    f"{case:6s} {label:>10s} {r['total']:7.2f} {r['trace']:7.2f} "
                    f"{r['lower']:7.2f} {r['xla']:7.2f}"
                )
            totals = dict((label, r["total"]) for label, r in runs)
            print(
                f"{case:6s} warm/cold: xla {totals['xla warm'] / totals['xla cold']:.2f}, "
                f"store {totals['store warm'] / totals['store cold']:.2f} "
                f"({len(os.listdir(store))} files in the store's folder)"
            )


if __name__ == "__main__":
    main()
