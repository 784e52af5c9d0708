"""Contact laws by kebab-case name, for configuration files and the command line."""

from .._core._registry import Registry
from ._base import AbstractContactLaw
from ._cylindrical import Liu2007, Pereira2011
from ._damped import Flores, Gonthier, HuntCrossley, LankaraniNikravesh, ZhiyingQishao
from ._foundation import ElasticFoundation, ElasticFoundationDiscrete
from ._hertz import Hertz
from ._hybrid import Hybrid
from ._impact import AdamsImpact

CONTACT_LAWS: Registry[AbstractContactLaw] = Registry(
    "contact law",
    {
        "hertz": Hertz,
        "lankarani-nikravesh": LankaraniNikravesh,
        "hunt-crossley": HuntCrossley,
        "flores": Flores,
        "gonthier": Gonthier,
        "zhiying-qishao": ZhiyingQishao,
        "pereira": Pereira2011,
        "liu": Liu2007,
        "impact": AdamsImpact,
        "elastic-foundation": ElasticFoundation,
        "elastic-foundation-discrete": ElasticFoundationDiscrete,
        "hybrid": Hybrid,
    },
)
"""Read-only mapping from registry name to contact law class (``jaxclear._core._registry.Registry``)."""


def contact_law_from_name(name: str, **params) -> AbstractContactLaw:
    """Build a contact law from its registry name.

    Args:
        name: one of the keys of :data:`CONTACT_LAWS` (e.g. ``"hybrid"``).
        **params: keyword arguments of the law's constructor (e.g. ``restitution=0.8``).

    Returns:
        The law instance.

    Raises:
        ValueError: ``name`` is not registered (the message lists the valid names), or a
            parameter is invalid.
    """
    return CONTACT_LAWS.build(name, **params)
