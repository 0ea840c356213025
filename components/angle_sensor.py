"""Ideal absolute angle sensor (the motor encoder): ``phi = flange.phi``, no torque."""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import RealOutput, RotFlange


class AngleSensor(Component):
    """Absolute angle sensor.

    Attributes
    ----------
    flange : RotFlange
        Measured flange (draws no torque).
    phi : RealOutput
        Absolute angle [rad].
    """

    flange = RotFlange("measured flange")
    phi = RealOutput("absolute angle [rad]", unit="rad")

    def equations(self):
        return [self.flange.tau, self.phi.y - self.flange.phi]
