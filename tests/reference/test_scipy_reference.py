"""Self-checks of the independent SciPy reference (tests/reference/scipy_slider_crank.py)."""

import pytest

from .scipy_slider_crank import (
    check_energy,
    check_ideal,
    check_small_clearance,
    check_smooth_vs_sharp,
    ideal_closed_form,
)


def test_closed_form_dead_centres():
    import numpy as np

    w = 5000 * np.pi / 30
    cf = ideal_closed_form(np.array([0.0, np.pi]), w)
    assert np.allclose(cf["x"], [0.17, 0.07]) and np.allclose(cf["v"], 0.0, atol=1e-12)
    assert np.isclose(cf["a"][0], -(w**2) * (0.05 + 0.05**2 / 0.12))


def test_ideal_matches_model_md():
    check_ideal()  # §6 numbers, closed form, torque sign by the energy balance


def test_energy_balance_sharp_short():
    check_energy(mode="sharp", revolutions=0.25)


def test_smooth_vs_sharp_first_half_ms():
    check_smooth_vs_sharp(t_end=0.5e-3)


@pytest.mark.slow
def test_energy_balance_smooth_radau():
    check_energy(mode="smooth", method="Radau", rtol=1e-8)


@pytest.mark.slow
def test_friction_dissipates():
    check_energy(friction=("coulomb", 0.1, 1e-4))


@pytest.mark.slow
def test_small_clearance_approaches_ideal():
    check_small_clearance()


@pytest.mark.slow
def test_smooth_vs_sharp_2ms():
    check_smooth_vs_sharp()
