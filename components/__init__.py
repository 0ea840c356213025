"""Physical components, one per file (``bscomp.components``)."""

from .acceleration_sensor import AccelerationSensor
from .angle_sensor import AngleSensor
from .ballscrew import Ballscrew
from .bearing import Bearing
from .bolted_fastener import BoltedFastener
from .bushing import Bushing
from .coupling import Coupling
from .damper import Damper
from .fixed import Fixed
from .fixed_node import FixedNode
from .fixed_rotational import FixedRotational
from .force import Force
from .gain import Gain
from .ideal_lead_screw import IdealLeadScrew
from .inertia import Inertia
from .linear_guide import LinearGuide
from .mass import Mass
from .node_to_flange import NodeToFlange
from .node_to_rot_flange import NodeToRotFlange
from .position_sensor import PositionSensor
from .rigid_body import RigidBody
from .screw_nut import ScrewNut
from .speed_sensor import SpeedSensor
from .spring import Spring
from .torque import Torque
from .torsional_damper import TorsionalDamper
from .torsional_spring import TorsionalSpring
from .velocity_sensor import VelocitySensor

__all__ = [
    "AccelerationSensor", "AngleSensor", "Damper", "Fixed", "FixedRotational", "Force", "Gain",
    "IdealLeadScrew", "Inertia", "Mass", "PositionSensor", "SpeedSensor", "Spring", "Torque",
    "TorsionalDamper", "TorsionalSpring", "VelocitySensor",
    "Ballscrew", "Bearing", "BoltedFastener", "Bushing", "Coupling", "FixedNode", "LinearGuide",
    "NodeToFlange", "NodeToRotFlange", "RigidBody", "ScrewNut",
]
