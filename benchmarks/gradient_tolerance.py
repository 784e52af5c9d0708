"""Gradient of a simulated response at the default and at a tight tolerance, against central differences.

Usage:
    python benchmarks/gradient_tolerance.py [--window 3e-4] [--rtols 1e-6,1e-10]

One clearance joint B of the benchmark slider–crank (5000 rpm, c = 0.5 mm, Lankarani–Nikravesh
c_e = 0.9, modified Coulomb μ = 0.01, journal starting centred): d x_slider(window) / d c by
``jax.grad`` (reverse mode, ``adjoint="reverse"``) and ``jax.jacfwd`` (forward mode) through the
public ``jaxclear.simulate``, at each Tsit5 tolerance (atol = rtol / 1000), and by central
differences of the solution at the tightest tolerance with two steps a decade apart (their
agreement shows they converged). At loose tolerances the derivative of the discrete solve is not
the derivative of the solution: step sizes are not differentiated and contact onsets move
(docs/differentiation.md). Prints figures only.
"""

import argparse
import time


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--window", type=float, default=3e-4, help="s (default 3e-4: through the first impact)"
    )
    p.add_argument("--rtols", default="1e-6,1e-10", help="comma list of Tsit5 rtol values")
    a = p.parse_args()

    import jax

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import ModifiedCoulomb
    from jaxclear.mechanisms import slider_crank

    def build(clearance):
        return slider_crank(
            rpm=5000.0,
            clearance_joints="B",
            clearance=clearance,
            contact_law=LankaraniNikravesh(restitution=0.9),
            friction_law=ModifiedCoulomb(friction_coefficient=0.01),
        )

    c0 = 5e-4
    rtols = [float(r) for r in a.rtols.split(",")]
    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, backend {jax.default_backend()}; "
        f"d x_slider({a.window:g} s) / d c at c = {c0:g} m"
    )
    for rtol in rtols:
        config = jaxclear.SolverConfig(method="tsit5", rtol=rtol, atol=rtol * 1e-3)

        def slider_x(clearance, config=config):
            return jaxclear.simulate(build(clearance), a.window, num_points=2, solver=config).q[
                -1, 6
            ]

        t0 = time.perf_counter()
        reverse = float(jax.jit(jax.grad(slider_x))(c0))
        t_rev = time.perf_counter() - t0
        t0 = time.perf_counter()
        forward = float(jax.jit(jax.jacfwd(slider_x))(c0))
        t_fwd = time.perf_counter() - t0
        line = f"rtol {rtol:g}: reverse {reverse:.6f}, forward {forward:.6f} (first calls {t_rev:.1f} s, {t_fwd:.1f} s)"
        if rtol == min(rtols):
            f = jax.jit(slider_x)
            fds = [float((f(c0 + h) - f(c0 - h)) / (2 * h)) for h in (c0 * 1e-3, c0 * 1e-4)]
            line += f"; central differences {fds[0]:.6f} (h = c/1000), {fds[1]:.6f} (h = c/10000)"
        print(line, flush=True)


if __name__ == "__main__":
    main()
