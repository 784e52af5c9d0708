"""Normal contact force laws of a revolute clearance joint (MODEL.md §3)."""

from ._base import (
    AbstractContactLaw as AbstractContactLaw,
    ContactGeometry as ContactGeometry,
    ContactKinematics as ContactKinematics,
    Smoothing as Smoothing,
)
from ._cylindrical import Liu2007 as Liu2007, Pereira2011 as Pereira2011
from ._damped import (
    AbstractDampedContactLaw as AbstractDampedContactLaw,
    Flores as Flores,
    Gonthier as Gonthier,
    HuntCrossley as HuntCrossley,
    LankaraniNikravesh as LankaraniNikravesh,
    ZhiyingQishao as ZhiyingQishao,
)
from ._foundation import (
    ElasticFoundation as ElasticFoundation,
    ElasticFoundationDiscrete as ElasticFoundationDiscrete,
)
from ._hertz import Hertz as Hertz
from ._hybrid import Hybrid as Hybrid
from ._impact import AdamsImpact as AdamsImpact
from ._registry import (
    CONTACT_LAWS as CONTACT_LAWS,
    contact_law_from_name as contact_law_from_name,
)
