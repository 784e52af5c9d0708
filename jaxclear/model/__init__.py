"""Model objects: bodies, joints, drivers, force elements, the mechanism."""

from ._body import GROUND as GROUND
from ._body import Body as Body
from ._clearance import ClearanceJoint as ClearanceJoint
from ._element import AbstractStateElement as AbstractStateElement
from ._forces import AbstractForceElement as AbstractForceElement
from ._forces import AppliedForce as AppliedForce
from ._forces import AppliedTorque as AppliedTorque
from ._forces import SpringDamper as SpringDamper
from ._joints import AbstractDriver as AbstractDriver
from ._joints import AbstractJoint as AbstractJoint
from ._joints import ConstantSpeedDriver as ConstantSpeedDriver
from ._joints import FunctionDriver as FunctionDriver
from ._joints import RevoluteJoint as RevoluteJoint
from ._joints import TranslationalJoint as TranslationalJoint
from ._mechanism import Mechanism as Mechanism
from ._mechanism import describe as describe
from ._parameters import ParameterInfo as ParameterInfo
from ._parameters import get_parameter as get_parameter
from ._parameters import parameter_info as parameter_info
from ._parameters import parameter_names as parameter_names
from ._parameters import with_parameters as with_parameters
from ._translational_clearance import CORNER_NAMES as CORNER_NAMES
from ._translational_clearance import CORNER_PAIRS as CORNER_PAIRS
from ._translational_clearance import TranslationalClearanceJoint as TranslationalClearanceJoint
