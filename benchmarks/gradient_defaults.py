"""Derivatives at simulate's default settings: accuracy against converged central differences, and cost.

Usage:
    python benchmarks/gradient_defaults.py [--windows 0.3,0.5,1,2,3] [--repeats 3]
        [--parameters 1,4,16] [--no-discrete] [--no-cost] [--no-accuracy] [--no-fit]

The case of issue 22: the benchmark slider–crank at 5000 rpm with one clearance joint B
(Lankarani–Nikravesh contact, restitution 0.9, modified Coulomb μ = 0.01, gravity on), journal
starting centred, c = 0.5 mm. Quantity: d(slider x)/dc at the end of each window.

Printed per window:
- the reference: central differences of the solution at ``jaxclear.gradient_solver`` settings
  (Lawson–Tsit5, rtol 1e-12) at relative steps 1e-5 and 1e-6 (their spread shows convergence);
- ``jax.jacfwd`` and ``jax.grad`` of ``simulate`` with no solver or adjoint argument (the
  error-controlled sensitivities, docs/differentiation.md), and, unless ``--no-discrete``,
  ``adjoint="discrete-forward"`` (diffrax's ForwardMode through the steps, the old default), each
  with its error against the reference.

Then (unless ``--no-cost``) the cost over the longest window: warm wall time of the primal solve,
of ``jax.jacfwd`` and ``jax.grad`` for p = 1, 4, 16 parameters (p distinct scalar leaves of the mechanism, the journal radius first, each scaled by a factor of
its own), their ratios to the primal in the same process, first-call (compile) times,
and the process's peak RSS.

Then (unless ``--no-fit``) the wall time of the README's ``jaxclear fit`` example (issue 22's
fitting target), a whole process with an empty compilation cache (a temporary
``JAXCLEAR_CACHE_DIR``), and its estimate. Public API only; prints figures, asserts nothing.
"""

import argparse
import importlib.metadata
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb

NOMINAL = {"clearance": 5e-4, "restitution": 0.9, "friction": 0.01, "rod_mass": 0.21}


def build(p):
    """The case's mechanism from a dict of parameters (NOMINAL's keys)."""
    return jaxclear.mechanisms.slider_crank(
        rpm=5000.0,
        gravity=True,
        clearance_joints="B",
        clearance=p["clearance"],
        rod_mass=p["rod_mass"],
        contact_law=LankaraniNikravesh(restitution=p["restitution"]),
        friction_law=ModifiedCoulomb(friction_coefficient=p["friction"]),
    )


def slider_x(p, t1, solver="auto", adjoint="auto"):
    return jaxclear.simulate(build(p), t1, num_points=2, solver=solver, adjoint=adjoint).q[-1, 6]


def scaled_leaves(mechanism):
    """The mechanism's nonzero scalar inexact leaves, the journal radius first (the clearance is
    R_B - R_J): (their names, ``scaled(s)``, the mechanism with the first len(s) of them each
    multiplied by its own factor s_k)."""
    dynamic, static = eqx.partition(mechanism, eqx.is_inexact_array)
    paths, treedef = jax.tree_util.tree_flatten_with_path(dynamic)
    leaves = [x for _, x in paths]
    names = [jax.tree_util.keystr(k) for k, _ in paths]
    scalars = [i for i, x in enumerate(leaves) if x.size == 1 and float(x) != 0.0]
    scalars.sort(key=lambda i: "journal_radius" not in names[i])

    def scaled(s):
        new = list(leaves)
        for k, i in enumerate(scalars[: s.shape[0]]):
            new[i] = leaves[i] * s[k]
        return eqx.combine(jax.tree_util.tree_unflatten(treedef, new), static)

    return [names[i] for i in scalars], scaled


def header() -> str:
    """jaxclear's, JAX's and diffrax's versions and the commit (marked if the checkout has
    uncommitted changes)."""
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain"], capture_output=True, text=True).stdout
    return (
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, diffrax "
        f"{importlib.metadata.version('diffrax')}, commit {commit}"
        f"{' (uncommitted changes)' if dirty.strip() else ''}"
    )


def timed(f, *args, repeats):
    """(first call's wall time, best of ``repeats`` warm calls), s."""
    start = time.perf_counter()
    jax.block_until_ready(f(*args))
    first = time.perf_counter() - start
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(f(*args))
        best = min(best, time.perf_counter() - start)
    return first, best


