"""Translational clearance joint (docs/model.md §2c): corner gap functions, static rest, the
c -> 0 limit and the unactuated Flores–Leine–Glocker slider–crank (slow).

Compiled solves are shared per module: one slider–crank (clearance, stiffness are array leaves,
so the c -> 0 sequence reuses one program) and one free slider resting in its guide.
"""

import json
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear import Body, Mechanism, ModelError, TranslationalClearanceJoint, cli
from jaxclear.cli._config import resolve_settings
from jaxclear.cli._main import build_parser
from jaxclear.cli._mechanism_config import build_mechanism
from jaxclear.contact import Flores, Hertz, Hybrid
from jaxclear.dynamics import clearance_outputs, evaluate, initial_state
from jaxclear.friction import Coulomb, NoFriction
from jaxclear.mechanisms import slider_crank

A, B = 0.05, 0.025  # slider half-length and half-height (Flores, Leine & Glocker 2010), m
SIDES = np.array([1.0, 1.0, -1.0, -1.0])  # upper, upper, lower, lower
ENDS = np.array([1.0, -1.0, -1.0, 1.0])  # front, rear, rear, front
SOLVER = jaxclear.SolverConfig(method="tsit5", rtol=1e-8, atol=1e-11, max_steps=400_000)
"""The settings of tests/test_clearance_joint.py."""


# --- (i) gap functions against a hand derivation ---------------------------------------------------
def _free_pair(clearance, slider_point, guide_point, axis_angle, angle, contact_law):
    """A moving guide body and a slider with no joint between them but the clearance joint."""
    joint = TranslationalClearanceJoint(
        "G",
        "slider",
        slider_point,
        "guide",
        guide_point,
        half_length=A,
        half_height=B,
        clearance=clearance,
        axis=(2.0 * np.cos(axis_angle), 2.0 * np.sin(axis_angle)),  # not unit: normalised inside
        angle=angle,
        contact_law=contact_law,
        friction_law=Coulomb(friction_coefficient=0.3, velocity_tolerance=1e-3),
    )
    bodies = (Body("guide", 1.0, 1.0), Body("slider", 0.1, 1e-4))
    return Mechanism(bodies=bodies, gravity=(0.0, 0.0), translational_clearance_joints=(joint,))


@eqx.filter_jit
def _evaluate(mech, q, qd):
    """(generalised forces Q, the joint's outputs) at (q, q̇), internal states at their start."""
    ev = evaluate(mech, 0.0, initial_state(mech, q, qd))
    return ev.forces, clearance_outputs(mech, ev)["G"]


def _rot(phi):
    return np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])


