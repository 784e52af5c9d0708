"""Every exception jaxclear raises, and the codes of the checks made inside a compiled solve.

Each message names the offending quantity and a fix. The hierarchy::

    ValueError
    ├── ModelError        a model object got an invalid parameter (NaN, mass <= 0, ...)
    ├── EnsembleError     an ensemble cannot start: bad values, or a folder holding another run
    ├── DataError         measured data cannot be used (unreadable, malformed, non-finite, ...)
    └── AssemblyError     no consistent initial positions/velocities (geometry does not close)
    RuntimeError
    └── SimulationError   the time integration failed (``t`` and ``state`` where it stopped)

Argument errors of plain Python functions (a negative count, an unknown option name) are
``ValueError``/``TypeError`` as in the standard library. Inside a compiled solve nothing is raised:
``simulate`` returns failures as data (``Trajectory.result`` and ``Trajectory.input_error``, whose
codes are ``InputCheck``), and the eager front door turns them into the exceptions above.
"""

import enum


class ModelError(ValueError):
    """A model object was built with an invalid parameter (non-positive mass, NaN, ...)."""


class EnsembleError(ValueError):
    """An ensemble cannot start: bad arguments, or an output folder holding another configuration."""


class DataError(ValueError):
    """Measured data (a CSV file or arrays given for a fit) cannot be used: unreadable, malformed,
    non-finite, times out of order, unknown columns, ... The one-line message names the file, the
    column and row, and the fix."""


class AssemblyError(ValueError):
    """Consistent initial positions/velocities could not be found (geometry does not close,
    redundant or singular constraints)."""


class SimulationError(RuntimeError):
    """The time integration failed. ``t`` is the time reached and ``state`` the state there.

    Attributes:
        t: time reached, s.
        state: dict of the last finite coordinates and velocities.
    """

    def __init__(self, message: str, t: float | None = None, state: dict | None = None):
        super().__init__(message)
        self.t = t
        self.state = state


class InputCheck(enum.IntEnum):
    """Codes of ``Trajectory.input_error``: checks of the inputs made inside the compiled solve.

    They are returned as values, not raised by host callbacks (``eqx.error_if``), so that the
    compiled solve can be stored and loaded again (``jaxclear.enable_compilation_cache``).
    """

    PASSED = 0
    NOT_ASSEMBLED = 1
    MASS_OR_INERTIA = 2
    STATE_NOT_FINITE = 3

    @property
    def message(self) -> str:
        """What failed and the fix, for the error raised (or the member's message in an ensemble)."""
        return _INPUT_CHECK_MESSAGES[self]

    @property
    def error(self) -> type[ValueError]:
        """The exception the eager front door raises for this code."""
        return AssemblyError if self is InputCheck.NOT_ASSEMBLED else ModelError


_INPUT_CHECK_MESSAGES = {
    InputCheck.PASSED: "all input checks passed",
    InputCheck.NOT_ASSEMBLED: "mechanism cannot be assembled: run jaxclear.assemble() on it for details",
    InputCheck.MASS_OR_INERTIA: "mass and inertia of every body must be positive and finite (see Body)",
    InputCheck.STATE_NOT_FINITE: "initial state is not finite: check the parameters",
}
