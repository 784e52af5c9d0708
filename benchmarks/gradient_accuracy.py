"""Gradients of an identification loss over one crank revolution against converged central differences.

Usage:
    python benchmarks/gradient_accuracy.py [--cases B-coulomb,OAB-coulomb,B-lugre,OAB-lugre]
        [--windows 0.5,1,2,3,4,5,6,8,12] [--steps 1e-5,1e-6,1e-7] [--no-default]
        [--only-default] [--rtols 1e-7,1e-8] [--method lawson-tsit5] [--variation 1e-9]

Four cases of the benchmark slider–crank at 5000 rpm (one revolution = 12 ms, c = 0.5 mm,
Lankarani–Nikravesh contact c_e = 0.9, journals starting centred): clearance at B or at O, A and B,
with modified Coulomb friction (μ = 0.01) or LuGre (μ_k = 0.1, μ_s = 1.5 μ_k, other LuGre defaults).

Loss (what an identification fits): over the sample instants t_k (120 per revolution, every 3° of
crank) inside a window [0, W],

    L = mean_k [ ((x_k − x̂_k)/0.1 mm)² + ((a_k − â_k)/1e4 m/s²)² + ((τ_k − τ̂_k)/100 N m)² ],

slider position x, slider acceleration a and crank torque τ against fixed targets (the ideal-joint
mechanism's). Parameters: clearance (shared by the clearance joints), restitution, friction
coefficient (μ for modified Coulomb, μ_k for LuGre) and rod mass.

For each case one solve over the revolution serves every window (the loss of window W weights the
samples inside it). Printed per window and parameter:

- central differences of the loss at the reference settings (the gradient settings' method at
  rtol 1e-13 for Coulomb, Tsit5 at rtol 1e-12 for LuGre) with relative steps ``--steps``, and the
  spread between neighbouring steps: a converged derivative has two steps a decade apart that
  agree; over a whole revolution the three-joint mechanisms are chaotic and they do not;
- relative errors against the central difference of the middle step of reverse mode
  (``jax.vjp``, ``config.reverse_adjoint()``) and forward mode (``jax.jacfwd``,
  ``adjoint="forward"``) at ``jaxclear.gradient_solver`` settings (unless ``--only-default``), and
  at the defaults (solver ``"auto"``, rtol 1e-6, and simulate's default adjoints: the
  error-controlled sensitivities, whose solve runs at rtol 1e-8, Tsit5 as Lawson–Tsit5:
  ``SolverConfig.sensitivity_rtol``, ``sensitivity_method``)
  unless ``--no-default``;
- with ``--rtols``, reverse mode's errors at those tolerances (solver ``"auto"``'s method or
  ``--method``, atol = 1e-3 rtol, the sensitivity solve at the same rtol and method), and for
  every setting the relative error of the loss itself against the reference
  solve: how far the derivative's error follows the solution's own.

``--checkpoints 30,300,1000,default,199999`` instead compares reverse-mode gradients of the first
case's loss over the first window with these numbers of checkpoints (``default``: diffrax's, about
√(2 max_steps); ``gradient_solver`` stores every step) against forward mode.

Public API only. Prints figures; asserts nothing. Takes minutes per case (every AD variant
compiles for 20–60 s).
"""

import argparse
import time

import numpy as np

RPM = 5000.0
REVOLUTION = 60.0 / RPM  # s
SAMPLES = 120  # sample instants per revolution (every 3° of crank angle)
SCALES = (1e-4, 1e4, 1e2)  # m, m/s², N m: residual scales of slider x, slider acceleration, torque
NOMINAL = {
    "coulomb": {"clearance": 5e-4, "restitution": 0.9, "friction": 0.01, "rod_mass": 0.21},
    "lugre": {"clearance": 5e-4, "restitution": 0.9, "friction": 0.1, "rod_mass": 0.21},
}
CASES = {
    "B-coulomb": (("B",), "coulomb"),
    "OAB-coulomb": (("O", "A", "B"), "coulomb"),
    "B-lugre": (("B",), "lugre"),
    "OAB-lugre": (("O", "A", "B"), "lugre"),
}


def sample_times(t1: float = REVOLUTION, samples: int = SAMPLES) -> np.ndarray:
    """The loss's sample instants in (0, t1], s."""
    return np.linspace(t1 / samples, t1, samples)


def build(case: str, p):
    """The case's mechanism with parameters ``p`` (dict of clearance, restitution, friction,
    rod_mass; floats or JAX arrays)."""
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import LuGre, ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    joints, friction = CASES[case]
    if friction == "coulomb":
        law = ModifiedCoulomb(friction_coefficient=p["friction"])
    else:
        law = LuGre(kinetic_friction=p["friction"], static_friction=1.5 * p["friction"])
    return slider_crank(
        rpm=RPM,
        rod_mass=p["rod_mass"],
        clearance_joints=joints,
        clearance=p["clearance"],
        contact_law=LankaraniNikravesh(restitution=p["restitution"]),
        friction_law=law,
    )


