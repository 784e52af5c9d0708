"""Named run statistics from the solver's steps (``Trajectory.extremes``), not the output grid.

These names are what ``jaxclear run`` writes under ``statistics`` in run.json and what ensembles
report per member, so they are defined once, here.
"""

import types

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..solve._extremes import Tracker
from ..solve._observables import observe


def statistics(traj) -> dict[str, Float[Array, "..."]]:
    """Peak and RMS values of a run over its statistics window (``simulate``'s ``statistics_start``).

    Every value comes from the solver's accepted steps (``Trajectory.extremes``), so it does not
    depend on the number of output points. Pure JAX: works on batched trajectories (each value
    then has the batch shape) and inside ``jax.jit``/``jax.grad`` (e.g. to minimise a peak
    force). ``float(v)`` gives numbers for JSON.

    Names (SI units):
        ``{J}_peak_normal_force`` (N) and ``{J}_peak_penetration`` (m) for each clearance joint J;
        ``peak_{body}_acceleration`` (m/s²): peak magnitude of each body's centre-of-mass
        acceleration (for the slider–crank's slider, its peak |ẍ|);
        ``rms_{body}_acceleration`` (m/s²): its RMS over the window (trapezoidal rule over the
        steps, as the torque's);
        ``{body}_torque_min``, ``{body}_torque_max``, ``{body}_torque_rms`` (N m): the input torque
        on the driven body (``crank_torque_*`` for the benchmark mechanisms), if there is a driver;
        ``max_constraint_violation`` (m or rad): peak max |Φ| of the ideal joints;
        ``statistics_start`` and ``statistics_duration`` (s): the window the values cover.

    Args:
        traj: a ``Trajectory`` from ``simulate`` or ``simulate_batch``.

    Returns:
        {name: value}.
    """
    x = traj.extremes
    if x is None:
        raise ValueError(
            "the trajectory has no extremes: simulate it with extremes=True (the default)."
        )
    mechanism = traj.mechanism
    out = {}
    for name in x.normal_force_max:
        out[f"{name}_peak_normal_force"] = x.normal_force_max[name]
        out[f"{name}_peak_penetration"] = x.penetration_max[name]
    for k, body in enumerate(mechanism.body_names):
        out[f"peak_{body}_acceleration"] = x.body_acceleration_max[..., k]
        out[f"rms_{body}_acceleration"] = x.body_acceleration_rms[..., k]
    if mechanism.driver is not None:
        body = mechanism.driver.body
        out[f"{body}_torque_min"] = x.input_torque_min
        out[f"{body}_torque_max"] = x.input_torque_max
        out[f"{body}_torque_rms"] = x.input_torque_rms
    out["max_constraint_violation"] = x.constraint_violation_max
    out["statistics_start"] = x.start
    out["statistics_duration"] = x.duration
    return {k: jnp.asarray(v) for k, v in out.items()}


def statistic_names(mechanism) -> list[str]:
    """The names ``statistics`` gives a run of ``mechanism``, sorted, without solving it.

    Traces one evaluation of what the solver observes at a step (no solve, nothing compiled), and
    names the extremes that observation would start, as ``statistics`` does. An ensemble uses it
    to lay out its table before its first member is solved.

    Args:
        mechanism: a ``Mechanism``.

    Returns:
        The names, sorted (the order of a ``statistics`` dict after ``jax.jit``, whose outputs
        come back with sorted keys).
    """

    def names(m):
        obs = observe(0.0, jnp.zeros(m.state_size), m)
        extremes = Tracker.first(0.0, 0.0, obs).extremes()
        return statistics(types.SimpleNamespace(extremes=extremes, mechanism=m))

    return sorted(eqx.filter_eval_shape(names, mechanism))
