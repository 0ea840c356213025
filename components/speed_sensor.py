"""Ideal absolute angular speed sensor (the tachometer, before its gain H_g): ``w = der(flange.phi)``."""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import RealOutput, RotFlange


class SpeedSensor(Component):
    """Absolute angular speed sensor.

    Attributes
    ----------
    flange : RotFlange
        Measured flange (draws no torque).
    w : RealOutput
        Angular speed [rad/s].
    """

    flange = RotFlange("measured flange")
    w = RealOutput("angular speed [rad/s]", unit="rad/s")

    def equations(self):
        return [self.flange.tau, self.w.y - self.der(self.flange.phi)]