def test_gap_functions_and_corner_forces_match_hand_derivation():
    """At random poses of a moving guide and a slider: δ_k = σ_b η + σ_a σ_b a sin θ + b cos θ −
    (b + c) with η the slider centre's height over the guide line and θ the tilt (hand derivation,
    docs/model.md §2c); the rates match finite differences; the generalised force equals
    Σ J_kᵀ f_k with f_k = −σ_b F_N,k n + F_T,k t (virtual work)."""
    rng = np.random.default_rng(26)
    c = 1e-3
    law = Hertz(stiffness=1e9, exponent=1.5)
    for _ in range(4):
        sp, gp = rng.normal(scale=0.02, size=2), rng.normal(scale=0.05, size=2)
        beta, alpha = rng.uniform(-np.pi, np.pi, size=2)
        mech = _free_pair(c, sp, gp, beta, alpha, law)
        guide = np.array([*rng.normal(scale=0.1, size=2), rng.uniform(-np.pi, np.pi)])
        tilt = rng.uniform(-0.02, 0.02)
        eta = rng.uniform(-1.2 * c, 1.2 * c)  # some corners penetrate their faces
        xi = rng.normal(scale=0.05)
        t_axis = _rot(guide[2]) @ np.array([np.cos(beta), np.sin(beta)])
        n_axis = np.array([-t_axis[1], t_axis[0]])
        r_q = guide[:2] + _rot(guide[2]) @ gp
        phi_s = guide[2] + alpha + tilt
        centre = r_q + xi * t_axis + eta * n_axis
        slider = np.array([*(centre - _rot(phi_s) @ sp), phi_s])
        q = jnp.asarray(np.concatenate([guide, slider]))
        qd = jnp.asarray(rng.normal(scale=[0.1, 0.1, 1.0, 0.1, 0.1, 1.0]))
        forces, out = _evaluate(mech, q, qd)

        hand = SIDES * eta + ENDS * SIDES * A * np.sin(tilt) + B * np.cos(tilt) - (B + c)
        np.testing.assert_allclose(out["corner_penetration"], hand, rtol=0, atol=1e-15)
        np.testing.assert_allclose(out["tilt"], tilt, atol=1e-14)
        np.testing.assert_allclose(out["offset"], eta, atol=1e-15)
        assert float(out["penetration"]) == pytest.approx(hand.max(), abs=1e-15)

        h = 1e-7
        ahead, behind = _evaluate(mech, q + h * qd, qd)[1], _evaluate(mech, q - h * qd, qd)[1]
        fd = (
            np.asarray(ahead["corner_penetration"]) - np.asarray(behind["corner_penetration"])
        ) / (2 * h)
        np.testing.assert_allclose(out["corner_penetration_rate"], fd, rtol=1e-6, atol=1e-9)

        # corner positions by hand: r_k = r_P + σ_a a u + σ_b b v, u = A(φ_s − α) â
        u = _rot(phi_s - alpha) @ np.array([np.cos(beta), np.sin(beta)])
        v = np.array([-u[1], u[0]])
        r_k = centre[None, :] + (ENDS * A)[:, None] * u + (SIDES * B)[:, None] * v
        f_k = (-SIDES * np.asarray(out["corner_normal_force"]))[:, None] * n_axis + np.asarray(
            out["corner_friction_force"]
        )[:, None] * t_axis
        assert np.all(np.asarray(out["corner_normal_force"])[hand > 1e-6] > 0)
        assert np.all(np.asarray(out["corner_normal_force"])[hand < 0] == 0)
        on_slider = np.array(
            [
                f_k[:, 0].sum(),
                f_k[:, 1].sum(),
                np.sum((r_k[:, 0] - slider[0]) * f_k[:, 1] - (r_k[:, 1] - slider[1]) * f_k[:, 0]),
            ]
        )
        on_guide = np.array(
            [
                -f_k[:, 0].sum(),
                -f_k[:, 1].sum(),
                -np.sum((r_k[:, 0] - guide[0]) * f_k[:, 1] - (r_k[:, 1] - guide[1]) * f_k[:, 0]),
            ]
        )
        scale = max(1.0, float(np.abs(f_k).max()))
        np.testing.assert_allclose(forces[3:], on_slider, atol=1e-10 * scale)
        np.testing.assert_allclose(forces[:3], on_guide, atol=1e-10 * scale)


# --- one compiled slider–crank for (ii) and (iii) -------------------------------------------------------
G = 9.81
RPM = 1000.0
OMEGA = RPM * 2 * np.pi / 60
CRANK, ROD = 0.05, 0.12
SLIDER_MASS = 0.14
WINDOW = 0.01  # s: at 1000 rpm, 60 degrees of crank from outer dead centre
POINTS = 41


def crank_run(clearance, stiffness, rpm, slider_point=(0.0, 0.0), initial_offset=0.0):
    """The gravity-loaded benchmark slider–crank with a translational clearance guide (Flores law,
    c_e = 0.4, no friction). Clearance, stiffness, speed, the rectangle's centre on the slider and
    the initial offset are array leaves: every call runs one compiled program."""
    mech = slider_crank(
        rpm=rpm,
        gravity=True,
        translational_clearance=dict(
            clearance=clearance,
            contact_law=Flores(stiffness=stiffness, restitution=0.4),
            friction_law=NoFriction(),
            initial_offset=initial_offset,
        ),
    )
    mech = eqx.tree_at(
        lambda m: m.translational_clearance_joints[0].slider_point,
        mech,
        jnp.asarray(slider_point, dtype=float),
    )
    return jaxclear.simulate(mech, WINDOW, num_points=POINTS, solver=SOLVER, extremes=False)


# --- (ii) static rest on the lower face -------------------------------------------------------------
REST_K, REST_N, REST_C = 1e9, 1.5, 1e-3
CENTRE_AHEAD = (
    0.02  # m: the rectangle's centre lies this far ahead of pin B (the slider's mass centre)
)


@pytest.fixture(scope="module")
def resting():
    """The crank held still at outer dead centre (rpm = 0): the slider, dropped 1 µm above the
    lower face, settles there under its weight and the rod's; its rectangle is centred 20 mm ahead
    of pin B, so the load acts off-centre."""
    return crank_run(REST_C, REST_K, 0.0, (CENTRE_AHEAD, 0.0), -REST_C + 1e-6)


