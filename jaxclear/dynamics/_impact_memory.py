"""Impact-velocity memory of the smooth formulation (MODEL.md §5) [ours].

The damped contact laws need δ̇⁻, the normal approach speed at contact onset. The sharp hybrid
model latches it by an event; the smooth formulation keeps a memory m per clearance joint that
follows δ̇ in free flight and is frozen in contact:

    ṁ = w(δ) [ dδ̇/dt + k_m (δ̇ − m) ],

with w(δ) = 1 for δ <= −w_m, 0 for δ >= 0 (C¹ cubic step in between), dδ̇/dt from the same
evaluation's accelerations, dδ̇/dt = (‖ė‖² − δ̇²)/e + nᵀë = (tᵀė)²/e + nᵀë, and k_m relaxing the
offset left after separation. The law sees max(m, v_min) (smooth), so grazing contacts do not
blow the damping up. As w_m → 0 and k_m → ∞ this latches δ̇ at onset exactly.

State variable: the integrator carries the offset u = m − δ̇ instead of m (same model):

    u̇ = ṁ − dδ̇/dt = (w(δ) − 1) dδ̇/dt − w(δ) k_m u,      m = δ̇ + u.

In free flight (w = 1) this is the pure decay u̇ = −k_m u with no forcing, so u stays 0 after it
has relaxed and an exponential integrator (``jaxclear._lawson``) takes it exactly, without the
explicit stability limit h < ~3/k_m; in contact (w = 0) u̇ = −dδ̇/dt keeps m frozen. Starting
from u = 0 (m = δ̇ at t0) it is the m-form above, except that the m-form evaluates (tᵀė)²/e with
e floored at 1e-3 c where the u-form needs no floor in free flight (the floor only matters where
w < 1, i.e. at the wall).

This module is isolated so that the reconstruction can be swapped (e.g. for event-based latching).
"""

import jax.numpy as jnp

from .._smooth import smooth_max, smooth_step

ECCENTRICITY_FLOOR = 1e-3  # fraction of c below which (tᵀė)²/e is evaluated at e = 1e-3 c (the
# term is multiplied by w − 1 = 0 far from the wall; this avoids 0/0 with a centred journal)


def freeze_weight(penetration, smoothing):
    """w(δ): 1 in free flight (δ <= −w_m), 0 in contact (δ >= 0)."""
    w_m = smoothing.memory_width
    return 1.0 - smooth_step(penetration + w_m, w_m)


def memory_offset_rate(offset, penetration, eccentricity, clearance, tangential_rate, normal_accel, smoothing):
    """u̇ for one joint, u = m − δ̇.

    Args:
        offset: u, m/s. penetration: δ, m. eccentricity: e, m. clearance: c, m.
        tangential_rate: tᵀė, m/s. normal_accel: nᵀë, m/s².
    """
    e = jnp.maximum(eccentricity, ECCENTRICITY_FLOOR * clearance)
    d_rate = tangential_rate**2 / e + normal_accel
    w = freeze_weight(penetration, smoothing)
    return (w - 1.0) * d_rate - w * smoothing.memory_rate * offset


def memory_relaxation(offset, penetration, smoothing):
    """The stiff part of u̇, −w(δ) k_m u (rate k_m ≈ 1e6 1/s): a pure decay, linear and diagonal in
    u, taken implicitly by IMEX solvers and exactly by ``jaxclear._lawson``."""
    return -freeze_weight(penetration, smoothing) * smoothing.memory_rate * offset


def memory(offset, penetration_rate):
    """m = δ̇ + u, the memory of the normal approach speed, m/s."""
    return penetration_rate + offset


def impact_velocity(memory_value, smoothing):
    """δ̇⁻ seen by the contact law: max(m, v_min), smooth over a band of width v_min."""
    v_min = smoothing.min_impact_velocity
    return smooth_max(memory_value, v_min, v_min)