def responses(traj):
    """(3, samples): slider x (m), slider acceleration (m/s²), crank torque (N m)."""
    import jax.numpy as jnp

    return jnp.stack([traj.q[:, 6], traj.qdd[:, 6], traj.input_torque])


def targets(ts) -> np.ndarray:
    """The ideal-joint slider–crank's responses at ``ts`` (fixed target arrays)."""
    import jaxclear
    from jaxclear.mechanisms import slider_crank

    config = jaxclear.SolverConfig(method="tsit5", rtol=1e-11, atol=1e-14)
    traj = jaxclear.simulate(
        slider_crank(rpm=RPM), float(ts[-1]), ts=ts, solver=config, extremes=False
    )
    return np.asarray(responses(traj))


def window_weights(ts, windows) -> np.ndarray:
    """(windows, samples): 1/count on the samples inside each window [0, W], else 0."""
    inside = ts[None, :] <= np.asarray(windows)[:, None] * (1 + 1e-12)
    return inside / inside.sum(axis=1, keepdims=True)


def loss_from_responses(out, target, weights):
    """Loss of each window from responses ``out`` (3, samples): shape (windows,)."""
    scales = np.asarray(SCALES)[:, None]
    return ((((out - target) / scales) ** 2).sum(axis=0) * weights).sum(axis=-1)


def loss_gradient(out, dout, target, weights):
    """d loss / d p of each window from d responses / d p ``dout`` (3, samples)."""
    scales = np.asarray(SCALES)[:, None]
    return ((2 * (out - target) / scales**2 * dout).sum(axis=0) * weights).sum(axis=-1)


def reference_solver(config):
    """Settings of the central differences: the gradient settings' method, tighter."""
    import jaxclear

    if config.method == "lawson-tsit5":
        return jaxclear.SolverConfig(
            method="lawson-tsit5", rtol=1e-13, atol=1e-16, max_steps=config.max_steps
        )
    return jaxclear.SolverConfig(method="tsit5", rtol=1e-12, atol=1e-15, max_steps=config.max_steps)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--windows", default="0.5,1,2,3,4,5,6,8,12", help="ms, comma list")
    parser.add_argument("--steps", default="1e-5,1e-6,1e-7", help="relative FD steps (3)")
    parser.add_argument("--no-default", action="store_true", help="skip the default settings")
    parser.add_argument(
        "--only-default",
        action="store_true",
        help="skip the gradient_solver settings (only the default settings against the reference)",
    )
    parser.add_argument(
        "--rtols",
        default="",
        help="also at these tolerances (comma list; solver 'auto''s method, atol = 1e-3 rtol, "
        "sensitivity_rtol = rtol), reverse mode only, each with the loss's own error",
    )
    parser.add_argument(
        "--method",
        default="",
        help="method of the --rtols settings (default: solver 'auto''s for the case)",
    )
    parser.add_argument(
        "--variation",
        default="",
        help="instead: how fast the derivative itself moves with the parameter: reverse-mode "
        "gradients at this rtol (solver 'auto''s method, atol = 1e-3 rtol) with clearance and "
        "restitution scaled by 1 + k·1e-7, k = ±1, ±3, ±10 (first case only)",
    )
    parser.add_argument(
        "--checkpoints",
        default="",
        help="instead: reverse-mode gradients of the first case's loss over the first window "
        "with these checkpoint counts (comma list; 'default' = diffrax's), against forward mode",
    )
    args = parser.parse_args()

    import jax
    import jax.numpy as jnp

    import jaxclear

    windows = np.array([float(w) * 1e-3 for w in args.windows.split(",")])
    steps = [float(s) for s in args.steps.split(",")]
    ts = sample_times()
    weights = window_weights(ts, windows)
    target = targets(ts)
    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, backend {jax.default_backend()}; "
        f"one revolution at {RPM:g} rpm ({REVOLUTION * 1e3:g} ms), {SAMPLES} samples, "
        f"windows {args.windows} ms; FD relative steps {args.steps}"
    )
    if args.variation:
        case = args.cases.split(",")[0]
        variation_study(
            case, float(args.variation), jax, jnp, jaxclear, ts, weights, target, windows
        )
        return
    if args.checkpoints:
        case = args.cases.split(",")[0]
        checkpoint_study(case, args.checkpoints, windows[0], jax, jnp, jaxclear, ts, target)
        return
    for case in args.cases.split(","):
        run_case(case, args, jax, jnp, jaxclear, windows, steps, ts, weights, target)