def test_static_rest_balances_load_and_moment(resting):
    """At rest on the lower face only the two lower corners carry load; their forces balance the
    slider's weight plus the rod's force at B, W = m g − F_B,y (ΣF_N = W), and its moment about the
    rectangle's centre, a (F_front − F_rear) = −W d (d = 20 mm); each corner's penetration is
    (F_k/K)^(1/n) with F_k from the lever rule (hand derivation)."""
    out = resting.clearance["slider_guide"]
    assert np.max(np.abs(np.asarray(resting.qd[-1]))) < 1e-6  # at rest
    force = np.asarray(out["corner_normal_force"])[-1]
    rod_on_slider = np.asarray(resting.reactions["B"])[-1]  # λ_B: force of the rod on the slider
    load = SLIDER_MASS * G - rod_on_slider[1]
    assert np.all(force[:2] == 0)  # upper corners off their face
    np.testing.assert_allclose(force[2] + force[3], load, rtol=1e-6)
    np.testing.assert_allclose(A * (force[3] - force[2]), -load * CENTRE_AHEAD, rtol=1e-5)
    front = 0.5 * load - load * CENTRE_AHEAD / (2 * A)
    rear = load - front
    # the smooth positive part of δ (width w) is δ − w/2 in contact (docs/model.md §5)
    shift = 0.5 * float(jaxclear.contact.Smoothing().penetration_width)
    hand = [(rear / REST_K) ** (1 / REST_N) + shift, (front / REST_K) ** (1 / REST_N) + shift]
    np.testing.assert_allclose(np.asarray(out["corner_penetration"])[-1, 2:], hand, rtol=1e-5)
    assert float(out["tilt"][-1]) > 0  # the load behind the centre sinks the rear end deeper


def test_output_columns(resting):
    """results.csv columns of the joint: offset, tilt, per-corner quantities and corner-pair modes."""
    columns = jaxclear.io.column_map(resting)
    for name in (
        "offset",
        "tilt",
        "penetration",
        "normal_force",
        "mode",
        "mode_upper",
        "mode_lower",
    ):
        assert f"slider_guide_{name}" in columns
    force = np.asarray(resting.clearance["slider_guide"]["corner_normal_force"])
    for k, corner in enumerate(("upper_front", "upper_rear", "lower_rear", "lower_front")):
        np.testing.assert_array_equal(
            columns[f"slider_guide_normal_force_{corner}"].values, force[:, k]
        )
    assert columns["slider_guide_mode_upper"].values.max() == 0  # never on the upper face
    assert columns["slider_guide_mode_lower"].values[-1] == 2  # resting: continuous contact
    assert "slider_guide" not in jaxclear.io.clearance_joint_names(resting)


# --- (iii) c -> 0: the ideal translational joint -------------------------------------------------------
CLEARANCES = (1e-4, 1e-5, 1e-6)
STIFF = 1e13  # N/m^1.5


def _ideal_torque(theta):
    """Input torque of the ideal slider–crank at constant speed by the energy method:
    τ = ½ M'(θ) ω² + V'(θ), M(θ) = Σ m |∂r/∂θ|² + J (∂φ/∂θ)², V = Σ m g y, from the closed-form
    positions with central differences (independent of the simulator)."""
    theta = np.asarray(theta, dtype=float)
    masses = np.array([0.30, 0.21, SLIDER_MASS])[:, None]
    inertias = np.array([1e-4, 2.5e-4, 1e-4])[:, None]

    def pose(th):
        ax, ay = CRANK * np.cos(th), CRANK * np.sin(th)
        bx = ax + np.sqrt(ROD**2 - ay**2)
        zero = np.zeros_like(th)
        x = np.stack([0.5 * ax, 0.5 * (ax + bx), bx])
        y = np.stack([0.5 * ay, 0.5 * ay, zero])
        return x, y, np.stack([th, np.arctan2(-ay, bx - ax), zero])

    def inertia(th, h=1e-6):
        ahead, behind = pose(th + h), pose(th - h)
        dx, dy, dphi = ((p - m) / (2 * h) for p, m in zip(ahead, behind))
        return np.sum(masses * (dx**2 + dy**2) + inertias * dphi**2, axis=0)

    def potential(th):
        return G * np.sum(masses * pose(th)[1], axis=0)

    h = 1e-4
    m_prime = (inertia(theta + h) - inertia(theta - h)) / (2 * h)
    v_prime = (potential(theta + h) - potential(theta - h)) / (2 * h)
    return 0.5 * m_prime * OMEGA**2 + v_prime


