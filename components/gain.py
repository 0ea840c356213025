"""Static gain on a signal, ``y = k u`` (amplifier K_a, torque constant K_t, tachometer H_g: Eq 4.1)."""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RealInput, RealOutput


class Gain(Component):
    """Signal gain.

    Attributes
    ----------
    u : RealInput
        Input signal.
    y : RealOutput
        Output signal.
    """

    u = RealInput("input signal")
    y = RealOutput("output signal")
    k = Parameter(1.0, unit="1", doc="gain (its unit follows the connected signals, e.g. N.m/A for K_t)")

    def equations(self):
        return [self.y.y - self.k * self.u.u]
