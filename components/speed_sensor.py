"""Ideal absolute angular speed sensor (the tachometer, before its gain H_g): ``w = der(flange.phi)``."""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import RealOutput, RotFlange


class SpeedSensor(Component):
    """Absolute angular speed sensor.

    # Connectors
    - ``flange``: measured flange (draws no torque)
    - ``w``: real output [rad/s]
    """

    flange = RotFlange("measured flange")
    w = RealOutput("angular speed [rad/s]", unit="rad/s")

    def equations(self):
        return [self.flange.tau, self.w.y - self.der(self.flange.phi)]
