"""Why diffrax's derivatives of the default-setting solve are wrong: tangent truncation vs grid dependence.

Usage:
    python benchmarks/sensitivity_diagnosis.py [--windows 3e-4,5e-4,1e-3,2e-3,3e-3]

Case of issue 22: one clearance joint B of the benchmark slider–crank (5000 rpm, c = 0.5 mm,
Lankarani–Nikravesh c_e = 0.9, modified Coulomb μ = 0.01, gravity as ``slider_crank``'s default,
journal starting centred). Quantity: d x_slider(T) / d c (x_slider = q[6]) at each window T.

The script runs its own ``diffrax.diffeqsolve`` on ``jaxclear.dynamics.vector_field`` from
``jaxclear.assemble``'s y0 (which does not depend on c with the journal centred: checked), with
jaxclear's default ("fast") settings: Tsit5, PIDController(rtol 1e-6, atol 1e-9, pcoeff 0.1,
icoeff 0.7); its slider x is checked against ``jaxclear.simulate(..., solver="fast")``. Then:

- reference: central differences of the solution at Tsit5 rtol 1e-12 / atol 1e-15, relative steps
  1e-5 and 1e-6 (their agreement shows convergence);
- adaptive AD: ``jax.jacfwd`` (``diffrax.ForwardMode``) and ``jax.grad``
  (``RecursiveCheckpointAdjoint`` storing every step) of the default adaptive solve;
- frozen grid: the default solve's accepted step times at the nominal c replayed with
  ``diffrax.StepTo``: AD (forward, reverse) of the replay, and its central differences (steps
  1e-6, 1e-7): the derivative of the discrete map on that fixed grid;
- adaptive FD: central differences of the default adaptive solve (its grid moves with c) at
  relative steps 1e-4 .. 1e-7.

Frozen-grid AD = frozen-grid FD shows AD is exact for the discrete map; frozen-grid AD minus the
reference is the tangents' truncation error on that grid; adaptive FD minus frozen-grid FD is the
part due to the step grid's dependence on c. Prints figures only.
"""

