"""Contact modes of clearance joints: free flight, impact, continuous contact (docs/model.md §7) [ours].

A saved instant is *in contact* when the penetration is positive. Maximal runs of consecutive
contact instants are *continuous contact* when the run lasts at least ``continuous_fraction`` of
the crank period (or of ``reference_period``), else *impact*. Labels come from the saved grid: a
contact shorter than the output interval that falls between two samples is not seen, so use a
fine output grid (``points_per_revolution``) when counting impacts.
"""

import itertools

import numpy as np

from ..model._translational_clearance import CORNER_PAIRS

FREE, IMPACT, CONTINUOUS = 0, 1, 2
MODE_NAMES = {FREE: "free", IMPACT: "impact", CONTINUOUS: "continuous"}
DEFAULT_CONTINUOUS_FRACTION = (
    0.02  # contact lasting >= 2 % of a crank period is continuous (the literature's rule)
)


def grid_contacts(t, penetration, minimum_duration: float) -> dict[str, np.ndarray]:
    """One joint's contacts from saved instants: maximal runs of instants with δ > 0.

    The fallback where located events are missing (``contact_events``): a run starting at
    sample i and ending at sample k lasts t_k − t_i + Δt (Δt the median spacing), ends at
    min(t_k + Δt, last instant); a contact between two samples is not seen.

    Args:
        t: saved times (N,), s.
        penetration: δ at those times (N,), m.
        minimum_duration: contact runs lasting at least this long (s) are continuous contact.

    Returns:
        ``{"onset", "end", "duration", "mode", "first", "last"}``: arrays over the runs (``first``
        and ``last`` are the runs' sample indices).
    """
    t = np.asarray(t, dtype=float)
    inside = np.asarray(penetration) > 0.0
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    edges = np.diff(np.concatenate([[0], inside.astype(int), [0]]))
    first, last = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    duration = t[last] - t[first] + dt
    return {
        "onset": t[first],
        "end": np.minimum(t[last] + dt, t[-1]) if t.size else t[last],
        "duration": duration,
        "mode": np.where(duration >= minimum_duration, CONTINUOUS, IMPACT),
        "first": first,
        "last": last,
    }


def contact_modes(t, penetration, minimum_duration: float) -> np.ndarray:
    """Mode label (0 free, 1 impact, 2 continuous) per saved instant for one joint
    (the runs of ``grid_contacts``).

    Args:
        t: saved times (N,), s.
        penetration: δ at those times (N,), m.
        minimum_duration: contact runs lasting at least this long (s) are continuous contact.
    """
    runs = grid_contacts(t, penetration, minimum_duration)
    labels = np.zeros(np.shape(t), dtype=int)
    for a, b, mode in zip(runs["first"], runs["last"], runs["mode"]):
        labels[a : b + 1] = mode
    return labels


def contact_joints(mechanism) -> list[str]:
    """The joints whose contact modes combine (``event_mode_shares``, ensembles, revolutions):
    the revolute clearance joints, then the translational clearance joints (each as a whole, in
    contact when one of its corners is), in the mechanism's order."""
    return [j.name for j in mechanism.clearance_joints] + [
        j.name for j in mechanism.translational_clearance_joints
    ]


def corner_pair_channels(mechanism) -> list[str]:
    """The corner pairs of the translational clearance joints, ``<J>.upper`` and ``<J>.lower``
    (``jaxclear.model.CORNER_PAIRS``), whose contacts are recorded beside the joint's own."""
    return [
        f"{j.name}.{pair}"
        for j in mechanism.translational_clearance_joints
        for pair in CORNER_PAIRS
    ]


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


# --- contact modes from located events (independent of the output grid) ---------------------------

EVENT_CONTINUOUS_FRACTION = 0.02
"""Contact lasting at least 2 % of the crank period is continuous contact, shorter contact an
impact: the rule of the literature (issue 12; Ma & Qian 2017 classify by contact duration)."""


