"""Normal contact force laws of a revolute clearance joint (docs/model.md §3)."""

from ._base import AbstractContactLaw as AbstractContactLaw
from ._base import ContactGeometry as ContactGeometry
from ._base import ContactKinematics as ContactKinematics
from ._base import Smoothing as Smoothing
from ._cylindrical import Liu2007 as Liu2007
from ._cylindrical import Pereira2011 as Pereira2011
from ._damped import AbstractDampedContactLaw as AbstractDampedContactLaw
from ._damped import Flores as Flores
from ._damped import Gonthier as Gonthier
from ._damped import HuntCrossley as HuntCrossley
from ._damped import LankaraniNikravesh as LankaraniNikravesh
from ._damped import ZhiyingQishao as ZhiyingQishao
from ._foundation import ElasticFoundation as ElasticFoundation
from ._foundation import ElasticFoundationDiscrete as ElasticFoundationDiscrete
from ._hertz import Hertz as Hertz
from ._hybrid import Hybrid as Hybrid
from ._impact import AdamsImpact as AdamsImpact
from ._lubrication import LUBRICATION_THEORIES as LUBRICATION_THEORIES
from ._lubrication import FilmForce as FilmForce
from ._lubrication import Lubrication as Lubrication
from ._lubrication import film_components as film_components
from ._lubrication import film_force as film_force
from ._registry import CONTACT_LAWS as CONTACT_LAWS
from ._registry import contact_law_from_name as contact_law_from_name
