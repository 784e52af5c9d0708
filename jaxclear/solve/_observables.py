"""What a solve reports besides its state: the per-instant outputs of a ``Trajectory``, the
observation ``ExtremesTracking`` takes at each step, the input checks made inside the compiled
solve, and the ``Trajectory`` built from them (shared by ``simulate`` and the sensitivity solve).
"""

from typing import Any

import jax
import jax.numpy as jnp

from .._core._errors import InputCheck
from ..dynamics._equations import (
    clearance_outputs,
    evaluate,
    evaluate_with_caches,
    forces_and_caches,
    implicit_stage_and_evaluation,
    solve_accelerations,
    state_rows,
)
from ..dynamics._groups import evaluation_groups
from ..model._translational_clearance import CORNER_PAIRS
from ._extremes import Observation, body_accelerations
from ._trajectory import Trajectory

ASSEMBLY_TOLERANCE = 1e-7  # m: residual above which a jitted/batched assembly is an error


def outputs(mechanism, t, y) -> dict[str, Any]:
    ev = evaluate(mechanism, t, y)
    lam = ev.multipliers
    slices = mechanism.constraint_slices
    if mechanism.driver is not None:
        torque = -lam[slices[mechanism.driver.name]][0]
    else:
        torque = jnp.zeros((), y.dtype)
    reactions = {j.name: lam[slices[j.name]] for j in mechanism.joints}
    clearance = clearance_outputs(mechanism, ev)
    phi, phid = ev.phi, ev.phi_dot
    viol = jnp.max(jnp.abs(phi), initial=0.0)
    vviol = jnp.max(jnp.abs(phid), initial=0.0)
    n = mechanism.num_coordinates
    return dict(
        qdd=ev.qdd,
        internal_state=y[2 * n :],
        multipliers=lam,
        input_torque=torque,
        reactions=reactions,
        clearance=clearance,
        constraint_violation=viol,
        velocity_violation=vviol,
    )


def input_error(mechanism, y0, assembled_ok):
    """Code of the first failed input check (``InputCheck``), ``InputCheck.PASSED`` if none."""
    masses = mechanism.mass_diagonal
    return jnp.select(
        [~assembled_ok, jnp.any(~(masses > 0) | ~jnp.isfinite(masses)), jnp.any(~jnp.isfinite(y0))],
        [InputCheck.NOT_ASSEMBLED, InputCheck.MASS_OR_INERTIA, InputCheck.STATE_NOT_FINITE],
        InputCheck.PASSED,
    ).astype(jnp.int32)


def _largest(x):
    """A scalar as it is; the largest entry of a per-corner array."""
    return x if jnp.ndim(x) == 0 else jnp.max(x)


def observe(t, y, mechanism) -> Observation:
    """What ``ExtremesTracking`` records at the end of each step (``jaxclear.solve._extremes``).

    The part of the right-hand side the extremes need, no more: forces (keeping each clearance
    joint's kinematics and contact forces from the same pass) and accelerations, without the
    internal-state rates or a second contact evaluation.
    """
    q, qd, states = mechanism.split_state(y)
    forces, caches = forces_and_caches(mechanism, t, q, qd, states)
    qdd, lam, phi, _ = solve_accelerations(mechanism, t, q, qd, forces)
    return _observation(mechanism, caches, qdd, lam, phi)


def field_and_observation(t, y, mechanism, gamma_h=None) -> tuple[Any, Observation]:
    """(dy/dt, ``Observation``) at (t, y) from one evaluation of the right-hand side: the vector
    field of ``dynamics._equations.vector_field`` (the same operations) and what ``observe``
    returns, from the same forces, multipliers and contact caches (``ExtremesTracking`` lets
    the observation ride along the solver's stages, ``jaxclear.solve._extremes``).

    With ``gamma_h`` (γh), an IMEX stage of ``AffineKenCarp`` instead: y is the stage's partial
    sum P, and the result ((Y, f(Y), f_I(Y)), the ``Observation`` at Y), the first part that of
    ``dynamics._equations.implicit_stage`` (the same operations)."""
    if gamma_h is not None:
        stage, ev, caches = implicit_stage_and_evaluation(t, y, gamma_h, mechanism)
        return stage, _observation(mechanism, caches, ev.qdd, ev.multipliers, ev.phi)
    q, qd, states = mechanism.split_state(y)
    ev, caches = evaluate_with_caches(mechanism, t, q, qd, states)
    dy = state_rows(mechanism, (ev.qd, ev.qdd), ev.state_rates, y.dtype)
    return dy, _observation(mechanism, caches, ev.qdd, ev.multipliers, ev.phi)


def _observation(mechanism, caches, qdd, lam, phi) -> Observation:
    normal_force, penetration = {}, {}
    for group, cache in zip(evaluation_groups(mechanism), caches):
        for name, (kinematics, contact) in group.contacts(cache).items():
            # a translational clearance joint has one value per corner: its entry is the largest,
            # and each corner pair (the two corners that face one guide face) is a channel of its
            # own, "<joint>.upper" and "<joint>.lower", so that its contacts are located too
            normal_force[name] = _largest(contact.normal_force)
            penetration[name] = _largest(kinematics.penetration)
            if jnp.ndim(kinematics.penetration) == 1:
                for pair, corners in CORNER_PAIRS.items():
                    channel = f"{name}.{pair}"
                    normal_force[channel] = jnp.max(contact.normal_force[corners])
                    penetration[channel] = jnp.max(kinematics.penetration[corners])
    if mechanism.driver is not None:
        torque = -lam[mechanism.constraint_slices[mechanism.driver.name]][0]
    else:
        torque = jnp.zeros((), qdd.dtype)
    return Observation(
        accelerations=qdd,
        body_accelerations=body_accelerations(qdd),
        input_torque=torque,
        normal_force=normal_force,
        penetration=penetration,
        constraint_violation=jnp.max(jnp.abs(phi), initial=0.0),
    )


def make_trajectory(
    mechanism, ts, ys, y_final, extremes, stats, result, error, t_final
) -> Trajectory:
    """The ``Trajectory`` of a solve from its saved states ``ys`` (on ``ts``) and final state.

    ``stats``: diffrax's ``num_steps``, ``num_accepted_steps``, ``num_rejected_steps``.
    """
    n = mechanism.num_coordinates
    out = jax.vmap(lambda t, y: outputs(mechanism, t, y))(ts, ys)
    return Trajectory(
        t=ts,
        q=ys[:, :n],
        qd=ys[:, n : 2 * n],
        qdd=out["qdd"],
        internal_state=out["internal_state"],
        multipliers=out["multipliers"],
        input_torque=out["input_torque"],
        reactions=out["reactions"],
        constraint_violation=out["constraint_violation"],
        velocity_violation=out["velocity_violation"],
        clearance=out["clearance"],
        extremes=extremes,
        num_steps=stats["num_steps"],
        num_accepted_steps=stats["num_accepted_steps"],
        num_rejected_steps=stats["num_rejected_steps"],
        result=result,
        input_error=error,
        t_final=t_final,
        y_final=y_final,
        mechanism=mechanism,
    )
