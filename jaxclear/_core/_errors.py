"""Exceptions raised by jaxclear. Each message names the offending quantity and a fix."""


class ModelError(ValueError):
    """A model object was built with an invalid parameter (non-positive mass, NaN, ...)."""


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