@pytest.fixture(scope="module")
def crank_runs():
    """The slider–crank at 1000 rpm for a sequence of clearances at a large corner stiffness."""
    return {c: crank_run(c, STIFF, RPM) for c in CLEARANCES}


def test_converges_to_the_ideal_translational_joint(crank_runs):
    """As c -> 0 (K = 1e13 N/m^1.5) the slider follows the closed-form ideal slider position, its
    tilt and lateral offset vanish, and the crank torque approaches the ideal (energy-method)
    torque; the errors shrink with c."""
    slider_err, torque_err = [], []
    for c, traj in crank_runs.items():
        t = np.asarray(traj.t)
        th = OMEGA * t
        x_ideal = CRANK * np.cos(th) + np.sqrt(ROD**2 - (CRANK * np.sin(th)) ** 2)
        out = traj.clearance["slider_guide"]
        assert np.max(np.abs(out["offset"])) < c + 1e-6
        assert np.max(np.abs(out["tilt"])) < 2 * (c + 1e-6) / A
        slider_err.append(np.max(np.abs(np.asarray(traj.q[:, 6]) - x_ideal)))
        late = t > 1e-3  # after the slider has crossed the clearance onto its face
        ideal = _ideal_torque(th[late])
        torque_err.append(np.max(np.abs(np.asarray(traj.input_torque)[late] - ideal)))
    scale = np.max(np.abs(_ideal_torque(np.linspace(0.0, OMEGA * WINDOW, 50))))
    print(f"slider errors {slider_err} m, torque errors {torque_err} N m, peak torque {scale} N m")
    # measured: slider errors 3.9e-5, 3.9e-6, 4.1e-7 m (first order in c); torque errors 0.13,
    # 0.10, 9.3e-4 N m against a peak ideal torque of 5.6 N m
    for k, c in enumerate(CLEARANCES):
        assert slider_err[k] < c
    assert slider_err[1] < 0.2 * slider_err[0] and slider_err[2] < 0.2 * slider_err[1]
    assert torque_err[-1] < 0.05 * torque_err[0]
    assert torque_err[-1] < 1e-3 * scale


# --- bad input -----------------------------------------------------------------------------------------
def test_bad_input_names_the_parameter():
    guide = jaxclear.TranslationalJoint("g", "slider", (0.0, 0.0), "ground", (0.0, 0.0))
    with pytest.raises(ModelError, match="clearance must be > 0"):
        TranslationalClearanceJoint.replacing(guide, clearance=-1e-3, half_length=A, half_height=B)
    with pytest.raises(ModelError, match="half_length must be > 0"):
        TranslationalClearanceJoint.replacing(guide, clearance=1e-3, half_length=0.0, half_height=B)
    with pytest.raises(ModelError, match="does not apply to a corner"):
        TranslationalClearanceJoint.replacing(
            guide, clearance=1e-3, half_length=A, half_height=B, contact_law=Hybrid()
        )
    with pytest.raises(ModelError, match="explicit stiffness"):
        TranslationalClearanceJoint.replacing(
            guide, clearance=1e-3, half_length=A, half_height=B, contact_law=Hertz()
        )
    with pytest.raises(TypeError, match="unknown translational_clearance option"):
        slider_crank(translational_clearance={"width": 1e-3})
    mech = slider_crank(translational_clearance=1e-3)
    assert mech.degrees_of_freedom == 2 and "slider_guide" not in [j.name for j in mech.joints]
    assert mech.translational_clearance_joints[0].clearance == 1e-3


