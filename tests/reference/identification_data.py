"""Measured-data sets for clearance identification, made by the independent SciPy reference.

The "measurements" come from tests/reference/scipy_slider_crank.py in sharp mode (contact onsets
located by events, impact velocity latched at each onset, max(δ, 0) exact, no contact force in free
flight), which shares no code with jaxclear: fitting them with ``jaxclear.identify`` /
``jaxclear fit`` tests the fit against an independent model of the same physics.

Common settings (``COMMON``): benchmark slider–crank of docs/model.md §6, crank angle 0 (outer dead
centre) at t = 0, journals centred at t = 0 with the ideal-joint velocities, gravity 9.81 m/s²
along −y, Lankarani–Nikravesh contact with the joint's Hertz stiffness (E = 207 GPa, ν = 0.3,
R_B = 10 mm, R_J = R_B − c) and restitution 0.9 (impact velocity floored at 1e-4 m/s), modified
Coulomb friction μ = 0.01 (v0 = 1e-4, v1 = 1e-3 m/s, corner width 1e-5 m/s), pins on the rod
(at B the hole is in the slider, at A in the crank), Baumgarte α = β = 50 1/s (jaxclear's
default), DOP853 at rtol = 1e-13, atol = 1e-16.

Each data set ``NAME`` of ``DATASETS`` is written to tests/reference/data/ as
* ``NAME.csv``: ``t,slider_x,slider_a,crank_torque`` with Gaussian noise (s, m, m/s², N m);
* ``NAME_clean.csv``: ``t,slider_x,slider_v,slider_a,crank_torque`` without noise (m/s for v);
* ``NAME.json``: true parameters, noise σ per column and seed, settings, generation figures.
Noise: σ(slider_x) = 1 µm; σ(slider_a), σ(crank_torque) = 2 % of the clean signal's RMS over the
set. slider_a is the acceleration from the equations of motion at the sampled state (not a finite
difference); crank_torque the driver's torque, > 0 when the motor does positive work at positive
crank speed (jaxclear's ``Trajectory.input_torque``).

Agreement with jaxclear (``compare_jaxclear``): the smooth model approaches these data as its
smoothing widths shrink; at the default widths (0.1 µm) it parts from them by several σ within
a few milliseconds at 5000 rpm (``python -m tests.reference.identification_data --jaxclear``).

Commands (from the repository root; deterministic):
    .venv/bin/python -m tests.reference.identification_data [NAME ...]      # (re)write the files
    .venv/bin/python -m tests.reference.identification_data --jaxclear      # compare with jaxclear
    .venv/bin/python -m tests.reference.identification_data --sensitivity   # clearance ± 2 %
Load:
    from tests.reference.identification_data import load   # (reference.identification_data in tests)
    columns, meta = load("ident_5000rpm_B")                 # clean=True: the noise-free signals
"""

import argparse
import datetime
import json
import time
from pathlib import Path

import numpy as np

from .scipy_slider_crank import BODY_INDEX, SliderCrank, simulate

DATA_DIR = Path(__file__).resolve().parent / "data"

COMMON = dict(
    mode="sharp",
    method="DOP853",
    rtol=1e-13,  # the JSON's numerical_error compares with a run at CHECK_TOLERANCES
    atol=1e-16,  # m, m/s, rad (one for all: coordinates ~0.1 m, penetrations ~0.1-10 µm)
    restitution=0.9,
    friction=("modified-coulomb", 0.01, 1e-4, 1e-3),
    gravity=True,
    alpha=50.0,  # Baumgarte α, β (1/s): jaxclear's default (Mechanism.baumgarte_alpha/beta)
    beta=50.0,
    bearing_radius=0.01,
    E=207e9,
    nu=0.3,
)
"""Reference settings shared by every data set (keyword arguments of ``simulate``)."""

CHECK_TOLERANCES = dict(rtol=1e-12, atol=1e-15)
"""A second run at these tolerances estimates the numerical error of the clean signals (stored in
the JSON as ``numerical_error``: max |difference| / noise σ per column)."""

NOISE_X = 1e-6  # m: σ of slider_x
NOISE_RELATIVE = 0.02  # σ of slider_a and crank_torque as a fraction of the clean signal's RMS

