"""Physical components, one per file (``bscomp.components``)."""

from ._beam_fe import BeamModel, DofSelection, Section, assemble_shaft, select_dofs
from .acceleration_sensor import AccelerationSensor
from .angle_sensor import AngleSensor

# nonlinear (Sec 5.2.2): regularised friction and backlash
from .backlash import Backlash  # noqa: E402
from .ballscrew import Ballscrew
from .bearing import Bearing
from .bolted_fastener import BoltedFastener
from .bushing import Bushing
from .coulomb_friction import CoulombFriction  # noqa: E402
from .coupling import Coupling

# control (Chapter 4): continuous blocks live in the DAE, sampled blocks are run by a simulator
from .current_amplifier import CurrentAmplifier  # noqa: E402
from .damper import Damper
from .digital_p_controller import DigitalPController  # noqa: E402
from .fixed import Fixed
from .fixed_node import FixedNode
from .fixed_rotational import FixedRotational
from .force import Force
from .force_between import ForceBetween
from .gain import Gain
from .housing import Housing
from .ideal_lead_screw import IdealLeadScrew
from .inertia import Inertia
from .linear_guide import LinearGuide
from .mass import Mass
from .moving_nut_joint import MovingNutJoint
from .moving_screw_nut import MovingScrewNut
from .node_to_flange import NodeToFlange
from .node_to_rot_flange import NodeToRotFlange
from .notch_filter import NotchFilter  # noqa: E402
from .pade_delay import PadeDelay
from .pi_controller import PIController  # noqa: E402
from .position_sensor import PositionSensor
from .reduced_substructure import ReducedSubstructure
from .rigid_body import RigidBody
from .rotational_backlash import RotationalBacklash  # noqa: E402
from .rotational_friction import RotationalFriction  # noqa: E402
from .rst_controller import RSTController  # noqa: E402
from .saturation import Saturation  # noqa: E402
from .screw_nut import ScrewNut
from .screw_nut_shape_function import ScrewNutShapeFunction
from .second_order_block import SecondOrderBlock
from .speed_sensor import SpeedSensor
from .spring import Spring
from .spring_damper import SpringDamper
from .stribeck_friction import StribeckFriction  # noqa: E402
from .structural_block import StructuralBlock
from .tachometer import Tachometer  # noqa: E402
from .torque import Torque
from .torque_between import TorqueBetween
from .torsional_damper import TorsionalDamper
from .torsional_spring import TorsionalSpring
from .velocity_sensor import VelocitySensor

__all__ = [
    "ScrewNutShapeFunction",
    "SecondOrderBlock",
    "ReducedSubstructure",
    "StructuralBlock",
    "MovingNutJoint",
    "MovingScrewNut",
    "AccelerationSensor", "AngleSensor", "Damper", "Fixed", "FixedRotational", "Force", "Gain",
    "IdealLeadScrew", "Inertia", "Mass", "PositionSensor", "SpeedSensor", "Spring", "Torque",
    "TorsionalDamper", "TorsionalSpring", "VelocitySensor", "ForceBetween", "TorqueBetween", "SpringDamper",
    "Ballscrew", "Bearing", "BoltedFastener", "Bushing", "Coupling", "FixedNode", "LinearGuide",
    "NodeToFlange", "NodeToRotFlange", "RigidBody", "ScrewNut",
]
__all__ += [
    "CurrentAmplifier", "PIController", "Saturation", "Tachometer",
    "DigitalPController", "NotchFilter", "RSTController",
]
__all__ += ["Backlash", "CoulombFriction", "RotationalBacklash", "RotationalFriction", "StribeckFriction"]
__all__ += ["Housing", "PadeDelay", "Section", "BeamModel", "DofSelection", "assemble_shaft", "select_dofs"]
