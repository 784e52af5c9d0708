"""Mechanisms several test modules share (one definition, so that their compiled solves match)."""

from jaxclear.contact import LankaraniNikravesh
from jaxclear.friction import ModifiedCoulomb
from jaxclear.mechanisms import slider_crank


def one_joint_b():
    """Case a of the benchmarks without gravity: clearance joint B (0.5 mm), Lankarani–Nikravesh
    with restitution 0.9, modified Coulomb μ = 0.01, 5000 rpm."""
    return slider_crank(
        rpm=5000.0,
        clearance_joints="B",
        clearance=5e-4,
        contact_law=LankaraniNikravesh(restitution=0.9),
        friction_law=ModifiedCoulomb(0.01),
        gravity=False,
    )