DATASETS = {
    "ident_5000rpm_B": dict(
        rpm=5000.0,
        clearance={"B": 3.0e-4},
        journal_body={"B": "rod"},
        t_end=6e-3,
        dt=1e-5,
        max_step=1e-6,
        seed=50001,
        note=(
            "jaxclear with penetration_width = memory_width = 1e-9 m follows the clean data "
            "within 0.4 sigma over the 6 ms (0.1 um defaults: 8 sigma in slider_x by 4-5 ms)"
        ),
    ),
    "ident_200rpm_B": dict(
        rpm=200.0,
        clearance={"B": 2.5e-4},
        journal_body={"B": "rod"},
        t_end=0.3,
        dt=5e-4,
        max_step=2e-5,
        seed=2001,
        note=(
            "slider_a and crank_torque are 0 in free flight and peak at ~2000 sigma inside the "
            "~0.1 ms impacts, so samples inside impacts resolve impact timing to ~10 ns: slider_x "
            "agrees with jaxclear (1e-9 m widths) within 0.5 sigma, while slider_a and "
            "crank_torque agree within 1 sigma at every sample only with initial velocities exact "
            "to ~1e-7 relative and widths <= 1e-11 m"
        ),
    ),
    "ident_5000rpm_AB": dict(
        rpm=5000.0,
        clearance={"A": 3.5e-4, "B": 2.5e-4},
        journal_body={"A": "rod", "B": "rod"},
        t_end=6e-3,
        dt=1e-5,
        max_step=1e-6,
        seed=50002,
        note=(
            "sensitive beyond ~3 ms: clearances 1e-7 relative larger move the clean signals by "
            "0.5 sigma at 3.5-4 ms and 8 sigma by 5.5 ms; jaxclear with 1e-9 m widths follows "
            "within 0.3 sigma (slider_x) to 2 ms, with 1e-10 m to 3 ms"
        ),
    ),
    # held out: made for issue 23 after the fit's global stage was designed (docs/identification.md)
    "heldout_200rpm_B": dict(
        rpm=200.0,
        clearance={"B": 3.2e-4},
        journal_body={"B": "rod"},
        t_end=0.3,
        dt=5e-4,
        max_step=2e-5,
        seed=2302,
        note=(
            "low speed with gravity, sparse impacts (the pin falls across the clearance between "
            "them); the issue's case 1 (joint B, 200 rpm, 0-0.3 s), with a truth neither the "
            "config's 0.5 mm nor ident_200rpm_B's 0.25 mm"
        ),
    ),
    "heldout_1000rpm_A3": dict(
        rpm=1000.0,
        clearance={"A": 3.0e-4},
        journal_body={"A": "rod"},
        restitution=0.75,
        friction_coefficient=0.05,
        t_end=0.03,
        dt=5e-5,
        max_step=4e-6,
        seed=1003,
        note=(
            "three unknowns at one joint (clearance, restitution, friction coefficient), the "
            "issue's case 2 (joint A, 1000 rpm, 0-30 ms)"
        ),
    ),
}
"""Data sets: crank speed (rpm), true clearances (m) and pin bodies of the clearance joints,
window [0, t_end] (s) sampled every dt (s), the reference's largest step (s), noise seed, and a
note on what the data resolve (copied to the JSON); optionally ``restitution`` and
``friction_coefficient`` (default ``COMMON``'s 0.9 and 0.01), written to the JSON's
``true_parameters`` beside the clearances.

max_step: the sharp reference applies no force to a journal in free flight, so an onset the event
search misses (δ up and down inside one step) would let the journal through the wall; steps of
at most max_step bound such a missed graze to (relative acceleration) · max_step² / 8 ≈ 1e-9 m
(about ω² r ≈ 1.4e4 m/s² at 5000 rpm, 22 m/s² at 200 rpm); without a bound the free-flight steps
grow to ~0.1 ms and a clearance 0.1 % larger in ident_5000rpm_AB lost a whole contact."""

