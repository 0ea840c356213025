"""Translational rigid mass (Modelica ``Translational.Components.Mass``, thesis Sec 3.3.2 lumped table).

Both flanges are rigidly attached to the body (an ideal constraint ``flange_b.s = flange_a.s``), and

.. math:: m \\ddot s = f_a + f_b

is written as the explicit flow ``flange_a.f = m a``; the split between the flanges is the constraint
reaction, solved by the system.
"""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import Flange


class Mass(Component):
    """Sliding mass.

    Attributes
    ----------
    flange_a, flange_b : Flange
        Translational flanges (optional: an unconnected flange is free).
    s, v, a : observable
        Position [m], velocity [m/s] and acceleration [m/s^2] of the body.
    """

    flange_a = Flange("left flange of the body", optional=True)
    flange_b = Flange("right flange of the body", optional=True)
    m = Parameter(unit="kg", positive=True, doc="mass")

    coordinate_names = {"flange_a.s": "s"}  # name of the body coordinate in the DAE

    @property
    def s(self):
        return self.flange_a.s

    @property
    def v(self):
        return self.der(self.s)

    @property
    def a(self):
        return self.der(self.v)

    def constraints(self):
        return [self.flange_b.s - self.flange_a.s]

    def equations(self):
        return [self.flange_a.f - self.m * self.a]

    def observables(self):
        return {"s": self.s, "v": self.v, "a": self.a}
