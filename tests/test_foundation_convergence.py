"""Discretised elastic-foundation laws converge to the closed form (docs/model.md §3).

Both the element sum (:class:`ElasticFoundationDiscrete`, midpoint rule) and the paper's hybrid law
with damping off (c_e = 1, so each element force is K_i δ_i) must approach
``F_N = K_EF (R h/L)(e θ_c − c sin θ_c)`` as the number of elements m2 grows.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import contact_kinematics

from jaxclear.contact import (
    ContactGeometry,
    ElasticFoundation,
    ElasticFoundationDiscrete,
    Hybrid,
    Smoothing,
)

GEOMETRY = ContactGeometry(0.01, 0.0095)  # benchmark joint
SMOOTHING = Smoothing()
PENETRATIONS = jnp.asarray([1e-6, 5e-6, 2e-5, 5e-5])  # m
ELEMENT_COUNTS = [2, 4, 8, 16, 32, 64]
# At m2 = 64 both discretisations are within ~1.2e-4 of the closed form (the midpoint rule's error
# is ≈ 1/(2 m2²), the hybrid's Gauss points make it ~20 times smaller); the midpoint rule only gets
# below 1e-3 from m2 = 32 on.
FINAL_RTOL = 1e-3
# Second-order convergence: halving the element angle divides the error by about 4.
MIN_ERROR_RATIO = 3.0


@eqx.filter_jit
def _normal_forces(law, penetrations):
    def one(delta):
        return law(contact_kinematics(delta, 0.0, 0.5), GEOMETRY, SMOOTHING)[0]

    return eqx.filter_vmap(one)(penetrations)


@pytest.fixture(scope="module")
def closed_form():
    return np.asarray(_normal_forces(ElasticFoundation(restitution=1.0), PENETRATIONS))


@pytest.mark.parametrize(
    "make",
    [
        lambda m2: ElasticFoundationDiscrete(restitution=1.0, num_elements=m2),
        lambda m2: Hybrid(restitution=1.0, num_elements=m2),
    ],
    ids=["discrete", "hybrid"],
)
def test_converges_to_closed_form(make, closed_form):
    errors = np.stack(
        [
            np.abs(np.asarray(_normal_forces(make(m2), PENETRATIONS)) / closed_form - 1.0)
            for m2 in ELEMENT_COUNTS
        ]
    )  # (len(ELEMENT_COUNTS), len(PENETRATIONS))
    for m2, row in zip(ELEMENT_COUNTS, errors):
        print(f"m2={m2:3d} relative errors " + " ".join(f"{e:.2e}" for e in row))
    assert np.all(np.diff(errors, axis=0) < 0.0)  # strictly decreasing for every δ
    assert np.all(errors[-1] < FINAL_RTOL)
    ratios = errors[-3:-1] / errors[-2:]  # from m2 = 16 on
    assert np.all(ratios > MIN_ERROR_RATIO)