NOISY_COLUMNS = ("t", "slider_x", "slider_a", "crank_torque")
CLEAN_COLUMNS = ("t", "slider_x", "slider_v", "slider_a", "crank_torque")
SIGNALS = ("slider_x", "slider_a", "crank_torque")
WINDOWS = 6  # comparisons report the worst difference in each sixth of the set


def time_grid(t_end, dt):
    """Uniform samples 0, dt, ..., t_end (s), t_end a multiple of dt."""
    n = int(round(t_end / dt))
    if abs(n * dt - t_end) > 1e-9 * t_end:
        raise ValueError(f"t_end={t_end} is not a multiple of dt={dt}")
    return np.linspace(0.0, t_end, n + 1)


def clean_signals(spec, t=None, clearance=None, **overrides):
    """Clean reference signals of a data set and the run's stats.

    Args:
        spec: an entry of ``DATASETS`` (or a dict with the same keys).
        t: output times, s (default the data set's grid).
        clearance: joint -> c, m (default the data set's true values), e.g. for sensitivities.
        **overrides: other ``simulate`` keyword arguments replacing ``COMMON`` (rtol, ...).

    Returns:
        (columns, stats): ``CLEAN_COLUMNS`` plus ``<joint>_delta`` (m) and ``<joint>_normal_force``
        (N) as arrays; the reference's run statistics plus ``bearing_body`` per joint.
    """
    t = time_grid(spec["t_end"], spec["dt"]) if t is None else np.asarray(t, float)
    clearance = dict(spec["clearance"] if clearance is None else clearance)
    r = simulate(
        clearance_joints=tuple(clearance),
        rpm=spec["rpm"],
        clearance=clearance,
        journal_body=spec["journal_body"],
        t_eval=t,
        **{**COMMON, **contact_settings(spec), "max_step": spec["max_step"], **overrides},
    )
    out = {name: np.asarray(r[name], float) for name in CLEAN_COLUMNS}
    for j in clearance:
        out[j + "_normal_force"] = r[j + "_normal_force"]
        out[j + "_delta"] = r[j + "_delta"]
    names = {b: n for n, b in BODY_INDEX.items()}
    stats = dict(r["stats"], bearing_body={j: names[g[0]] for j, g in r["model"].joints.items()})
    return out, stats


def contact_settings(spec):
    """The data set's restitution and friction as ``simulate`` keywords (``COMMON``'s by default)."""
    law, mu, v0, v1 = COMMON["friction"]
    return dict(
        restitution=spec.get("restitution", COMMON["restitution"]),
        friction=(law, spec.get("friction_coefficient", mu), v0, v1),
    )


def true_parameters(spec):
    """What a fit should find: clearances per joint, and restitution and friction coefficient
    (one value for every joint of the set)."""
    contact = contact_settings(spec)
    return {
        "clearance": dict(spec["clearance"]),
        "restitution": contact["restitution"],
        "friction_coefficient": contact["friction"][1],
    }


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def noise_sigma(clean):
    """Noise σ per noisy column from the clean signals (module doc)."""
    return {
        "slider_x": NOISE_X,
        "slider_a": NOISE_RELATIVE * rms(clean["slider_a"]),
        "crank_torque": NOISE_RELATIVE * rms(clean["crank_torque"]),
    }


def difference(a, b, sigma, t, windows=WINDOWS):
    """Differences a − b of each signal in units of the noise σ.

    Returns:
        {signal: dict(rms, max, window_max (list, one per window), first_above_sigma_s (first
        time |a − b| > σ, or None), chi2 (Σ ((a − b)/σ)²))}.
    """
    edges = np.linspace(t[0], t[-1], windows + 1)
    out = {}
    for c in SIGNALS:
        d = (np.asarray(a[c]) - np.asarray(b[c])) / sigma[c]
        above = np.flatnonzero(np.abs(d) > 1.0)
        out[c] = dict(
            rms=rms(d),
            max=float(np.abs(d).max()),
            window_max=[
                float(np.abs(d[(t >= lo) & (t <= hi)]).max())
                for lo, hi in zip(edges[:-1], edges[1:])
            ],
            first_above_sigma_s=float(t[above[0]]) if above.size else None,
            chi2=float(np.sum(d * d)),
        )
    return out