def variation_study(case, rtol, jax, jnp, jaxclear, ts, weights, target, windows):
    """Converged gradients at parameters p (1 + k·1e-7): how much the derivative moves over a
    parameter change as small as a solve's own error (the state at rtol 1e-6 is off by about
    what a relative change of 1e-7 moves it)."""
    _, friction = CASES[case]
    p0 = {k: jnp.asarray(v) for k, v in NOMINAL[friction].items()}
    config = jaxclear.recommended_solver(build(case, p0))
    config = config.replace(
        rtol=rtol, atol=1e-3 * rtol, sensitivity_rtol=rtol, sensitivity_method=config.method
    )
    scales = jnp.asarray(SCALES)[:, None]
    w = jnp.asarray(weights)

    def losses(p):
        traj = jaxclear.simulate(build(case, p), REVOLUTION, ts=ts, solver=config, extremes=False)
        r2 = (((responses(traj) - jnp.asarray(target)) / scales) ** 2).sum(axis=0)
        return (r2[None] * w).sum(axis=-1)

    jac = jax.jit(jax.jacrev(losses))
    header = " ".join(f"{v * 1e3:>9g}" for v in windows)
    print(f"\n{case}, {config.method} rtol {rtol:g}: change of d loss / d p against p's nominal")
    for name in ("clearance", "restitution"):
        grads = {}
        for k in (-10, -3, -1, 0, 1, 3, 10):
            grads[k] = np.asarray(jac({**p0, name: p0[name] * (1 + k * 1e-7)})[name])
        print(f"d loss / d {name}, window (ms): {header}")
        for k, g in grads.items():
            change = (g - grads[0]) / np.abs(grads[0])
            print(f"  p (1 {k * 1e-7:+.0e})    {' '.join(f'{100 * v:+8.3f}%' for v in change)}")


def checkpoint_study(case, counts, window, jax, jnp, jaxclear, ts, target):
    """Reverse mode with a given number of checkpoints: the solve runs over the whole revolution,
    the loss weights only the samples inside ``window`` (the steps after it carry no cotangent)."""
    import diffrax

    _, friction = CASES[case]
    p0 = {k: jnp.asarray(v) for k, v in NOMINAL[friction].items()}
    config = jaxclear.gradient_solver(build(case, p0))
    weights = jnp.asarray(window_weights(ts, [window])[0])
    scales = jnp.asarray(SCALES)[:, None]

    def loss(p, adjoint):
        traj = jaxclear.simulate(
            build(case, p), REVOLUTION, ts=ts, solver=config, adjoint=adjoint, extremes=False
        )
        r2 = ((responses(traj) - jnp.asarray(target)) / scales) ** 2
        return jnp.sum(r2.sum(axis=0) * weights), traj.num_steps

    forward, steps = jax.jit(jax.jacfwd(lambda p: loss(p, "forward"), has_aux=True))(p0)
    print(
        f"\n{case}, {config.method} rtol {config.rtol:g}, loss over {window * 1e3:g} ms of a "
        f"revolution; forward mode ({int(steps)} steps): d loss / d clearance {float(forward['clearance']):.6g}"
    )
    for count in counts.split(","):
        checkpoints = None if count == "default" else int(count)
        adjoint = diffrax.RecursiveCheckpointAdjoint(checkpoints=checkpoints)
        grad, steps = jax.jit(jax.grad(lambda p: loss(p, adjoint), has_aux=True))(p0)
        print(
            f"  reverse, checkpoints {count:>7s} ({int(steps)} steps): d loss / d clearance "
            f"{float(grad['clearance']):.6g}",
            flush=True,
        )