import argparse
import subprocess
import sys
import time


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--windows", default="3e-4,5e-4,1e-3,2e-3,3e-3", help="comma list, s")
    a = p.parse_args()
    windows = [float(w) for w in a.windows.split(",")]

    import diffrax
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.dynamics import vector_field
    from jaxclear.friction import ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    jax.config.update("jax_enable_x64", True)
    start = time.perf_counter()

    def build(clearance):
        return slider_crank(
            rpm=5000.0,
            clearance_joints="B",
            clearance=clearance,
            contact_law=LankaraniNikravesh(),
            friction_law=ModifiedCoulomb(friction_coefficient=0.01),
        )

    c0 = 5e-4
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    print(
        f"commit {commit}, jaxclear {jaxclear.__version__}, jax {jax.__version__}, "
        f"diffrax {diffrax.__version__}, backend {jax.default_backend()}"
    )
    print(
        f"d x_slider(T) / d c at c = {c0:g} m, one clearance joint B (L-N, modified Coulomb 0.01)"
    )

    # y0 does not depend on c (journal centred): checked, then held fixed
    y0 = jaxclear.assemble(build(c0))
    same = all(
        np.array_equal(np.asarray(jaxclear.assemble(build(c0 * f))), np.asarray(y0))
        for f in (1 - 1e-3, 1 + 1e-3, 1.2)
    )
    print(f"assembled y0 identical at c·(1 ± 1e-3) and 1.2 c: {same}")
    if not same:
        raise SystemExit("y0 depends on c: this diagnosis holds it fixed, so it does not apply")

    # The mechanism's leaves enter every compiled solve as arguments, as in jaxclear.simulate: built
    # inside the jitted function from c alone, the other leaves would be constants that XLA folds,
    # with other roundings, and on this contact solve another rounding is another step sequence.
    # Only the leaves that depend on c are rebuilt from the traced c.
    leaves0, static0 = eqx.partition(build(c0), eqx.is_array)
    flat0 = jax.tree_util.tree_leaves(leaves0)
    depends = [False] * len(flat0)
    for f in (0.9, 1.1):
        other = jax.tree_util.tree_leaves(eqx.partition(build(c0 * f), eqx.is_array)[0])
        depends = [d or not np.array_equal(a, b) for d, a, b in zip(depends, flat0, other)]

    def mechanism(c, leaves):
        built, treedef = jax.tree_util.tree_flatten(eqx.partition(build(c), eqx.is_array)[0])
        given = jax.tree_util.tree_leaves(leaves)
        mixed = [b if d else g for b, g, d in zip(built, given, depends)]
        return eqx.combine(jax.tree_util.tree_unflatten(treedef, mixed), static0)

    term = diffrax.ODETerm(vector_field)
    solver = diffrax.Tsit5()
    default = diffrax.PIDController(rtol=1e-6, atol=1e-9, pcoeff=0.1, icoeff=0.7)
    tight = diffrax.PIDController(rtol=1e-12, atol=1e-15, pcoeff=0.1, icoeff=0.7)
    max_steps = 20_000

    def adaptive(c, t1, controller, adjoint, steps_max, saveat, leaves):
        return diffrax.diffeqsolve(
            term,
            solver,
            0.0,
            t1,
            None,
            y0,
            args=mechanism(c, leaves),
            saveat=saveat,
            stepsize_controller=controller,
            max_steps=steps_max,
            adjoint=adjoint,
            throw=False,
        )

    end_only = diffrax.SaveAt(t1=True)
    every_step = diffrax.SaveAt(subs=[diffrax.SubSaveAt(t1=True), diffrax.SubSaveAt(steps=True)])

    @jax.jit
    def default_solve_(c, t1, leaves):  # slider x, the accepted step times, number of steps
        sol = adaptive(
            c, t1, default, diffrax.RecursiveCheckpointAdjoint(), max_steps, every_step, leaves
        )
        return (
            sol.ys[0][-1, 6],
            sol.ts[1],
            sol.stats["num_accepted_steps"],
            sol.result == diffrax.RESULTS.successful,
        )

    @jax.jit
    def tight_x_(c, t1, leaves):
        sol = adaptive(
            c, t1, tight, diffrax.RecursiveCheckpointAdjoint(), 400_000, end_only, leaves
        )
        return sol.ys[-1, 6], sol.stats["num_accepted_steps"]

    def default_x(c, t1, adjoint, leaves):  # slider x and, as auxiliary output, the step count
        sol = adaptive(c, t1, default, adjoint, max_steps, end_only, leaves)
        return sol.ys[-1, 6], sol.stats["num_accepted_steps"]

    # the primal value and step count of the differentiated solve come out too: the solve under
    # the AD transformation is compiled separately and need not take the nominal steps
    @jax.jit
    def fwd_adaptive_(c, t1, leaves):
        f = lambda cc: default_x(cc, t1, diffrax.ForwardMode(), leaves)  # noqa: E731
        x, dx, n = jax.jvp(f, (c,), (jnp.ones_like(c),), has_aux=True)
        return dx, x, n

    @jax.jit
    def rev_adaptive_(c, t1, leaves):
        adjoint = diffrax.RecursiveCheckpointAdjoint(checkpoints=max_steps)
        f = lambda cc: default_x(cc, t1, adjoint, leaves)  # noqa: E731
        (x, n), g = jax.value_and_grad(f, has_aux=True)(c)
        return g, x, n

    default_solve = lambda c, t1: default_solve_(c, t1, leaves0)  # noqa: E731
    tight_x = lambda c, t1: tight_x_(c, t1, leaves0)  # noqa: E731
    fwd_adaptive = lambda c, t1: fwd_adaptive_(c, t1, leaves0)  # noqa: E731
    rev_adaptive = lambda c, t1: rev_adaptive_(c, t1, leaves0)  # noqa: E731

    # frozen grid: StepTo over a grid of fixed length L (one compile for every window): the
    # window's own accepted step times up to T, then the longest window's times after T, then
    # padding; x_slider(T) is read at T's index, so the steps after T do not enter it
    def frozen(c, grid, index, adjoint, leaves=leaves0):
        sol = diffrax.diffeqsolve(
            term,
            solver,
            grid[0],
            grid[-1],
            None,
            y0,
            args=mechanism(c, leaves),
            saveat=diffrax.SaveAt(steps=True),
            stepsize_controller=diffrax.StepTo(ts=grid),
            max_steps=grid.shape[0] - 1,
            adjoint=adjoint,
            throw=False,
        )
        return sol.ys[index, 6]

    frozen_x_ = jax.jit(
        lambda c, g, k, lv: frozen(c, g, k, diffrax.RecursiveCheckpointAdjoint(), lv)
    )
    fwd_frozen_ = jax.jit(
        jax.jacfwd(lambda c, g, k, lv: frozen(c, g, k, diffrax.ForwardMode(), lv))
    )

    def rev_frozen_fn(c, g, k, lv):
        n = g.shape[0] - 1
        return frozen(c, g, k, diffrax.RecursiveCheckpointAdjoint(checkpoints=n), lv)

    rev_frozen_ = jax.jit(jax.grad(rev_frozen_fn))
    frozen_x = lambda c, g, k: frozen_x_(c, g, k, leaves0)  # noqa: E731
    fwd_frozen = lambda c, g, k: fwd_frozen_(c, g, k, leaves0)  # noqa: E731
    rev_frozen = lambda c, g, k: rev_frozen_(c, g, k, leaves0)  # noqa: E731

    c = jnp.asarray(c0)

    def central(f, h):
        return (float(f(c * (1 + h))) - float(f(c * (1 - h)))) / (2 * h * c0)

    # 1. the default solve: grids, steps, and the check against jaxclear.simulate
    grids, steps, x_nominal = {}, {}, {}
    print(
        "\nwindow T | steps (own solve) | x_slider own solve | jaxclear.simulate(solver='fast') | rel. diff | simulate steps"
    )
    for T in windows:
        x, ts, n, res = default_solve(c, jnp.asarray(T))
        n = int(n)
        if not bool(res):
            raise SystemExit(f"default solve to {T:g} s failed (diffrax result {int(res)})")
        ts = np.asarray(ts)[:n]
        grids[T], steps[T], x_nominal[T] = np.concatenate([[0.0], ts]), n, float(x)
        traj = jaxclear.simulate(build(c0), T, num_points=2, solver="fast")
        xs = float(traj.q[-1, 6])
        print(
            f"{T * 1e3:.1f} ms | {n} | {x_nominal[T]:.12e} | {xs:.12e} | "
            f"{abs(x_nominal[T] - xs) / abs(xs):.1e} | {int(traj.num_accepted_steps)}"
        )
    longest = grids[max(windows)]
    length = max(len(g) for g in grids.values()) + len(longest) + 2
    frozen_grids, frozen_index = {}, {}
    for T in windows:
        g = np.concatenate([grids[T], longest[longest > T]])
        pad = g[-1] + 1e-7 * np.arange(1, length - len(g) + 1)
        frozen_grids[T] = jnp.asarray(np.concatenate([g, pad]))
        frozen_index[T] = jnp.asarray(len(grids[T]) - 2)  # ys[k] is the state at grid[k + 1]
    print(f"(setup {time.perf_counter() - start:.0f} s)", file=sys.stderr)

    rows = []
    for T in windows:
        t1, g, k = jnp.asarray(T), frozen_grids[T], frozen_index[T]
        replay = float(frozen_x(c, g, k))
        row = dict(T=T, replay_diff=abs(replay - x_nominal[T]) / abs(x_nominal[T]))
        row["ref"] = {h: central(lambda cc: tight_x(cc, t1)[0], h) for h in (1e-5, 1e-6)}
        row["tight_steps"] = int(tight_x(c, t1)[1])
        for key, fn in (("ad_fwd", fwd_adaptive), ("ad_rev", rev_adaptive)):
            d, x, n = fn(c, t1)
            row[key] = float(d)
            row[key + "_steps"] = int(n)
            row[key + "_x"] = abs(float(x) - x_nominal[T]) / abs(x_nominal[T])
        row["fz_fwd"] = float(fwd_frozen(c, g, k))
        row["fz_rev"] = float(rev_frozen(c, g, k))
        row["fz_fd"] = {h: central(lambda cc: frozen_x(cc, g, k), h) for h in (1e-6, 1e-7, 1e-8)}
        row["ad_fd"] = {
            h: central(lambda cc: default_solve(cc, t1)[0], h) for h in (1e-4, 1e-5, 1e-6, 1e-7)
        }
        rows.append(row)
        print(f"({T * 1e3:.1f} ms done, {time.perf_counter() - start:.0f} s)", file=sys.stderr)

    def pct(x, ref):
        return f"{x:.6g} ({100 * (x - ref) / abs(ref):+.3g} %)"

    print(
        "\nreference: central differences at Tsit5 rtol 1e-12 / atol 1e-15, relative steps 1e-5 | 1e-6"
    )
    print(
        "T | reference 1e-5 | reference 1e-6 | steps at 1e-12 | steps at default: nominal solve, "
        "under jacfwd, under grad | x under jacfwd, grad, frozen replay vs nominal x (rel.)"
    )
    for r in rows:
        print(
            f"{r['T'] * 1e3:.1f} ms | {r['ref'][1e-5]:.7g} | {r['ref'][1e-6]:.7g} | "
            f"{r['tight_steps']} | {steps[r['T']]}, {r['ad_fwd_steps']}, {r['ad_rev_steps']} | "
            f"{r['ad_fwd_x']:.1e}, {r['ad_rev_x']:.1e}, {r['replay_diff']:.1e}"
        )
    print("\nd x_slider / d c (error % vs the reference at step 1e-6)")
    print(
        "T | adaptive AD fwd | adaptive AD rev | frozen-grid AD fwd | frozen-grid AD rev | "
        "frozen-grid FD 1e-6 | frozen-grid FD 1e-7 | frozen-grid FD 1e-8"
    )
    for r in rows:
        ref = r["ref"][1e-6]
        print(
            f"{r['T'] * 1e3:.1f} ms | {pct(r['ad_fwd'], ref)} | {pct(r['ad_rev'], ref)} | "
            f"{pct(r['fz_fwd'], ref)} | {pct(r['fz_rev'], ref)} | "
            + " | ".join(pct(r["fz_fd"][h], ref) for h in (1e-6, 1e-7, 1e-8))
        )
    print(
        "\nadaptive default solve, central differences (grid moves with c), error % vs the reference"
    )
    print("T | FD 1e-4 | FD 1e-5 | FD 1e-6 | FD 1e-7")
    for r in rows:
        ref = r["ref"][1e-6]
        print(
            f"{r['T'] * 1e3:.1f} ms | "
            + " | ".join(pct(r["ad_fd"][h], ref) for h in (1e-4, 1e-5, 1e-6, 1e-7))
        )
    print(f"\ntotal {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
