"""Contact modes of clearance joints: free flight, impact, continuous contact (docs/model.md §7) [ours].

A saved instant is *in contact* when the penetration is positive. Maximal runs of consecutive
contact instants are *continuous contact* when the run lasts at least ``continuous_fraction`` of
the crank period (or of ``reference_period``), else *impact*. Labels come from the saved grid: a
contact shorter than the output interval that falls between two samples is not seen, so use a
fine output grid (``points_per_revolution``) when counting impacts.
"""

import itertools

import numpy as np

FREE, IMPACT, CONTINUOUS = 0, 1, 2
MODE_NAMES = {FREE: "free", IMPACT: "impact", CONTINUOUS: "continuous"}
DEFAULT_CONTINUOUS_FRACTION = 0.05  # [ours] contact lasting >= 5 % of a crank period is continuous


def contact_modes(t, penetration, minimum_duration: float) -> np.ndarray:
    """Mode label (0 free, 1 impact, 2 continuous) per saved instant for one joint.

    Args:
        t: saved times (N,), s.
        penetration: δ at those times (N,), m.
        minimum_duration: contact runs lasting at least this long (s) are continuous contact.
    """
    t = np.asarray(t)
    contact = np.asarray(penetration) > 0.0
    labels = np.zeros(t.shape, dtype=int)
    dt = np.median(np.diff(t)) if t.size > 1 else 0.0
    start = 0
    for is_contact, group in itertools.groupby(contact):
        n = len(list(group))
        if is_contact:
            duration = t[start + n - 1] - t[start] + dt
            labels[start : start + n] = CONTINUOUS if duration >= minimum_duration else IMPACT
        start += n
    return labels


def crank_period(mechanism) -> float | None:
    """Period of a constant-speed driver, s (``None`` if not constant speed)."""
    speed = None if mechanism.driver is None else mechanism.driver.constant_speed
    if speed is None or float(speed) == 0.0:
        return None
    return float(2 * np.pi / abs(float(speed)))


def trajectory_modes(
    traj, continuous_fraction: float = DEFAULT_CONTINUOUS_FRACTION, reference_period=None
) -> dict:
    """Mode labels per clearance joint: ``{joint name: (N,) int array}``."""
    period = reference_period or crank_period(traj.mechanism) or float(traj.t[-1] - traj.t[0])
    return {
        name: contact_modes(traj.t, out["penetration"], continuous_fraction * period)
        for name, out in traj.clearance.items()
    }


def combination_shares(modes: dict) -> dict:
    """Time share of each combination of joint modes, e.g. ``{"O:free A:impact B:continuous": 0.12}``.

    With three joints there are 3³ = 27 possible combinations (docs/model.md §7).
    """
    names = list(modes)
    if not names:
        return {}
    stacked = np.stack([modes[n] for n in names], axis=-1)
    keys, counts = np.unique(stacked, axis=0, return_counts=True)
    total = counts.sum()
    return {
        " ".join(f"{n}:{MODE_NAMES[int(k)]}" for n, k in zip(names, key)): float(c / total)
        for key, c in zip(keys, counts)
    }