def accuracy(windows, discrete):
    p0 = {k: jnp.asarray(v) for k, v in NOMINAL.items()}
    tight = jaxclear.gradient_solver(build(p0))
    c0 = NOMINAL["clearance"]
    with_c = lambda c: {**p0, "clearance": c}  # noqa: E731
    reference = jax.jit(lambda c, t1: slider_x(with_c(c), t1, solver=tight))
    forward = jax.jit(jax.jacfwd(lambda c, t1: slider_x(with_c(c), t1)))
    reverse = jax.jit(jax.grad(lambda c, t1: slider_x(with_c(c), t1)))
    old = jax.jit(jax.jacfwd(lambda c, t1: slider_x(with_c(c), t1, adjoint="discrete-forward")))
    print("window  reference (FD 1e-5 / 1e-6)       jacfwd (err %)        grad (err %)", end="")
    print("        discrete-forward (err %)" if discrete else "")
    for w in windows:
        t1 = jnp.asarray(w * 1e-3)
        fds = [
            float((reference(c0 * (1 + h), t1) - reference(c0 * (1 - h), t1)) / (2 * h * c0))
            for h in (1e-5, 1e-6)
        ]
        ref = fds[-1]
        values = [float(forward(jnp.asarray(c0), t1)), float(reverse(jnp.asarray(c0), t1))]
        if discrete:
            values.append(float(old(jnp.asarray(c0), t1)))
        cells = "  ".join(f"{v:12.6g} ({100 * (v - ref) / abs(ref):+7.2f})" for v in values)
        print(f"{w:5.2f} ms  {fds[0]:12.6g} / {fds[1]:12.6g}  {cells}")


def cost(window, sizes, repeats):
    t1 = window * 1e-3
    base = {k: jnp.asarray(v) for k, v in NOMINAL.items()}
    primal = jax.jit(lambda p: slider_x(p, t1))
    first, warm = timed(primal, base, repeats=repeats)
    print(f"\ncost over {window} ms: primal {warm:.3f} s warm (first call {first:.1f} s)")
    names, scaled = scaled_leaves(build(base))
    print(
        "p   jacfwd warm  ratio  first     grad warm  ratio  first   (leaves: journal radius, then"
    )
    print(f"    {', '.join(n.split('.')[-1] for n in names[1:6])}, ...)")
    for p in sizes:
        if p > len(names):
            print(f"{p:<3d} only {len(names)} nonzero scalar leaves")
            continue

        def loss(s):
            return jaxclear.simulate(scaled(s), t1, num_points=2).q[-1, 6]

        scales = jnp.ones((p,))
        fw = jax.jit(jax.jacfwd(loss))
        rv = jax.jit(jax.grad(loss))
        f_first, f_warm = timed(fw, scales, repeats=repeats)
        r_first, r_warm = timed(rv, scales, repeats=repeats)
        print(
            f"{p:<3d} {f_warm:9.3f} s {f_warm / warm:6.2f} {f_first:6.1f} s  "
            f"{r_warm:9.3f} s {r_warm / warm:6.2f} {r_first:6.1f} s"
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process: {peak:.0f} MB")


README_FIT = [
    "fit",
    "tests/reference/data/ident_5000rpm_B.csv",
    "examples/fit_clearance_B.toml",
    "--fit",
    "B.clearance=5e-4:1e-4:8e-4",
]
"""The README's fit example (true clearance 0.3 mm, start 0.5 mm), run from the repository root."""


def fit_wall():
    """Wall time of the README's fit example in a fresh process with an empty compilation cache."""
    root = Path(__file__).resolve().parent.parent
    command = shutil.which("jaxclear", path=str(Path(sys.executable).parent)) or "jaxclear"
    with tempfile.TemporaryDirectory() as scratch:
        env = {**os.environ, "JAXCLEAR_CACHE_DIR": str(Path(scratch) / "cache")}
        out = Path(scratch) / "fit-B"
        start = time.perf_counter()
        done = subprocess.run(
            [command, *README_FIT, "--out", str(out)],
            cwd=root,
            env=env,
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - start
        print(
            f"\njaxclear fit (README example, empty compilation cache): {wall:.1f} s wall, ", end=""
        )
        print(f"exit code {done.returncode}")
        if (out / "fit.json").exists():
            record = json.loads((out / "fit.json").read_text())
            print(
                f"success {record.get('success')}; parameters {json.dumps(record.get('parameters'))}"
            )
        else:
            print(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "no fit.json")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", default="0.3,0.5,1,2,3")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--parameters", default="1,4,16")
    parser.add_argument("--no-discrete", action="store_true")
    parser.add_argument("--no-cost", action="store_true")
    parser.add_argument(
        "--no-accuracy", action="store_true", help="the cost over the longest window only"
    )
    parser.add_argument("--no-fit", action="store_true", help="leave the fit example out")
    args = parser.parse_args()
    print(header())
    windows = [float(w) for w in args.windows.split(",")]
    if not args.no_accuracy:
        accuracy(windows, not args.no_discrete)
    if not args.no_cost:
        cost(max(windows), [int(p) for p in args.parameters.split(",")], args.repeats)
    if not args.no_fit:
        fit_wall()


if __name__ == "__main__":
    main()