def generate(name):
    """(clean columns, noisy columns, metadata) of data set ``name``."""
    spec = DATASETS[name]
    wall = time.perf_counter()
    clean, stats = clean_signals(spec)
    wall = time.perf_counter() - wall
    check, _ = clean_signals(spec, **CHECK_TOLERANCES)
    sigma = noise_sigma(clean)
    numerical = difference(check, clean, sigma, clean["t"])
    rng = np.random.default_rng(spec["seed"])
    noisy = {"t": clean["t"]}
    for col in NOISY_COLUMNS[1:]:  # drawn in this column order
        noisy[col] = clean[col] + sigma[col] * rng.standard_normal(clean[col].shape)
    joints = tuple(spec["clearance"])
    meta = dict(
        name=name,
        source=(
            "tests/reference/scipy_slider_crank.py (independent NumPy/SciPy reference, no jaxclear "
            "code) in sharp mode: contact onsets located by events, impact velocity latched at "
            "each onset, no contact force in free flight; written by "
            "tests/reference/identification_data.py"
        ),
        true_parameters=true_parameters(spec),
        note=spec["note"],
        clearance_joints=list(joints),
        journal_body=dict(spec["journal_body"]),
        bearing_body=stats["bearing_body"],
        columns=dict(
            t="s",
            slider_x="m",
            slider_v="m/s (clean file only)",
            slider_a="m/s^2, from the equations of motion at the sampled state",
            crank_torque="N m, > 0 when the motor does positive work at positive crank speed",
        ),
        noise=dict(
            distribution="independent Gaussian, zero mean",
            sigma=sigma,
            rule="slider_x: 1e-6 m; slider_a, crank_torque: 2 % of the clean signal's RMS",
            clean_rms={c: rms(clean[c]) for c in ("slider_a", "crank_torque")},
            seed=spec["seed"],
            generator="numpy.random.default_rng(seed).standard_normal, columns in file order",
        ),
        time_grid=dict(t_start=0.0, t_end=spec["t_end"], dt=spec["dt"], samples=len(clean["t"])),
        reference=dict(
            rpm=spec["rpm"],
            initial_crank_angle_rad=0.0,
            initial_state="ideal-joint assembly at crank angle 0 (outer dead centre), journals centred",
            mode="sharp",
            contact_law="lankarani-nikravesh, K = 4/(3(σ_B+σ_J)) sqrt(R_B R_J/c), exponent 1.5",
            restitution=contact_settings(spec)["restitution"],
            min_impact_velocity=1e-4,
            friction=dict(
                law="modified-coulomb",
                friction_coefficient=contact_settings(spec)["friction"][1],
                lower_velocity=COMMON["friction"][2],
                upper_velocity=COMMON["friction"][3],
                velocity_width=1e-5,
            ),
            gravity=dict(g=9.81, direction="-y"),
            young_modulus=COMMON["E"],
            poisson_ratio=COMMON["nu"],
            bearing_radius=COMMON["bearing_radius"],
            baumgarte_alpha=COMMON["alpha"],
            baumgarte_beta=COMMON["beta"],
            method=COMMON["method"],
            rtol=COMMON["rtol"],
            atol=COMMON["atol"],
            max_step_s=spec["max_step"],
        ),
        numerical_error=dict(
            note=f"max |clean - run at rtol {CHECK_TOLERANCES['rtol']}, atol "
            f"{CHECK_TOLERANCES['atol']}| / noise sigma",
            **{c: numerical[c]["max"] for c in SIGNALS},
        ),
        generation=dict(
            wall_time_s=round(wall, 2),
            utc=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            rhs_evaluations=int(stats["nfev"]),
            contact_onsets=stats["onsets"],
            max_penetration_at_samples_m={j: float(np.max(clean[j + "_delta"])) for j in joints},
            max_normal_force_at_samples_N={
                j: float(np.max(clean[j + "_normal_force"])) for j in joints
            },
        ),
        jaxclear_equivalent=(
            "jaxclear.mechanisms.slider_crank(rpm=RPM, gravity=True, clearance_joints={J: "
            "dict(clearance=C_J, journal_body='rod'), ...}, contact_law=LankaraniNikravesh("
            f"restitution={contact_settings(spec)['restitution']:g}), friction_law=ModifiedCoulomb("
            f"friction_coefficient={contact_settings(spec)['friction'][1]:g})); the smooth "
            "model needs penetration_width = memory_width <= 1e-9 m (Smoothing) to follow these data "
            "within the noise (see compare_jaxclear)"
        ),
    )
    return clean, noisy, meta


