"""Clearance joints evaluated in batches: several joints of the same kind in one vmap.

XLA's CPU backend runs a right-hand side as a sequence of small kernels, each costing ~45 ns to
launch whatever its size; the arithmetic of one clearance joint is cheaper than that. Joints whose
laws and smoothing have the same structure (same classes, same static options, same leaf shapes)
are therefore evaluated together: their array leaves are stacked, the two joined bodies'
coordinates gathered for each, and the local functions of ``dynamics._clearance`` vmapped over the
stack, so three joints cost about the kernels of one (measured on the slider–crank, see
benchmarks/bench_clearance.py). A group of one goes through the mechanism-level functions.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..model._clearance import ClearanceJoint
from . import _clearance as clearance

_LAW_FIELDS = ("geometry", "contact_law", "friction_law", "smoothing", "lubrication")
"""``ClearanceJoint`` fields whose structure (classes, static options) must match within a group
(``lubrication``: dry or lubricated, and the film's static theory and Petroff option)."""


def _signature(element: ClearanceJoint):
    """Elements with equal signatures can share one vmapped evaluation (hashable).

    Everything but the array leaves must match: the classes and static options of the laws and
    any non-array leaf (a Python float in a law would otherwise be taken from the first element).
    Names and body names (static fields of the element itself) are left out.
    """
    leaves = jax.tree_util.tree_leaves(eqx.partition(element, eqx.is_array)[0])
    parts = []
    for field in _LAW_FIELDS:
        static = eqx.partition(getattr(element, field), eqx.is_array)[1]
        static_leaves, treedef = jax.tree_util.tree_flatten(static)
        parts.append((treedef, tuple(static_leaves)))
    key = (
        type(element),
        tuple(parts),
        tuple((x.shape, x.dtype) for x in leaves),
        element.num_states,
        element.memory_offset,
    )
    try:
        hash(key)
    except TypeError:
        return None
    return key


def groups(mechanism) -> list[tuple[ClearanceJoint, ...]]:
    """Clearance joints of ``mechanism`` grouped for evaluation (static, computed while tracing).

    Returns a list of tuples of joints, in the order of their first members in
    ``mechanism.clearance_joints``; tuples of more than one joint are batched.
    """
    out, by_signature = [], {}
    for element in mechanism.clearance_joints:
        key = _signature(element)
        if key is not None and key in by_signature:
            out[by_signature[key]] += (element,)
        else:
            by_signature[key] = len(out)
            out.append((element,))
    return out


def _extended(x):
    """x with a zero body appended (the slot that ground's index points to), as rows of 3."""
    return jnp.concatenate([x, jnp.zeros(3, dtype=x.dtype)]).reshape(-1, 3)


def _indices(mechanism, elements):
    """(bearing, journal) body rows of each element; ground maps to the appended zero row."""
    ground = len(mechanism.bodies)
    pairs = [clearance.body_indices(e, mechanism.index) for e in elements]
    return tuple(np.array([ground if p[k] is None else p[k] for p in pairs]) for k in (0, 1))


def _stack_states(elements, states):
    return jnp.stack([states[e.name] for e in elements])


def _vmapped(elements, function):
    """vmap of ``function(joint, *args)`` over the joints' stacked array leaves."""
    dyn = [jax.tree_util.tree_leaves(eqx.partition(e, eqx.is_array)[0]) for e in elements]
    first, static = eqx.partition(elements[0], eqx.is_array)
    stacked = jax.tree_util.tree_unflatten(
        jax.tree_util.tree_structure(first), [jnp.stack(x) for x in zip(*dyn)]
    )

    def call(dynamic, *args):
        return function(eqx.combine(dynamic, static), *args)

    return lambda *args: jax.vmap(call)(stacked, *args)


def batched_force_and_cache(mechanism, elements, q, qd, t, states, gamma_h=None):
    """(Q contribution of all ``elements``, stacked cache, stacked stage); ``gamma_h`` and the
    stage: see ``clearance.local_force_and_cache``."""
    ib, ij = _indices(mechanism, elements)
    q3, qd3 = _extended(q), _extended(qd)
    fn = _vmapped(
        elements,
        lambda e, *a: clearance.local_force_and_cache(e, *a, gamma_h=gamma_h),
    )
    on_bearing, on_journal, cache, stage = fn(
        q3[ib], qd3[ib], q3[ij], qd3[ij], _stack_states(elements, states)
    )
    force = jnp.zeros_like(q3).at[ib].add(on_bearing).at[ij].add(on_journal)
    return force[:-1].reshape(-1), cache, stage


def batched_state_rates(mechanism, elements, cache, q, qd, qdd, t, states) -> dict:
    """{name: internal-state rate} of ``elements`` from their stacked cache."""
    ib, ij = _indices(mechanism, elements)
    q3, qd3, qdd3 = _extended(q), _extended(qd), _extended(qdd)
    fn = _vmapped(elements, clearance.local_state_derivative)
    rates = fn(
        cache, qdd3[ib], qdd3[ij], q3[ib], qd3[ib], q3[ij], qd3[ij], _stack_states(elements, states)
    )
    return {e.name: rates[k] for k, e in enumerate(elements)}


def batched_stiff_rates(mechanism, elements, q, qd, t, states) -> dict:
    """{name: stiff part of the internal-state rate} of ``elements``."""
    ib, ij = _indices(mechanism, elements)
    q3, qd3 = _extended(q), _extended(qd)
    fn = _vmapped(elements, clearance.local_stiff_state_derivative)
    rates = fn(q3[ib], qd3[ib], q3[ij], qd3[ij], _stack_states(elements, states))
    return {e.name: rates[k] for k, e in enumerate(elements)}