def run_case(case, args, jax, jnp, jaxclear, windows, steps, ts, weights, target):
    """One case: the central differences, then the variants ``args`` asks for (``--no-default``,
    ``--only-default``, ``--rtols``, ``--method``)."""
    rtols = [float(r) for r in args.rtols.split(",") if r]
    joints, friction = CASES[case]
    p0 = {k: jnp.asarray(v) for k, v in NOMINAL[friction].items()}
    names = list(p0)
    config = jaxclear.gradient_solver(build(case, p0))
    reference = reference_solver(config)

    def outputs(p, solver, adjoint="auto"):
        traj = jaxclear.simulate(
            build(case, p), REVOLUTION, ts=ts, solver=solver, adjoint=adjoint, extremes=False
        )
        return responses(traj), traj.num_steps

    print(
        f"\n== {case}: clearance at {', '.join(joints)}, {friction}; gradient settings "
        f"{config.method} rtol {config.rtol:g} atol {config.atol:g} dtmax {config.dtmax} "
        f"checkpoints {config.checkpoints}; central differences at {reference.method} rtol {reference.rtol:g}"
    )
    f_ref = jax.jit(lambda p: outputs(p, reference))
    start = time.perf_counter()
    out0, n_ref = f_ref(p0)
    out0 = np.asarray(out0)
    print(f"reference solve: {int(n_ref)} steps, first call {time.perf_counter() - start:.1f} s")
    loss0 = loss_from_responses(out0, target, weights)
    fd = {}  # name -> (steps, windows)
    for name in names:
        rows = []
        for r in steps:
            h = r * float(p0[name])
            up = np.asarray(f_ref({**p0, name: p0[name] + h})[0])
            down = np.asarray(f_ref({**p0, name: p0[name] - h})[0])
            rows.append(
                (
                    loss_from_responses(up, target, weights)
                    - loss_from_responses(down, target, weights)
                )
                / (2 * h)
            )
        fd[name] = np.array(rows)

    variants = [] if args.only_default else [("gradient_solver", config, config.reverse_adjoint())]
    if not args.no_default:
        variants.append(("default", "auto", "reverse"))
    auto = jaxclear.recommended_solver(build(case, p0))
    if args.method:
        auto = auto.replace(method=args.method)
    for rtol in rtols:
        solver = auto.replace(
            rtol=rtol, atol=1e-3 * rtol, sensitivity_rtol=rtol, sensitivity_method=auto.method
        )
        variants.append((f"{args.method or 'rtol'} {rtol:g}", solver, "reverse"))
    ad = {}
    loss_error = {}  # label -> (windows,) relative error of the loss itself against the reference
    for label, solver, reverse_adjoint in variants:
        if label in ("gradient_solver", "default"):
            # forward mode: jacfwd of the responses, one pass for all parameters; the loss's gradient
            # pairs them with the responses of the same evaluation (the primal output of the jvp, as
            # in jax.jacfwd of a loss), not with those of a separate undifferentiated solve
            def with_responses(p, solver=solver):
                out, n = outputs(p, solver, "forward")
                return out, (out, n)

            jac = jax.jit(jax.jacfwd(with_responses, has_aux=True))
            start = time.perf_counter()
            d_out, (out_fwd, n_fwd) = jac(p0)
            first_fwd = time.perf_counter() - start
            out_fwd = np.asarray(out_fwd)
            ad[(label, "forward")] = (
                {k: loss_gradient(out_fwd, np.asarray(d_out[k]), target, weights) for k in names},
                int(n_fwd),
                first_fwd,
            )

        # reverse mode: one vjp, applied to each window's cotangent
        def windows_grad(p, solver=solver, reverse_adjoint=reverse_adjoint):
            (out, n), pullback = jax.vjp(lambda q: outputs(q, solver, reverse_adjoint), p)
            scales = jnp.asarray(SCALES)[:, None]
            residual = 2 * (out - jnp.asarray(target)) / scales**2
            cotangents = residual[None] * jnp.asarray(weights)[:, None, :]
            zero = np.zeros((), dtype=jax.dtypes.float0)
            grads = jax.lax.map(lambda c: pullback((c, zero))[0], cotangents)
            return grads, n, out

        start = time.perf_counter()
        g_rev, n_rev, out_rev = jax.jit(windows_grad)(p0)
        first_rev = time.perf_counter() - start
        loss_rev = loss_from_responses(np.asarray(out_rev), target, weights)
        loss_error[label] = np.abs(loss_rev - loss0) / np.abs(loss0)
        ad[(label, "reverse")] = ({k: np.asarray(g_rev[k]) for k in names}, int(n_rev), first_rev)

    middle = len(steps) // 2
    header = " ".join(f"{w * 1e3:>9g}" for w in windows)
    print(f"loss per window (ms): {header}")
    print(f"                      {' '.join(f'{v:9.3g}' for v in loss0)}")
    for label, err in loss_error.items():
        print(f"  its error, {label[:18]:18s} {' '.join(f'{100 * v:8.2g}%' for v in err)}")
    for name in names:
        print(f"d loss / d {name} (nominal {float(p0[name]):g})")
        for i, r in enumerate(steps):
            print(f"  FD h={r:<7g}          {' '.join(f'{v:9.3g}' for v in fd[name][i])}")
        for i in range(len(steps) - 1):
            spread = np.abs(fd[name][i] - fd[name][i + 1]) / np.abs(fd[name][i + 1])
            print(
                f"  FD spread {steps[i]:g}/{steps[i + 1]:g}     {' '.join(f'{100 * v:8.2g}%' for v in spread)}"
            )
        for (label, mode), (grads, n, first) in ad.items():
            err = np.abs(grads[name] - fd[name][middle]) / np.abs(fd[name][middle])
            print(f"  {mode:7s} {label[:18]:18s} {' '.join(f'{100 * v:8.2g}%' for v in err)}")
    for (label, mode), (grads, n, first) in ad.items():
        print(f"{label}, {mode}: {n} steps, first call (compile + run) {first:.1f} s")


if __name__ == "__main__":
    main()
