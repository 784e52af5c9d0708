"""Impact-velocity memory of the smooth formulation (docs/model.md §5) [ours].

The damped contact laws need δ̇⁻, the normal approach speed at contact onset. The sharp hybrid
model latches it by an event; the smooth formulation keeps a memory m per clearance joint that
follows δ̇ in free flight and is frozen in contact:

    ṁ = w(δ) [ dδ̇/dt + k_m (δ̇ − m) ],

with w(δ) = 1 for δ <= −w_m, 0 for δ >= 0 (C¹ cubic step in between), dδ̇/dt from the same
evaluation's accelerations, dδ̇/dt = (‖ė‖² − δ̇²)/e + nᵀë = (tᵀė)²/e + nᵀë, and k_m relaxing the
offset left after separation. The law sees max(m, v_min) (smooth), so grazing contacts do not
blow the damping up. As w_m → 0 and k_m → ∞ this latches δ̇ at onset exactly.

Two state variables for the same model:
- absolute (the state everyone sees: ``Trajectory.internal_state``, ``assemble``): m itself;
- offset (used inside the solve by ``lawson-tsit5`` only): u = m − δ̇, with

    u̇ = ṁ − dδ̇/dt = (w(δ) − 1) dδ̇/dt − w(δ) k_m u,      m = δ̇ + u.

  In free flight (w = 1) this is the pure decay u̇ = −k_m u with no forcing, so an exponential
  integrator (``jaxclear.solve._lawson``) takes it exactly, without the explicit stability limit
  h < ~3/k_m; in contact (w = 0) u̇ = −dδ̇/dt keeps m frozen. The two forms differ only where
  (tᵀė)²/e is floored (e < 1e-3 c, far from the wall, where w − 1 = 0 in the offset form).
  The offset form is not the default because in contact its rows couple to the contact force
  through m (∂u̇/∂u = −∂δ̈/∂m, large for grazing contacts with small m): with the offset form as
  the state of every solver (commit d5307fd), Kvaerno5's chord iteration stalled on the three-joint
  benchmark (case b of benchmarks/bench_clearance.py --first-contact --fast-compile: NaN orbits;
  1e6 rejected steps at 0.82 ms), where the absolute form, in which ṁ = 0 in contact, ran through.

This module is isolated so that the reconstruction can be swapped (e.g. for event-based latching).
"""

import jax.numpy as jnp

from .._core._smooth import smooth_max, smooth_step

ECCENTRICITY_FLOOR = 1e-3  # fraction of c below which (tᵀė)²/e is evaluated at e = 1e-3 c (memory
# is irrelevant far from the wall; this avoids 0/0 with a centred journal)


def freeze_weight(penetration, smoothing):
    """w(δ): 1 in free flight (δ <= −w_m), 0 in contact (δ >= 0)."""
    w_m = smoothing.memory_width
    return 1.0 - smooth_step(penetration + w_m, w_m)


def memory_rate(
    memory,
    penetration,
    penetration_rate,
    eccentricity,
    clearance,
    tangential_rate,
    normal_accel,
    smoothing,
):
    """ṁ for one joint (absolute form).

    Args:
        memory: m, m/s. penetration: δ, m. penetration_rate: δ̇, m/s.
        eccentricity: e, m. clearance: c, m. tangential_rate: tᵀė, m/s.
        normal_accel: nᵀë, m/s².
    """
    e = jnp.maximum(eccentricity, ECCENTRICITY_FLOOR * clearance)
    d_rate = tangential_rate**2 / e + normal_accel
    return freeze_weight(penetration, smoothing) * (
        d_rate + smoothing.memory_rate * (penetration_rate - memory)
    )


def memory_offset_rate(
    offset, penetration, eccentricity, clearance, tangential_rate, normal_accel, smoothing
):
    """u̇ for one joint (offset form, u = m − δ̇).

    Args:
        offset: u, m/s. penetration: δ, m. eccentricity: e, m. clearance: c, m.
        tangential_rate: tᵀė, m/s. normal_accel: nᵀë, m/s².
    """
    e = jnp.maximum(eccentricity, ECCENTRICITY_FLOOR * clearance)
    d_rate = tangential_rate**2 / e + normal_accel
    w = freeze_weight(penetration, smoothing)
    return (w - 1.0) * d_rate - w * smoothing.memory_rate * offset


def memory_relaxation(state, penetration, penetration_rate, smoothing, offset: bool = False):
    """The stiff part of the rate (k_m ≈ 1e6 1/s), linear and diagonal in the state: taken implicitly
    by IMEX solvers, exactly by ``jaxclear.solve._lawson``. Absolute form w(δ) k_m (δ̇ − m); offset form
    −w(δ) k_m u, a pure decay."""
    w = freeze_weight(penetration, smoothing)
    if offset:
        return -w * smoothing.memory_rate * state
    return w * smoothing.memory_rate * (penetration_rate - state)


def memory(state, penetration_rate, offset: bool = False):
    """m, the memory of the normal approach speed (m/s), from the state (m itself or u = m − δ̇)."""
    return penetration_rate + state if offset else state


def impact_velocity(memory_value, smoothing):
    """δ̇⁻ seen by the contact law: max(m, v_min), smooth over a band of width v_min."""
    v_min = smoothing.min_impact_velocity
    return smooth_max(memory_value, v_min, v_min)