def write_csv(path, columns, names):
    data = np.column_stack([columns[n] for n in names])
    np.savetxt(path, data, fmt="%.12g", delimiter=",", header=",".join(names), comments="")


def write(name, directory=DATA_DIR):
    """Generate data set ``name`` and write its CSV, clean CSV and JSON; returns the metadata."""
    clean, noisy, meta = generate(name)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    write_csv(directory / f"{name}.csv", noisy, NOISY_COLUMNS)
    write_csv(directory / f"{name}_clean.csv", clean, CLEAN_COLUMNS)
    (directory / f"{name}.json").write_text(json.dumps(meta, indent=2) + "\n")
    return meta


def load(name, clean=False, directory=DATA_DIR):
    """Read a data set.

    Args:
        name: a key of ``DATASETS`` (e.g. ``"ident_5000rpm_B"``).
        clean: read the noise-free signals (``NAME_clean.csv``, with slider_v) instead.
        directory: where the files are (default tests/reference/data/).

    Returns:
        (columns, metadata): a dict column name -> 1-D numpy array (SI units), and the JSON dict.
    """
    directory = Path(directory)
    path = directory / (f"{name}_clean.csv" if clean else f"{name}.csv")
    with open(path) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    meta = json.loads((directory / f"{name}.json").read_text())
    return {n: data[:, i].copy() for i, n in enumerate(names)}, meta


# ------------------------------------------------------------------ checks (not run by the tests)
def jaxclear_signals(
    name, width=None, method="dopri8", rtol=1e-11, t=None, clearance=None, start="jaxclear"
):
    """The same mechanism simulated by jaxclear's smooth model.

    Args:
        name: data set.
        width: ``Smoothing`` penetration_width = memory_width, m (None: jaxclear's default).
        method, rtol: jaxclear solver (atol = 1e-3 rtol).
        t: output times (default the data set's grid).
        clearance: joint -> c (default the true values).
        start: ``"jaxclear"`` (``jaxclear.assemble``) or ``"reference"``: q and q̇ of the
            reference's ``initial_state`` (exact ideal-joint velocities), jaxclear's internal states.

    Returns:
        (columns, stats) with slider_x, slider_v, slider_a, crank_torque.
    """
    import jaxclear
    from jaxclear.contact import LankaraniNikravesh, Smoothing
    from jaxclear.friction import ModifiedCoulomb

    spec = DATASETS[name]
    t = time_grid(spec["t_end"], spec["dt"]) if t is None else np.asarray(t, float)
    clearance = dict(spec["clearance"] if clearance is None else clearance)
    options = {}
    if width is not None:
        options["smoothing"] = Smoothing(penetration_width=width, memory_width=width)
    mech = jaxclear.mechanisms.slider_crank(
        rpm=spec["rpm"],
        gravity=True,
        clearance_joints={
            j: dict(clearance=c, journal_body=spec["journal_body"][j]) for j, c in clearance.items()
        },
        contact_law=LankaraniNikravesh(restitution=contact_settings(spec)["restitution"]),
        friction_law=ModifiedCoulomb(friction_coefficient=contact_settings(spec)["friction"][1]),
        **options,
    )
    config = jaxclear.SolverConfig(method=method, rtol=rtol, atol=1e-3 * rtol, max_steps=2_000_000)
    y0 = None
    if start == "reference":
        model = SliderCrank(
            tuple(clearance),
            spec["rpm"],
            "sharp",
            clearance=clearance,
            journal_body=spec["journal_body"],
        )
        y0 = np.array(jaxclear.assemble(mech))
        y0[:18] = model.initial_state()[:18]
    traj = jaxclear.simulate(mech, float(t[-1]), ts=t, y0=y0, solver=config, extremes=False)
    out = dict(
        t=np.asarray(traj.t),
        slider_x=np.asarray(traj.coordinates("slider")[:, 0]),
        slider_v=np.asarray(traj.velocities("slider")[:, 0]),
        slider_a=np.asarray(traj.accelerations("slider")[:, 0]),
        crank_torque=np.asarray(traj.input_torque),
    )
    return out, traj.stats()