# --- parameters by name (montecarlo, sweep, --fit) ---------------------------------------------------------
def test_parameter_names_round_trip():
    """The guide's clearance, the slider's size and the corner laws' values are named parameters:
    ``with_parameters`` sets the joint's leaves, ``get_parameter`` reads them back."""
    mech = slider_crank(translational_clearance=1e-3, clearance_joints="B")
    names = jaxclear.parameter_names(mech)
    values = {
        "slider_guide.clearance": 4e-4,
        "slider_guide.half_length": 0.04,
        "slider_guide.half_height": 0.02,
        "slider_guide.stiffness": 3e10,
        "slider_guide.restitution": 0.6,
        "slider_guide.friction_coefficient": 0.05,
        "slider_guide.penetration_width": 2e-7,
        "B.clearance": 3e-4,  # the revolute joint's own, beside it
    }
    assert set(values) <= set(names)
    new = jaxclear.with_parameters(mech, values)
    for name, value in values.items():
        assert float(jaxclear.get_parameter(new, name)) == pytest.approx(value)
        assert float(jaxclear.get_parameter(mech, name)) != pytest.approx(value)
    (joint,) = new.translational_clearance_joints
    assert (float(joint.clearance), float(joint.half_length), float(joint.half_height)) == (
        4e-4,
        0.04,
        0.02,
    )
    assert float(joint.contact_law.stiffness) == 3e10
    info = jaxclear.parameter_info(mech, "slider_guide.clearance")
    assert info.unit == "m" and info.domain[0] == 0.0
    assert jaxclear.parameter_info(mech, "slider_guide.restitution").domain == (0.0, 1.0)
    # a centre-of-mass shift keeps the slider rectangle where it is on the body
    shifted = jaxclear.with_parameters(mech, {"slider_com_x": 0.01})
    point = shifted.translational_clearance_joints[0].slider_point
    np.testing.assert_allclose(point, np.asarray(joint.slider_point) - [0.01, 0.0])
    # an ideal guide has no clearance to vary: the error says how to give it one
    with pytest.raises(ModelError, match="ideal translational joint .* translational_clearance=c"):
        jaxclear.get_parameter(slider_crank(), "slider_guide.clearance")


# --- command line ----------------------------------------------------------------------------------------
EXAMPLE = Path(jaxclear.__file__).parent / "model" / "slider_crank_translational_clearance.toml"


def _config_with(tmp_path, table: str, drop: tuple[str, ...] = ()) -> Path:
    """The example config with the lines setting the keys ``drop`` removed and ``table`` added to
    its ``[clearance.slider_guide]``."""
    lines = [
        line
        for line in EXAMPLE.read_text().splitlines()
        if not any(line.startswith(f"{key} =") for key in drop)
    ]
    text = "\n".join(lines).replace(
        "[clearance.slider_guide]", "[clearance.slider_guide]\n" + table
    )
    config = tmp_path / "config.toml"
    config.write_text(text + "\n")
    return config


def _built(config: Path):
    return build_mechanism(resolve_settings(build_parser().parse_args(["run", str(config)])))


def test_example_config_builds_the_joint():
    (joint,) = _built(EXAMPLE).translational_clearance_joints
    assert float(joint.clearance) == 1e-3 and float(joint.half_length) == A
    assert float(joint.half_height) == B and float(joint.contact_law.stiffness) == 1e10
    assert isinstance(joint.contact_law, Flores) and float(joint.contact_law.restitution) == 0.4
    assert isinstance(joint.friction_law, Coulomb)
    assert "slider_guide" not in [j.name for j in _built(EXAMPLE).joints]


def test_per_joint_keys_reach_the_joint(tmp_path):
    """half_length, half_height and contact_stiffness of [clearance.<joint>] set a, b and K; with
    neither contact nor restitution given the corners take the Flores law with restitution 0.4,
    not the pins' defaults (hybrid, 0.9)."""
    keys = ("half_length", "half_height", "contact_stiffness", "contact", "restitution")
    table = "half_length = 0.04\nhalf_height = 0.02\ncontact_stiffness = 2e10"
    (joint,) = _built(_config_with(tmp_path, table, drop=keys)).translational_clearance_joints
    assert (float(joint.half_length), float(joint.half_height)) == (0.04, 0.02)
    assert isinstance(joint.contact_law, Flores)
    assert float(joint.contact_law.stiffness) == 2e10
    assert float(joint.contact_law.restitution) == 0.4
    # a restitution given in the shared [clearance] table applies to the corners too
    shared = _config_with(tmp_path, "", drop=keys)
    shared.write_text(
        shared.read_text().replace(
            'joints = "slider_guide"', 'joints = "slider_guide"\nrestitution = 0.7'
        )
    )
    (joint,) = _built(shared).translational_clearance_joints
    assert float(joint.contact_law.restitution) == 0.7


