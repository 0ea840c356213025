"""Tachometer on the motor shaft: ``v = H_g w``, ``w = der(flange.phi)`` (Sec 4.3, Fig 4.3).

The analog velocity loop of the P-PI cascade measures the motor speed with a tachometer of gain
H_g = 0.0668 V/(rad/s) (Sec 4.3). The sensor is ideal (no ripple, no filter) and draws no torque.
"""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RealOutput, RotFlange


class Tachometer(Component):
    """Angular speed to voltage.

    Attributes
    ----------
    flange : RotFlange
        Measured rotational flange (no torque drawn).
    v : RealOutput
        Tachometer voltage [V].
    """

    flange = RotFlange("measured flange (motor shaft)")
    v = RealOutput("tachometer voltage [V]", unit="V")
    H_g = Parameter(0.0668, unit="V.s/rad", positive=True, doc="tachometer gain (Sec 4.3)")

    def equations(self):
        return [self.flange.tau, self.v.y - self.H_g * self.der(self.flange.phi)]
