"""Friction laws by kebab-case name, for configuration files and the command line."""

import types

from .._checks import build_from_registry
from ._base import AbstractFrictionLaw
from ._coulomb import Coulomb, ModifiedCoulomb
from ._lugre import LuGre
from ._none import NoFriction

FRICTION_LAWS: types.MappingProxyType[str, type[AbstractFrictionLaw]] = types.MappingProxyType(
    {
        "none": NoFriction,
        "coulomb": Coulomb,
        "modified-coulomb": ModifiedCoulomb,
        "lugre": LuGre,
    }
)
"""Read-only mapping from registry name to friction law class."""


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
    return build_from_registry(FRICTION_LAWS, "friction law", name, params)
