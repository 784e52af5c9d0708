"""Impact-velocity memory of the smooth formulation (MODEL.md §5) [ours].

The damped contact laws need δ̇⁻, the normal approach speed at contact onset. The sharp hybrid
model latches it by an event; the smooth formulation keeps it in an internal state m per clearance
joint that follows δ̇ in free flight and is frozen in contact:

    ṁ = w(δ) [ dδ̇/dt + k_m (δ̇ − m) ],

with w(δ) = 1 for δ <= −w_m, 0 for δ >= 0 (C¹ cubic step in between), dδ̇/dt from the same
evaluation's accelerations, dδ̇/dt = (‖ė‖² − δ̇²)/e + nᵀë = (tᵀė)²/e + nᵀë, and k_m relaxing the
offset left after separation. The law sees max(m, v_min) (smooth), so grazing contacts do not
blow the damping up. As w_m → 0 and k_m → ∞ this latches δ̇ at onset exactly.

This module is isolated so that the reconstruction can be swapped (e.g. for event-based latching).
"""

import jax.numpy as jnp

from .._smooth import smooth_max, smooth_step

ECCENTRICITY_FLOOR = 1e-3  # fraction of c below which (tᵀė)²/e is evaluated at e = 1e-3 c (memory
# is irrelevant far from the wall; this avoids 0/0 with a centred journal)


def freeze_weight(penetration, smoothing):
    """w(δ): 1 in free flight (δ <= −w_m), 0 in contact (δ >= 0)."""
    w_m = smoothing.memory_width
    return 1.0 - smooth_step(penetration + w_m, w_m)


def memory_rate(memory, penetration, penetration_rate, eccentricity, clearance, tangential_rate, normal_accel, smoothing):
    """ṁ for one joint.

    Args:
        memory: m, m/s. penetration: δ, m. penetration_rate: δ̇, m/s.
        eccentricity: e, m. clearance: c, m. tangential_rate: tᵀė, m/s.
        normal_accel: nᵀë, m/s².
    """
    e = jnp.maximum(eccentricity, ECCENTRICITY_FLOOR * clearance)
    d_rate = tangential_rate**2 / e + normal_accel
    return freeze_weight(penetration, smoothing) * (d_rate + smoothing.memory_rate * (penetration_rate - memory))


def memory_relaxation(memory, penetration, penetration_rate, smoothing):
    """The stiff part of ṁ, w(δ) k_m (δ̇ − m) (rate k_m ≈ 1e6 1/s): implicit in IMEX solvers."""
    return freeze_weight(penetration, smoothing) * smoothing.memory_rate * (penetration_rate - memory)


def impact_velocity(memory, smoothing):
    """δ̇⁻ seen by the contact law: max(m, v_min), smooth over a band of width v_min."""
    v_min = smoothing.min_impact_velocity
    return smooth_max(memory, v_min, v_min)