@pytest.mark.parametrize(
    "table, message",
    [
        ('contact = "hybrid"', "does not apply to the corners"),
        ('journal_body = "rod"', "revolute clearance joints only"),
        ("clearance = -1e-3", "clearance"),
        ("", "given its guide's clearance in a table"),
        ("half_height = -1", "[clearance.slider_guide] half_height in"),
        ("half_length = 0", "[clearance.slider_guide] half_length in"),
        ("contact_stiffness = -1e10", "[clearance.slider_guide] contact_stiffness in"),
        ("half_length = true", "half_length in"),
    ],
)
def test_bad_config_exits_2(tmp_path, capsys, table, message):
    """One-line errors, exit 2: a law that needs a pin, a revolute-only key, a negative clearance,
    a translational joint without its own table's clearance, a slider size or corner stiffness
    that is not a positive number."""
    key = table.split(" = ")[0] if table else "clearance"
    config = _config_with(tmp_path, table, drop=(key, "contact"))
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(config), "--out", str(tmp_path / "out")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    if "half" in table or "stiffness" in table:
        assert "must be positive" in err or "must be a number" in err


@pytest.mark.parametrize(
    "text, message",
    [
        # slider sizes and the corner stiffness belong to a translational joint's own table
        ("[clearance]\nhalf_length = 0.04", "belongs in a per-joint table"),
        (
            '[clearance]\njoints = "B"\n[clearance.B]\ncontact_stiffness = 1e10',
            "[clearance.B] contact_stiffness: applies to translational clearance joints only",
        ),
    ],
)
def test_translational_keys_elsewhere_exit_2(tmp_path, capsys, text, message):
    config = tmp_path / "bad.toml"
    config.write_text(text + "\n")
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(config), "--out", str(tmp_path / "out")])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err


