"""Mechanical energy bookkeeping: kinetic, potential, drive work."""

import jax
import jax.numpy as jnp
import numpy as np


def kinetic_energy(traj):
    """T = ½ q̇ᵀ M q̇ at each saved instant, J."""
    m = traj.mechanism.mass_diagonal
    m = jnp.reshape(m, (1,) * (traj.qd.ndim - 1) + m.shape)
    return 0.5 * jnp.sum(m * traj.qd**2, axis=-1)


def potential_energy(traj):
    """Gravitational plus spring potential at each saved instant, J (zero at the origin)."""
    mech = traj.mechanism
    masses = jnp.stack([b.mass for b in mech.bodies])
    pos = jnp.reshape(traj.q, traj.q.shape[:-1] + (len(mech.bodies), 3))[..., :2]
    g = jnp.reshape(mech.gravity, (1,) * (pos.ndim - 1) + (2,))
    masses = jnp.reshape(masses, (1,) * (pos.ndim - 2) + masses.shape)
    grav = -jnp.sum(masses * jnp.sum(pos * g, axis=-1), axis=-1)
    springs = jnp.zeros_like(grav)
    q = jnp.reshape(traj.q, (-1, traj.q.shape[-1]))
    for f in (
        mech.forces
    ):  # AbstractForceElement.potential_energy: zero unless the element stores energy
        energy = jax.vmap(lambda qq, f=f: f.potential_energy(mech.index, qq))(q)
        springs = springs + jnp.reshape(energy, springs.shape)
    return grav + springs


def drive_power(traj):
    """Power the driver delivers, τ · (θ̇_body − θ̇_reference), W."""
    mech = traj.mechanism
    if mech.driver is None:
        return jnp.zeros_like(traj.t)
    d = mech.driver
    rate = traj.velocities(d.body)[..., 2]
    if d.relative_to != "ground":
        rate = rate - traj.velocities(d.relative_to)[..., 2]
    return traj.input_torque * rate


def drive_work(traj):
    """Cumulative drive work from the first saved instant (trapezoid rule on the output grid), J.

    Accurate only when the output grid resolves the torque (impacts need fine grids).
    """
    p = np.asarray(drive_power(traj))
    t = np.asarray(traj.t)
    increments = 0.5 * (p[1:] + p[:-1]) * np.diff(t)
    return np.concatenate([[0.0], np.cumsum(increments)])
