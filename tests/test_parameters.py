"""Named mechanism parameters: jaxclear.parameter_names / get_parameter / with_parameters."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear
from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import LuGre, ModifiedCoulomb


@pytest.fixture(scope="module")
def mechanism():
    return jaxclear.mechanisms.slider_crank(
        rpm=5000.0,
        clearance_joints={"A": {}, "B": {"journal_body": "rod"}},
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(friction_coefficient=0.01),
    )


def test_names_cover_bodies_joints_laws_and_driver(mechanism):
    names = jaxclear.parameter_names(mechanism)
    for name in (
        "rod_mass",
        "slider_inertia",
        "crank_com_x",
        "rpm",
        "A.clearance",
        "B.clearance",
        "B.restitution",
        "B.friction_coefficient",
        "B.young_modulus",
        "B.memory_rate",
        "baumgarte_alpha",
    ):
        assert name in names
    assert "O.clearance" not in names  # O is an ideal joint here
    lugre = jaxclear.mechanisms.slider_crank(clearance_joints="B", friction_law=LuGre())
    assert "B.bristle_stiffness" in jaxclear.parameter_names(lugre)


def test_values_round_trip(mechanism):
    values = {
        "B.clearance": 3e-4,
        "rod_mass": 0.25,
        "rpm": 200.0,
        "B.young_modulus": 1e11,
        "A.restitution": 0.7,
        "B.friction_coefficient": 0.05,
    }
    changed = jaxclear.with_parameters(mechanism, values)
    for name, value in values.items():
        assert float(jaxclear.get_parameter(changed, name)) == pytest.approx(value, rel=1e-12)
    assert float(changed.driver.speed) == pytest.approx(200.0 * math.pi / 30.0)
    assert float(jaxclear.get_parameter(changed, "B.bearing_radius")) == pytest.approx(0.01)
    assert float(jaxclear.get_parameter(changed, "B.journal_young")) == 1e11
    assert float(jaxclear.get_parameter(changed, "B.bearing_young")) == 1e11
    # the original is untouched (pure)
    assert float(jaxclear.get_parameter(mechanism, "B.clearance")) == pytest.approx(5e-4)
    assert float(jaxclear.get_parameter(mechanism, "rod_mass")) == 0.21


def test_centre_of_mass_shift_keeps_attachment_points(mechanism):
    """Moving the rod's centre of mass by d along its axis moves its points by -d in body frame,
    so the joints sit where they were in the world."""
    d = 0.01
    shifted = jaxclear.with_parameters(mechanism, {"rod_com_x": d})
    a_before = np.asarray(mechanism.clearance_joints[0].journal_point)  # A: pin on the rod
    a_after = np.asarray(shifted.clearance_joints[0].journal_point)
    np.testing.assert_allclose(a_after, a_before - [d, 0.0])
    b_after = np.asarray(shifted.clearance_joints[1].journal_point)  # B: pin on the rod
    np.testing.assert_allclose(
        b_after, np.asarray(mechanism.clearance_joints[1].journal_point) - [d, 0.0]
    )
    np.testing.assert_allclose(
        np.asarray(shifted.bodies[1].position[:2]),
        np.asarray(mechanism.bodies[1].position[:2]) + [d, 0.0],
    )


def test_traceable_under_jit_grad_vmap(mechanism):
    def journal_radius(c):
        changed = jaxclear.with_parameters(mechanism, {"B.clearance": c})
        return jaxclear.get_parameter(changed, "B.journal_radius")

    assert float(jax.jit(jax.grad(journal_radius))(3e-4)) == -1.0
    radii = jax.vmap(journal_radius)(jnp.array([1e-4, 2e-4]))
    np.testing.assert_allclose(np.asarray(radii), [0.01 - 1e-4, 0.01 - 2e-4])


def test_unknown_name_suggests_close_match(mechanism):
    with pytest.raises(
        jaxclear.ModelError, match=r"unknown parameter 'B.clearence'; did you mean 'B.clearance'"
    ):
        jaxclear.with_parameters(mechanism, {"B.clearence": 1e-4})
    # an ideal joint: said so, with how to give it a clearance (was "unknown parameter", issue 28)
    with pytest.raises(
        jaxclear.ModelError,
        match=r"joint 'O' is an ideal revolute joint and has no clearance.*clearance_joints='A,B,O'",
    ):
        jaxclear.get_parameter(mechanism, "O.clearance")
    with pytest.raises(jaxclear.ModelError, match="unknown parameter 'C.clearance'"):
        jaxclear.get_parameter(mechanism, "C.clearance")


def test_info_units_and_domains(mechanism):
    info = jaxclear.parameter_info(mechanism, "B.clearance")
    assert info.unit == "m" and info.domain == (0.0, pytest.approx(0.01))
    assert jaxclear.parameter_info(mechanism, "B.restitution").domain == (0.0, 1.0)
    assert jaxclear.parameter_info(mechanism, "rod_mass").domain == (0.0, math.inf)
