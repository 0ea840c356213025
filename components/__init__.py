"""Physical components, one per file (``bscomp.components``)."""

from .acceleration_sensor import AccelerationSensor
from .angle_sensor import AngleSensor
from .damper import Damper
from .fixed import Fixed
from .fixed_rotational import FixedRotational
from .force import Force
from .gain import Gain
from .ideal_lead_screw import IdealLeadScrew
from .inertia import Inertia
from .mass import Mass
from .position_sensor import PositionSensor
from .speed_sensor import SpeedSensor
from .spring import Spring
from .torque import Torque
from .torsional_damper import TorsionalDamper
from .torsional_spring import TorsionalSpring
from .velocity_sensor import VelocitySensor

__all__ = [
    "AccelerationSensor", "AngleSensor", "Damper", "Fixed", "FixedRotational", "Force", "Gain", "IdealLeadScrew",
    "Inertia", "Mass", "PositionSensor", "SpeedSensor", "Spring", "Torque", "TorsionalDamper",
    "TorsionalSpring", "VelocitySensor",
]