def compare_jaxclear(
    name, widths=(None, 1e-8, 1e-9, 1e-10), method="dopri8", rtol=1e-11, start="jaxclear"
):
    """Differences of jaxclear's signals from the committed clean data, per smoothing width.

    Returns:
        {width: ``difference`` dict}, in units of the data set's noise σ.
    """
    clean, meta = load(name, clean=True)
    sigma = meta["noise"]["sigma"]
    res = {}
    for w in widths:
        jx, _ = jaxclear_signals(name, w, method, rtol, start=start)
        res[w] = difference(jx, clean, sigma, clean["t"])
    return res


def sensitivity(name, relative=0.02):
    """Change of the clean signals when one clearance changes by ±``relative``.

    Returns:
        {"<joint> <sign>": ``difference`` dict}, in units of the data set's noise σ.
    """
    spec = DATASETS[name]
    clean, meta = load(name, clean=True)
    sigma = meta["noise"]["sigma"]
    res = {}
    for j, c in spec["clearance"].items():
        for sign in (+1, -1):
            changed = dict(spec["clearance"], **{j: c * (1 + sign * relative)})
            sig, _ = clean_signals(spec, clearance=changed)
            res[f"{j} {'+' if sign > 0 else '-'}{100 * relative:g} %"] = difference(
                sig, clean, sigma, clean["t"]
            )
    return res


def _print_table(title, res, t_end):
    print(title)
    for key, d in res.items():
        for c in SIGNALS:
            v = d[c]
            first = v["first_above_sigma_s"]
            print(
                f"  {str(key):>14} {c:>12}: rms {v['rms']:8.3g}  max {v['max']:8.3g}  "
                f"chi2 {v['chi2']:9.3g}  first>σ "
                + (f"{first * 1e3:7.2f} ms" if first is not None else "   never  ")
                + "  per sixth of [0, %g ms]: " % (t_end * 1e3)
                + " ".join(f"{x:.3g}" for x in v["window_max"])
            )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=list(DATASETS), help="data sets")
    parser.add_argument("--directory", default=str(DATA_DIR), help="where to write the files")
    parser.add_argument(
        "--jaxclear", action="store_true", help="compare the committed data with jaxclear"
    )
    parser.add_argument(
        "--widths",
        default="default,1e-8,1e-9,1e-10",
        help="--jaxclear: smoothing widths (m; 'default' for jaxclear's), comma-separated",
    )
    parser.add_argument(
        "--start",
        choices=("jaxclear", "reference"),
        default="jaxclear",
        help="--jaxclear: jaxclear's assembled start, or the reference's q, q̇ (exact velocities)",
    )
    parser.add_argument(
        "--sensitivity", action="store_true", help="signal changes for clearance ± 2 %%"
    )
    parser.add_argument("--relative", type=float, default=0.02, help="--sensitivity: the change")
    args = parser.parse_args(argv)
    widths = [None if w == "default" else float(w) for w in args.widths.split(",")]
    for name in args.names:
        t_end = DATASETS[name]["t_end"]
        if args.jaxclear:
            _print_table(
                f"{name}: jaxclear (dopri8, rtol 1e-11, {args.start} start) - data, / σ, "
                "per smoothing width (m)",
                compare_jaxclear(name, widths, start=args.start),
                t_end,
            )
        elif args.sensitivity:
            _print_table(
                f"{name}: reference with a changed clearance - data, / σ",
                sensitivity(name, args.relative),
                t_end,
            )
        else:
            meta = write(name, args.directory)
            g = meta["generation"]
            print(
                f"{name}: {meta['time_grid']['samples']} samples, {g['wall_time_s']} s, "
                f"onsets {g['contact_onsets']}, noise σ {meta['noise']['sigma']}, "
                f"numerical error / σ {meta['numerical_error']}"
            )


if __name__ == "__main__":
    main()
