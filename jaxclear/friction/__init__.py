"""Friction laws of a revolute clearance joint (docs/model.md §4)."""

from ._base import AbstractFrictionLaw as AbstractFrictionLaw
from ._base import AbstractStatelessFrictionLaw as AbstractStatelessFrictionLaw
from ._coulomb import Coulomb as Coulomb
from ._coulomb import ModifiedCoulomb as ModifiedCoulomb
from ._lugre import LuGre as LuGre
from ._none import NoFriction as NoFriction
from ._registry import FRICTION_LAWS as FRICTION_LAWS
from ._registry import friction_law_from_name as friction_law_from_name