def test_example_runs_from_the_command_line(tmp_path, capsys):
    """``jaxclear run`` on the example: the header names the translational joint with its values,
    the printed figures its peak corner force; the joint's contacts and its corner pairs' are
    located from the solver's steps (modes.csv, run.json), and the corner-pair mode shares agree
    with the results' corner-pair mode columns to the saved grid's resolution."""
    out = tmp_path / "out"
    argv = ["run", str(EXAMPLE), "--revolutions", "0.25", "--skip-revolutions", "0"]
    assert cli.main([*argv, "--no-plots", "--no-progress", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    header = printed.splitlines()[0]
    assert "ideal joints" not in header and "slider_guide peak normal force" in printed
    assert (
        "translational clearance joint slider_guide (c = 1 mm, slider 100 x 50 mm, flores corner "
        "contact K = 1e+10, coulomb friction)" in header
    )
    info = json.loads((out / "run.json").read_text())
    shares = info["corner_pair_mode_shares"]
    assert info["status"] == "complete" and sum(shares.values()) == pytest.approx(1.0)
    assert info["contact_mode_source"].startswith("contact onsets and ends located")
    assert set(info["contact_modes"]) == {"slider_guide"}
    assert set(info["corner_pair_modes"]) == {"slider_guide.upper", "slider_guide.lower"}
    located = (out / "modes.csv").read_text().splitlines()[1:]
    channels = {row.split(",")[0] for row in located}
    assert "slider_guide" in channels and channels & {"slider_guide.upper", "slider_guide.lower"}
    npz = np.load(out / "results.npz")
    pairs = np.stack([npz["slider_guide_mode_upper"], npz["slider_guide_mode_lower"]], axis=1)
    changes = int(np.sum(np.any(pairs[1:] != pairs[:-1], axis=1)))
    names = {0.0: "free", 1.0: "impact", 2.0: "continuous"}
    for key, share in shares.items():
        upper, lower = (part.split(":")[1] for part in key.split(" "))
        count = sum((names[u], names[v]) == (upper, lower) for u, v in pairs)
        # each change of the saved labels can move a share by at most one saved interval
        assert abs(share - count / len(pairs)) <= (changes + 1) / (len(pairs) - 1)
    # the slider leaves the centre of the guide and lands on a face within the quarter revolution
    assert shares.get("slider_guide.upper:free slider_guide.lower:free", 0.0) < 1.0


# --- (iv) the unactuated Flores–Leine–Glocker slider–crank ----------------------------------------------
def flores_leine_glocker(contact_law=None):
    """Flores, Leine & Glocker (2010), Table 1: l1 = 0.153 m, l2 = 0.306 m, a = 0.05 m,
    b = 0.025 m, c = 1 mm, m1 = m2 = 0.038 kg, m3 = 0.076 kg, J1 = 7.4e-5, J2 = 5.9e-4,
    J3 = 2.7e-6 kg m², restitution 0.4, μ = 0.01, θ̇1(0) = 150 rad/s; gravity along −y."""
    law = contact_law or Flores(stiffness=1e10, restitution=0.4)
    return slider_crank(
        rpm=None,
        initial_speed=150.0,
        crank_length=0.153,
        rod_length=0.306,
        crank_mass=0.038,
        rod_mass=0.038,
        slider_mass=0.076,
        crank_inertia=7.4e-5,
        rod_inertia=5.9e-4,
        slider_inertia=2.7e-6,
        gravity=True,
        translational_clearance=dict(
            clearance=1e-3,
            half_length=0.05,
            half_height=0.025,
            contact_law=law,
            friction_law=Coulomb(friction_coefficient=0.01),
        ),
    )


def corner_restitution(out) -> np.ndarray:
    """Separation over approach speed of each single-corner contact (no other corner touching)
    with an approach faster than 1 cm/s: the approach speed is the corner's latched impact
    memory, the separation speed −δ̇ at the contact's last saved instant."""
    pen = np.asarray(out["corner_penetration"])
    rate = np.asarray(out["corner_penetration_rate"])
    memory = np.asarray(out["corner_impact_velocity"])
    contact = pen > 0
    ratios = []
    for k in range(4):
        inside = contact[:, k]
        starts = np.flatnonzero(inside[1:] & ~inside[:-1]) + 1
        ends = np.flatnonzero(~inside[1:] & inside[:-1])
        for s in starts:
            after = ends[ends >= s]
            if not len(after) or after[0] - s < 3 or contact[s : after[0] + 1].sum(1).max() > 1:
                continue  # open at the end, too short to sample, or another corner involved
            if memory[s, k] > 0.01:
                ratios.append(-rate[after[0], k] / memory[s, k])
    return np.array(ratios)


FLG_LAWS = {"flores": Flores, "lankarani-nikravesh": jaxclear.contact.LankaraniNikravesh}


@pytest.mark.slow
@pytest.mark.parametrize("law", list(FLG_LAWS))
def test_flores_leine_glocker_slider_crank(law):
    """0.2 s of the free slider–crank: the slider stays in its guide (|y/c| <= 1 plus
    penetration), flies between the faces and lands on both (one corner, then the pair: a face
    flat), and the crank keeps turning (docs/model.md §2c). The Flores law (meant for any c_e)
    returns single-corner impacts with about the restitution 0.4 that a velocity-level Newton
    law imposes; Lankarani–Nikravesh (meant for c_e near 1) far less dissipative. ``-s`` prints
    the figures of docs/model.md §2c."""
    mech = flores_leine_glocker(FLG_LAWS[law](stiffness=1e10, restitution=0.4))
    traj = jaxclear.simulate(mech, 0.2, num_points=40001, solver=SOLVER)
    out = traj.clearance["slider_guide"]
    c = 1e-3
    ratio = np.asarray(out["offset"]) / c
    tilt = np.asarray(out["tilt"])
    assert np.max(np.abs(ratio)) < 1.05
    contact = np.asarray(out["corner_penetration"]) > 0
    upper = contact[:, :2].any(axis=1)
    lower = contact[:, 2:].any(axis=1)
    free = ~contact.any(axis=1)
    assert upper.any() and lower.any() and free.any()
    assert (contact[:, :2].all(axis=1)).any() and (contact[:, 2:].all(axis=1)).any()  # faces flat
    assert (contact.sum(axis=1) == 1).any()  # one-corner impacts
    theta, speed = np.asarray(traj.q[:, 2]), np.asarray(traj.qd[:, 2])
    assert theta[-1] > 2 * np.pi  # more than one revolution
    # the peak statistics see the joint (largest corner force, from the solver's steps)
    peak = jaxclear.analysis.statistics(traj)["slider_guide_peak_normal_force"]
    assert peak >= np.max(np.asarray(out["corner_normal_force"])) > 0
    # two opposite corners on their faces tilt the slider by a sin θ = c: the largest tilt
    assert np.max(np.abs(tilt)) < 1.05 * c / A
    restitution = corner_restitution(out)
    print(
        f"{law}: {int(traj.num_steps)} steps; y/c in [{ratio.min():.4f}, {ratio.max():.4f}]; tilt "
        f"in [{tilt.min() * 1e3:.2f}, {tilt.max() * 1e3:.2f}] mrad; crank {theta[-1] / 2 / np.pi:.3f}"
        f" rev, speed {speed[0]:.1f} -> {speed[-1]:.1f} rad/s; free {free.mean():.3f}, upper face "
        f"flat {contact[:, :2].all(1).mean():.4f}, lower face flat {contact[:, 2:].all(1).mean():.4f}"
        f" of the time; {len(restitution)} single-corner impacts, separation/approach median "
        f"{np.median(restitution):.3f} ({restitution.min():.3f} .. {restitution.max():.3f}); "
        f"peak corner force {peak:.1f} N"
    )
    assert len(restitution) >= 10
    if law == "flores":
        assert 0.3 < np.median(restitution) < 0.45
    else:
        assert np.median(restitution) > 0.6


@pytest.mark.slow
def test_gradient_and_vmap_through_the_joint():
    """Forward-mode derivative of the slider's lateral offset at 4 ms (on its face by then) with
    respect to the guide clearance matches central differences; vmap over the clearance equals
    separate runs."""
    mech = slider_crank(
        rpm=RPM,
        gravity=True,
        translational_clearance=dict(
            clearance=1e-4, contact_law=Flores(stiffness=1e10, restitution=0.4)
        ),
    )
    config = jaxclear.gradient_solver(mech)

    def offset(c):
        m = eqx.tree_at(lambda m: m.translational_clearance_joints[0].clearance, mech, c)
        traj = jaxclear.simulate(
            m, 0.004, num_points=5, solver=config, adjoint="forward", extremes=False
        )
        return traj.clearance["slider_guide"]["offset"][-1]

    c0, h = jnp.asarray(1e-4), 1e-8
    derivative = jax.jacfwd(offset)(c0)
    central = (offset(c0 + h) - offset(c0 - h)) / (2 * h)
    np.testing.assert_allclose(derivative, central, rtol=1e-6)
    batch = jax.vmap(offset)(jnp.array([1e-4, 2e-4]))
    np.testing.assert_allclose(
        batch, [offset(jnp.asarray(1e-4)), offset(jnp.asarray(2e-4))], rtol=1e-9
    )


def test_ideal_mechanism_restores_the_ideal_guide():
    """``ideal_mechanism`` (the plots' reference run) turns the translational clearance joint back
    into the ideal guide it replaced: the ideal benchmark's slider position at assembly."""
    with_gap = slider_crank(translational_clearance=1e-3)
    ideal = jaxclear.ideal_mechanism(with_gap)
    assert not ideal.translational_clearance_joints
    guide = [j for j in ideal.joints if j.name == "slider_guide"]
    assert len(guide) == 1 and isinstance(guide[0], jaxclear.TranslationalJoint)
    np.testing.assert_allclose(
        np.asarray(jaxclear.assemble(ideal)),
        np.asarray(jaxclear.assemble(slider_crank())),
        atol=1e-12,
    )


@pytest.mark.slow
def test_montecarlo_over_the_guide_clearance(tmp_path, capsys):
    """``jaxclear montecarlo`` draws the guide clearance of the example: every member succeeds,
    the drawn values lie in the distribution's range, and each member's contact modes (the joint
    as a whole, located from the solver's steps) add up over the window."""
    config = tmp_path / "guide.toml"
    config.write_text(
        EXAMPLE.read_text()
        + '\n[montecarlo]\n"slider_guide.clearance" = '
        + '{ distribution = "uniform", low = 0.8e-3, high = 1.2e-3 }\n'
    )
    out = tmp_path / "mc"
    argv = ["montecarlo", str(config), "--samples", "2", "--revolutions", "0.25"]
    argv += ["--no-plots", "--no-progress", "--devices", "1", "--out", str(out)]
    assert cli.main(argv) == 0
    lines = (out / "samples.csv").read_text().splitlines()
    rows = [dict(zip(lines[0].split(","), line.split(","))) for line in lines[1:]]
    assert len(rows) == 2 and all(r["status"] == "ok" for r in rows)
    for r in rows:
        assert 0.8e-3 <= float(r["slider_guide.clearance"]) <= 1.2e-3
        assert float(r["contact_modes_located"]) == 1.0
        shares = [float(r[f"slider_guide_{m}_share"]) for m in ("free", "impact", "continuous")]
        assert sum(shares) == pytest.approx(1.0) and shares[0] < 1.0  # the slider lands
        pairs = [float(r[f"slider_guide.{p}_peak_normal_force"]) for p in ("upper", "lower")]
        assert float(r["slider_guide_peak_normal_force"]) == max(pairs) > 0.0
