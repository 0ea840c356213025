"""Ideal absolute velocity sensor: ``v = der(flange.s)``, no force."""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import Flange, RealOutput


class VelocitySensor(Component):
    """Absolute velocity sensor.

    Attributes
    ----------
    flange : Flange
        Measured flange (draws no force).
    v : RealOutput
        Absolute velocity [m/s].
    """

    flange = Flange("measured flange")
    v = RealOutput("absolute velocity [m/s]", unit="m/s")

    def equations(self):
        return [self.flange.f, self.v.y - self.der(self.flange.s)]
