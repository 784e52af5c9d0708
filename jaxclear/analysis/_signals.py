"""Named signals of a trajectory as JAX arrays: the continuous physical columns of results.csv.

``signal_names(mechanism)`` lists the columns of ``jaxclear run``'s results (``result_columns``,
same spelling) that are continuous physical quantities, the ones a measured response can be
compared with; ``signals(traj, names)`` computes them with ``jax.numpy`` from the ``Trajectory``
arrays, so that a fit can differentiate through them (``jax.jit``, ``jax.grad``, ``jax.vmap``).

Left out: the driven body's angle (prescribed by the driver, nothing to fit), the clearance
joints' ``impact_velocity`` (a latched solver memory, not a measurable quantity) and ``<J>_mode``
(integer labels), the constraint and velocity violations (numerical errors), and the Lagrange
multipliers of joints other than revolute and translational.
"""

from collections.abc import Callable, Sequence

from jaxtyping import Array, Float

from ..mechanisms import is_slider_crank
from ..model import Mechanism, RevoluteJoint, TranslationalJoint
from ..solve._trajectory import BODY_OUTPUTS, CLEARANCE_OUTPUTS, Trajectory

CLEARANCE_SIGNALS = tuple(
    key
    for key in CLEARANCE_OUTPUTS
    if key
    in {
        "ecc_x",
        "ecc_y",
        "penetration",
        "penetration_rate",
        "normal_force",
        "friction_force",
        "tangential_force",
        "slip_velocity",
        "friction_state",
    }
)
"""Outputs of a clearance joint that are signals (``<joint>_<output>``), in results.csv order;
``friction_state`` only for friction laws with an internal state (LuGre)."""

Signal = Float[Array, "*batch N"]
Extractor = Callable[[Trajectory], Signal]


def _coordinate(array: str, column: int) -> Extractor:
    return lambda traj: getattr(traj, array)[..., column]


def _joint_force(joint: str, axis: int) -> Extractor:
    # Trajectory.joint_force: the force body_j exerts on body_i is minus the multipliers.
    return lambda traj: -traj.reactions[joint][..., axis]


def _input_torque(traj: Trajectory) -> Signal:
    return traj.input_torque


def _clearance(joint: str, key: str) -> Extractor:
    return lambda traj: traj.clearance[joint][key]


def _extractors(mechanism: Mechanism) -> dict[str, Extractor]:
    """{signal name: function of a Trajectory}, in results.csv column order (``result_columns``)."""
    table: list[tuple[str, Extractor]] = []
    if is_slider_crank(mechanism):
        i = mechanism.body_index("slider")
        table += [
            ("slider_x", _coordinate("q", 3 * i)),
            ("slider_v", _coordinate("qd", 3 * i)),
            ("slider_a", _coordinate("qdd", 3 * i)),
        ]
    else:
        for body in mechanism.body_names:
            i = mechanism.body_index(body)
            for name, k, array, _, _ in BODY_OUTPUTS:
                table.append((f"{body}_{name}", _coordinate(array, 3 * i + k)))
    if mechanism.driver is not None:
        table.append((f"{mechanism.driver.body}_torque", _input_torque))
    for joint in mechanism.joints:
        if isinstance(joint, RevoluteJoint):
            table += [
                (f"{joint.name}_F{axis}", _joint_force(joint.name, k))
                for k, axis in enumerate("xy")
            ]
        elif isinstance(joint, TranslationalJoint):
            # Rows (relative angle, normal offset); the guide acts on the slider with -λ
            # (as in result_columns, docs/model.md §1).
            table += [
                (f"{joint.name}_moment", _joint_force(joint.name, 0)),
                (f"{joint.name}_normal", _joint_force(joint.name, 1)),
            ]
    for joint in mechanism.clearance_joints:
        for key in CLEARANCE_SIGNALS:
            if key == "friction_state" and not joint.friction_law.num_states:
                continue
            table.append((f"{joint.name}_{key}", _clearance(joint.name, key)))
    names = [name for name, _ in table]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"signal names collide: {dupes}; rename the joints or bodies.")
    return dict(table)


def signal_names(mechanism: Mechanism) -> tuple[str, ...]:
    """Names of the signals of ``mechanism``'s trajectories, in results.csv column order.

    The same names as the columns ``jaxclear run`` writes (``result_columns``), restricted to
    continuous physical quantities: for the benchmark slider–crank ``slider_x`` (m), ``slider_v``
    (m/s), ``slider_a`` (m/s²), for any other mechanism every body's ``<body>_x``, ``_y``, ``_phi``,
    ``_vx``, ``_vy``, ``_omega``, ``_ax``, ``_ay``, ``_alpha``; with a driver
    ``<driven body>_torque`` (N m); per ideal revolute joint ``<J>_Fx``, ``<J>_Fy`` (N); per
    translational joint ``<J>_moment`` (N m), ``<J>_normal`` (N); per clearance joint
    ``<J>_<output>`` for the outputs in ``CLEARANCE_SIGNALS``.

    Args:
        mechanism: a ``Mechanism``.

    Returns:
        The names, a tuple of str.

    Raises:
        ValueError: two signals would have the same name (a body and a joint named alike).
    """
    return tuple(_extractors(mechanism))


def signals(traj: Trajectory, names: Sequence[str] | None = None) -> dict[str, Signal]:
    """Named signals at the trajectory's saved instants, as JAX arrays.

    Computed with ``jax.numpy`` from the ``Trajectory`` arrays, so it works inside ``jax.jit``,
    ``jax.grad`` and ``jax.vmap`` (and on a batched trajectory: leading batch axes are kept). The
    values equal those of the same-named columns of ``result_columns``.

    Args:
        traj: a ``Trajectory`` (single or batched).
        names: which signals (see ``signal_names``); default all of them.

    Returns:
        ``{name: values}`` in the order of ``names``; each array has shape (*batch, N), SI units.

    Raises:
        TypeError: ``names`` is a single string.
        ValueError: a name is not a signal of ``traj.mechanism`` (the message lists the valid ones).
    """
    table = _extractors(traj.mechanism)
    if names is None:
        names = tuple(table)
    if isinstance(names, str):
        raise TypeError(f"signals: names must be a sequence of names; write [{names!r}].")
    for name in names:
        if name not in table:
            raise ValueError(
                f"signals: {name!r} is not a signal of this mechanism; valid names: "
                f"{', '.join(table)}."
            )
    return {name: table[name](traj) for name in names}


def checked_signal_names(mechanism: Mechanism, names, parameter: str) -> tuple[str, ...]:
    """``names`` as a tuple, each a signal of ``mechanism``; ``parameter`` names them in errors."""
    if isinstance(names, str):
        raise TypeError(f"{parameter} must be a sequence of signal names; write [{names!r}].")
    names = tuple(names)
    valid = signal_names(mechanism)
    bad = [n for n in names if n not in valid]
    if bad or not names:
        raise ValueError(
            f"{parameter}: {bad or 'no names'} {'are' if len(bad) != 1 else 'is'} not signals of this "
            f"mechanism; choose among {valid}."
        )
    return names
