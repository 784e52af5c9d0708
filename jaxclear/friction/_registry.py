"""Friction laws by kebab-case name, for configuration files and the command line."""

from .._core._registry import Registry
from ._base import AbstractFrictionLaw
from ._coulomb import Coulomb, ModifiedCoulomb
from ._lugre import LuGre
from ._none import NoFriction

FRICTION_LAWS: Registry[AbstractFrictionLaw] = Registry(
    "friction law",
    {
        "none": NoFriction,
        "coulomb": Coulomb,
        "modified-coulomb": ModifiedCoulomb,
        "lugre": LuGre,
    },
)
"""Read-only mapping from registry name to friction law class (``jaxclear._core._registry.Registry``)."""


def friction_law_from_name(name: str, **params) -> AbstractFrictionLaw:
    """Build a friction law from its registry name.

    Args:
        name: one of the keys of :data:`FRICTION_LAWS` (e.g. ``"lugre"``).
        **params: keyword arguments of the law's constructor (e.g. ``static_friction=0.2``).

    Returns:
        The law instance.

    Raises:
        ValueError: ``name`` is not registered (the message lists the valid names), or a
            parameter is invalid.
    """
    return FRICTION_LAWS.build(name, **params)