def contact_events(
    traj,
    *,
    continuous_fraction: float = EVENT_CONTINUOUS_FRACTION,
    reference_period: float | None = None,
    start: float | None = None,
) -> dict[str, dict[str, np.ndarray]]:
    """Each clearance joint's contacts, located from the solver's steps (not the output grid).

    Needs a trajectory simulated with ``contact_events=K`` (``jaxclear.simulate``): onsets and
    ends are where the penetration changes sign between the solver's samples (two per step), by
    linear interpolation, so a contact shorter than the output interval is still seen.

    Args:
        traj: an unbatched ``Trajectory`` with recorded contact events.
        continuous_fraction: contact lasting at least this fraction of the crank period is
            continuous contact, shorter an impact (default 2 %).
        reference_period: the period the fraction refers to, s (default the crank period, or the
            run's duration without a constant-speed driver).
        start: keep contacts that end after this time, s (default the statistics window's start);
            a contact in progress at ``start`` is cut there.

    Returns:
        ``{joint: {"onset", "end", "duration", "mode", "finished"}}``: arrays over the contacts in
        time order; ``mode`` is ``IMPACT`` (1) or ``CONTINUOUS`` (2); a contact in progress at the
        end of the run has ``finished`` False and ends at the run's end time (its mode is what its
        duration so far says).

    Raises:
        ValueError: no recorded events, a batched trajectory, or an overflowing buffer (the message
            says which joint and how many contacts there were).
    """
    x = traj.extremes
    if x is None or not x.events or next(iter(x.events.values())).shape[-2] == 0:
        raise ValueError(
            "the trajectory has no recorded contact events: simulate with contact_events=K "
            "(e.g. 4096) and extremes=True."
        )
    if np.ndim(traj.t_final) != 0:
        raise ValueError("contact_events takes one trajectory; index a batched one first.")
    period = reference_period or crank_period(traj.mechanism) or float(traj.t[-1] - traj.t[0])
    t_start = float(x.start) if start is None else float(start)
    out = {}
    for joint, buffer in x.events.items():
        count, room = int(x.event_count[joint]), buffer.shape[0]
        if count > room:
            raise ValueError(
                f"joint {joint} had {count} contacts, more than the {room} recorded: simulate "
                f"with contact_events >= {count}."
            )
        out[joint] = located_contacts(
            buffer,
            count,
            x.contact_onset[joint],
            t_start,
            float(traj.t_final),
            continuous_fraction * period,
        )
    return out


def located_contacts(
    buffer, count: int, ongoing, t_start: float, t_end: float, threshold: float
) -> dict[str, np.ndarray]:
    """One joint's contacts from the recorded event buffer (``Extremes.events``), as in
    ``contact_events``.

    Args:
        buffer: (K, 2) onset and end times of finished contacts, s (the first ``count`` rows used).
        count: finished contacts (at most K).
        ongoing: onset of a contact in progress at ``t_end``, s (NaN if none).
        t_start: keep contacts that end after this time; one in progress then is cut there, s.
        t_end: end of the run, s.
        threshold: contacts lasting at least this long are continuous contact, shorter an impact, s.
    """
    events = np.asarray(buffer)[:count]
    onset, end = events[:, 0], events[:, 1]
    finished = np.ones(count, dtype=bool)
    ongoing = float(ongoing)
    if np.isfinite(ongoing):
        onset = np.append(onset, ongoing)
        end = np.append(end, t_end)
        finished = np.append(finished, False)
    duration = end - onset  # the whole contact decides its mode, also when cut at start
    keep = end > t_start
    return {
        "onset": np.maximum(onset[keep], t_start),
        "end": end[keep],
        "duration": duration[keep],
        "mode": np.where(duration[keep] >= threshold, CONTINUOUS, IMPACT),
        "finished": finished[keep],
    }


