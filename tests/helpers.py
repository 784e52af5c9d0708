"""Shared test utilities (after lineax/tests/helpers.py)."""

import contextlib
import os

import equinox as eqx
import jax
import jax.numpy as jnp
import jaxtyping
import numpy as np

NUM_POINTS = 4001
"""Output grid size shared by the simulation tests: ``simulate`` compiles once per mechanism
topology, solver config and number of output points, so using one size everywhere lets the test
modules of one pytest process reuse each other's compiled solves."""


def tree_allclose(x, y, *, rtol=1e-5, atol=1e-8):
    """True if two pytrees have the same structure and all array leaves are close."""
    x_arr, x_static = eqx.partition(x, eqx.is_array)
    y_arr, y_static = eqx.partition(y, eqx.is_array)
    if jax.tree_util.tree_structure(x_arr) != jax.tree_util.tree_structure(y_arr):
        return False
    if jax.tree_util.tree_structure(x_static) != jax.tree_util.tree_structure(y_static):
        return False
    if x_static != y_static:
        return False
    leaves = zip(jax.tree_util.tree_leaves(x_arr), jax.tree_util.tree_leaves(y_arr), strict=True)
    for a, b in leaves:
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape or a.dtype != b.dtype:
            return False
        if not np.allclose(a, b, rtol=rtol, atol=atol, equal_nan=True):
            return False
    return True


def central_difference_jvp(fn, x, v, *, eps=None, scale=None):
    """Central finite-difference approximation of the JVP ``d/ds fn(x + s v)`` at s = 0.

    Args:
        fn: function of one pytree argument returning a pytree of arrays.
        x: point (pytree of float arrays).
        v: tangent (same structure as ``x``).
        eps: step in ``s``. Default ``sqrt(machine eps) * scale``, which balances the O(eps²)
            truncation error against the O(machine eps / eps) round-off of the difference.
        scale: typical magnitude of ``x`` along ``v`` (default: max(1, max |x|) / max |v|).

    Returns:
        ``(fn(x + eps v) - fn(x - eps v)) / (2 eps)`` with the structure of ``fn(x)``.
    """
    if eps is None:
        if scale is None:
            xmax = max(
                [float(jnp.max(jnp.abs(leaf))) for leaf in jax.tree_util.tree_leaves(x)] + [1.0]
            )
            vmax = max(
                [float(jnp.max(jnp.abs(leaf))) for leaf in jax.tree_util.tree_leaves(v)] + [1e-300]
            )
            scale = xmax / vmax
        eps = float(np.sqrt(np.finfo(np.float64).eps)) * scale
    xp = jax.tree_util.tree_map(lambda a, b: a + eps * b, x, v)
    xm = jax.tree_util.tree_map(lambda a, b: a - eps * b, x, v)
    fp, fm = fn(xp), fn(xm)
    return jax.tree_util.tree_map(lambda a, b: (a - b) / (2 * eps), fp, fm)


def contact_kinematics(delta, rate, impact, tangential=0.0):
    """``ContactKinematics`` from numbers or arrays (its fields are annotated as float arrays)."""
    from jaxclear.contact import ContactKinematics

    return ContactKinematics(
        jnp.asarray(delta, dtype=float),
        jnp.asarray(rate, dtype=float),
        jnp.asarray(impact, dtype=float),
        jnp.asarray(tangential, dtype=float),
    )


@contextlib.contextmanager
def without_runtime_type_checks():
    """Switch jaxtyping's runtime checks (pyproject ``--jaxtyping-packages``) off inside the block.

    For tests of the package's own friendly errors on arguments whose annotation the runtime
    checker would reject first (with a ``TypeError`` of its own).
    """
    before = jaxtyping.config.jaxtyping_disable
    jaxtyping.config.update("jaxtyping_disable", True)
    try:
        yield
    finally:
        jaxtyping.config.update("jaxtyping_disable", before)


def two_cpu_devices_environment():
    """The environment for a subprocess with two CPU devices: this process's, with
    ``--xla_force_host_platform_device_count=2`` added to XLA_FLAGS (so the suite's own flags,
    tests/conftest.py's fusion emitters off, stay)."""
    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count=2"
    return dict(os.environ, XLA_FLAGS=flags.strip())
