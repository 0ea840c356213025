"""Ideal absolute position sensor (e.g. the table's linear encoder): ``s = flange.s``, no force."""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import Flange, RealOutput


class PositionSensor(Component):
    """Absolute position sensor.

    Attributes
    ----------
    flange : Flange
        Measured flange (draws no force).
    s : RealOutput
        Absolute position [m].
    """

    flange = Flange("measured flange")
    s = RealOutput("absolute position [m]", unit="m")

    def equations(self):
        return [self.flange.f, self.s.y - self.flange.s]
