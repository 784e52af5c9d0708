"""Clearances identified from data made by the independent SciPy reference, with their uncertainty and fit time.

Usage:
    python benchmarks/identification_accuracy.py [--cases ident_5000rpm_B,ident_200rpm_B,ident_5000rpm_AB]

The data (tests/reference/data/, made by tests/reference/identification_data.py with the sharp,
event-located SciPy model; noise 1 µm on slider_x and 2 % of the RMS on slider_a and crank_torque)
are fitted by ``jaxclear.identify`` at its defaults (noise estimated from the data, scan of the
bounds, Levenberg–Marquardt over growing windows, ``jaxclear.gradient_solver``), starting every
clearance from 0.5 mm within [0.1, 0.8] mm (``jaxclear.FitSettings()``). Prints, per case and
clearance: the estimate, its standard deviation (1σ), the error against the truth (relative and in
σ), the part of the record fitted, the loss (1 = noise level), the wall time of the fit including
compilation (each case in this process; cases of the same mechanism topology share a compilation,
so the first is the dearest), and the reason when a fit is not a success (``result.success``).
"""

import argparse
import json
import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "tests" / "reference" / "data"
CASES = ("ident_5000rpm_B", "ident_200rpm_B", "ident_5000rpm_AB")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default=",".join(CASES))
    args = p.parse_args()

    import jax

    import jaxclear
    from jaxclear.contact import LankaraniNikravesh
    from jaxclear.friction import ModifiedCoulomb

    print(
        f"jaxclear {jaxclear.__version__}, jax {jax.__version__}, backend {jax.default_backend()}"
    )
    for name in args.cases.split(","):
        meta = json.loads((DATA / f"{name}.json").read_text())
        truth = meta["true_parameters"]["clearance"]
        joints = {j: {"clearance": 5e-4} for j in meta["clearance_joints"]}
        for j, body in meta["journal_body"].items():
            joints[j]["journal_body"] = body
        mechanism = jaxclear.mechanisms.slider_crank(
            rpm=float(meta["reference"]["rpm"]),
            gravity=True,
            clearance_joints=joints,
            contact_law=LankaraniNikravesh(restitution=0.9),
            friction_law=ModifiedCoulomb(friction_coefficient=0.01),
        )
        data = jaxclear.Measurements.from_csv(
            DATA / f"{name}.csv", known=jaxclear.signal_names(mechanism)
        )
        fitted = {f"{j}.clearance": (5e-4, 1e-4, 8e-4) for j in joints}
        start = time.perf_counter()
        result = jaxclear.identify(mechanism, data, fitted)
        elapsed = time.perf_counter() - start
        print(
            f"{name}: fitted up to {result.window_end * 1e3:.4g} ms of {data.t[-1] * 1e3:.4g} ms, "
            f"loss {result.loss:.3f}, {result.iterations} iterations, {elapsed:.1f} s"
        )
        if not result.success:  # the estimates below are then no fit (exit 3 of jaxclear fit)
            print(f"  not a fit: {result.reason}")
        for key, e in result.parameters.items():
            true = truth[key.split(".")[0]]
            err = e.value - true
            print(
                f"  {key}: {e.value * 1e3:.6f} mm ± {e.std * 1e3:.2g} mm (1σ); truth "
                f"{true * 1e3:.4f} mm, error {err / true:+.4%} = {abs(err) / e.std:.2f} σ",
                flush=True,
            )


if __name__ == "__main__":
    main()
