"""Force elements evaluated in batches: several clearance joints of the same kind in one vmap.

XLA's CPU backend runs a right-hand side as a sequence of small kernels, each costing ~45 ns to
launch whatever its size; the arithmetic of one clearance joint is cheaper than that. Joints whose
laws and smoothing have the same structure (same classes, same static options, same leaf shapes)
are therefore evaluated together: their array leaves are stacked, the two joined bodies'
coordinates gathered for each, and the element's ``local_*`` methods vmapped over the stack, so
three joints cost about the kernels of one (measured on the slider–crank, see
benchmarks/bench_clearance.py).

An element takes part if it has the methods ``body_indices``, ``local_force_and_cache``,
``local_state_derivative`` and ``local_stiff_state_derivative`` (``ClearanceJoint`` has); any other
element, or a group of one, goes through its mechanism-level methods unchanged.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

_LOCAL_METHODS = ("body_indices", "local_force_and_cache", "local_state_derivative", "local_stiff_state_derivative")


def _batchable(element) -> bool:
    return all(hasattr(element, m) for m in _LOCAL_METHODS)


def _signature(element):
    """Elements with equal signatures can share one vmapped evaluation (hashable).

    Everything but the array leaves must match: the classes and static options of the laws and
    any non-array leaf (a Python float in a law would otherwise be taken from the first element).
    Names and body names (static fields of the element itself) are left out.
    """
    leaves = jax.tree_util.tree_leaves(eqx.partition(element, eqx.is_array)[0])
    parts = []
    for field in ("geometry", "contact_law", "friction_law", "smoothing"):
        static = eqx.partition(getattr(element, field, None), eqx.is_array)[1]
        static_leaves, treedef = jax.tree_util.tree_flatten(static)
        parts.append((treedef, tuple(static_leaves)))
    key = (type(element), tuple(parts), tuple((x.shape, x.dtype) for x in leaves), element.num_states,
           getattr(element, "memory_offset", None))
    try:
        hash(key)
    except TypeError:
        return None
    return key


def groups(mechanism) -> list[tuple]:
    """Force elements of ``mechanism`` grouped for evaluation (static, computed while tracing).

    Returns a list of tuples of elements; tuples of more than one element are batched.
    """
    out, by_signature = [], {}
    for element in mechanism.force_elements:
        if not _batchable(element):
            out.append((element,))
            continue
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
    pairs = [e.body_indices(mechanism.index) for e in elements]
    return tuple(np.array([ground if p[k] is None else p[k] for p in pairs]) for k in (0, 1))


def _stack_states(elements, states):
    return jnp.stack([states[e.name] for e in elements])


def _vmapped(elements, method):
    """vmap of ``method`` of the element class over the elements' stacked array leaves."""
    dyn = [jax.tree_util.tree_leaves(eqx.partition(e, eqx.is_array)[0]) for e in elements]
    first, static = eqx.partition(elements[0], eqx.is_array)
    stacked = jax.tree_util.tree_unflatten(jax.tree_util.tree_structure(first), [jnp.stack(x) for x in zip(*dyn)])

    def call(dynamic, *args):
        return getattr(eqx.combine(dynamic, static), method)(*args)

    return lambda *args: jax.vmap(call)(stacked, *args)


def batched_force_and_cache(mechanism, elements, q, qd, t, states):
    """(Q contribution of all ``elements``, stacked cache)."""
    ib, ij = _indices(mechanism, elements)
    q3, qd3 = _extended(q), _extended(qd)
    fn = _vmapped(elements, "local_force_and_cache")
    on_bearing, on_journal, cache = fn(q3[ib], qd3[ib], q3[ij], qd3[ij], _stack_states(elements, states))
    force = jnp.zeros_like(q3).at[ib].add(on_bearing).at[ij].add(on_journal)
    return force[:-1].reshape(-1), cache


def batched_state_rates(mechanism, elements, cache, q, qd, qdd, t, states) -> dict:
    """{name: internal-state rate} of ``elements`` from their stacked cache."""
    ib, ij = _indices(mechanism, elements)
    q3, qd3, qdd3 = _extended(q), _extended(qd), _extended(qdd)
    fn = _vmapped(elements, "local_state_derivative")
    rates = fn(cache, qdd3[ib], qdd3[ij], q3[ib], qd3[ib], q3[ij], qd3[ij], _stack_states(elements, states))
    return {e.name: rates[k] for k, e in enumerate(elements)}


def batched_stiff_rates(mechanism, elements, q, qd, t, states) -> dict:
    """{name: stiff part of the internal-state rate} of ``elements``."""
    ib, ij = _indices(mechanism, elements)
    q3, qd3 = _extended(q), _extended(qd)
    fn = _vmapped(elements, "local_stiff_state_derivative")
    rates = fn(q3[ib], qd3[ib], q3[ij], qd3[ij], _stack_states(elements, states))
    return {e.name: rates[k] for k, e in enumerate(elements)}
