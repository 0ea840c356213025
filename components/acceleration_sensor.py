"""Ideal absolute acceleration sensor (an accelerometer on the table): ``a = der(der(flange.s))``."""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import Flange, RealOutput


class AccelerationSensor(Component):
    """Absolute acceleration sensor.

    Attributes
    ----------
    flange : Flange
        Measured flange (draws no force).
    a : RealOutput
        Absolute acceleration [m/s^2].
    """

    flange = Flange("measured flange")
    a = RealOutput("absolute acceleration [m/s2]", unit="m/s2")

    def equations(self):
        return [self.flange.f, self.a.y - self.der(self.der(self.flange.s))]