def event_mode_shares(
    traj,
    *,
    continuous_fraction: float = EVENT_CONTINUOUS_FRACTION,
    reference_period: float | None = None,
    start: float | None = None,
) -> dict:
    """Time shares and counts of the contact modes from located events (``contact_events``).

    Returns:
        ``{"joints": {joint: {"free", "impact", "continuous": time share; "impacts",
        "continuous_contacts": counts}}, "combinations": {"O:free A:impact B:continuous": share},
        "labels": {"F-I-C": share}}`` over [start, end of the run]; the combinations are those of
        all clearance joints at once (3ⁿ possible, only those that occur are listed), in the
        order of ``contact_joints`` (revolute clearance joints, then translational ones, each in
        contact when one of its corners is); ``labels`` are the same shares under the short labels
        of ``combination_label`` (F free flight, I impact, C continuous contact). With
        translational clearance joints, ``"corner_pairs"`` holds the same entries for their corner
        pairs (``<J>.upper``, ``<J>.lower``: in contact when one of the pair's corners is).
    """
    events = contact_events(
        traj,
        continuous_fraction=continuous_fraction,
        reference_period=reference_period,
        start=start,
    )
    x = traj.extremes
    t_start = float(x.start) if start is None else float(start)
    order = [j for j in contact_joints(traj.mechanism) if j in events]
    shares = shares_of_contacts(events, order, t_start, float(traj.t_final))
    pairs = [c for c in corner_pair_channels(traj.mechanism) if c in events]
    if pairs:
        shares["corner_pairs"] = shares_of_contacts(events, pairs, t_start, float(traj.t_final))
    return shares


MODE_LETTERS = {FREE: "F", IMPACT: "I", CONTINUOUS: "C"}
"""One-letter mode names of a combination label: ``C-I-F`` is O in continuous contact, A in an
impact and B in free flight (joints in the mechanism's order)."""


def combination_label(modes) -> str:
    """Short label of a combination of joint modes, e.g. ``(2, 1, 0)`` -> ``"C-I-F"``."""
    return "-".join(MODE_LETTERS[int(m)] for m in modes)


def all_combinations(count: int) -> list[str]:
    """The 3ⁿ combination labels of ``count`` joints, free flight first (``F-F-F``, ``F-F-I``, ...)."""
    return [
        combination_label(k) for k in itertools.product((FREE, IMPACT, CONTINUOUS), repeat=count)
    ]


def shares_of_contacts(events: dict, order, t_start: float, t_end: float) -> dict:
    """``event_mode_shares`` of contacts already located (``contact_events``/``located_contacts``).

    Args:
        events: ``{joint: contacts}`` as ``contact_events`` returns.
        order: the joints, in the mechanism's order (the order of a combination's modes).
        t_start, t_end: the window, s.
    """
    span = t_end - t_start
    joints = {}
    cuts = {t_start, t_end}
    for j in order:
        e = events[j]
        share = {
            MODE_NAMES[m]: float(np.sum((e["end"] - e["onset"])[e["mode"] == m]) / span)
            for m in (IMPACT, CONTINUOUS)
        }
        share["free"] = 1.0 - share["impact"] - share["continuous"]
        share["impacts"] = int(np.sum(e["mode"] == IMPACT))
        share["continuous_contacts"] = int(np.sum(e["mode"] == CONTINUOUS))
        joints[j] = share
        cuts.update(e["onset"].tolist())
        cuts.update(e["end"].tolist())
    points = np.array(sorted(c for c in cuts if t_start <= c <= t_end))
    mids = 0.5 * (points[1:] + points[:-1])
    widths = np.diff(points)
    combos: dict[str, float] = {}
    short: dict[str, float] = {}
    if order:
        labels = []
        for j in order:
            e = events[j]
            label = np.full(mids.shape, FREE)
            for onset, end, mode in zip(e["onset"], e["end"], e["mode"]):
                label[(mids > onset) & (mids < end)] = mode
            labels.append(label)
        stacked = np.stack(labels, axis=-1)
        for key in np.unique(stacked, axis=0):
            inside = np.all(stacked == key, axis=-1)
            name = " ".join(f"{n}:{MODE_NAMES[int(k)]}" for n, k in zip(order, key))
            combos[name] = float(np.sum(widths[inside]) / span)
            short[combination_label(key)] = combos[name]
    return {"joints": joints, "combinations": combos, "labels": short}
