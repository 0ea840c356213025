"""Rotational rigid inertia (Modelica ``Rotational.Components.Inertia``; the rotor of Sec 3.3.2).

.. math:: J \\ddot\\varphi = \\tau_a + \\tau_b

with both flanges rigidly attached (ideal constraint) and ``flange_a.tau = J a`` explicit.
"""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RotFlange


class Inertia(Component):
    """Rotating inertia.

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        Rotational flanges (optional).
    phi, w, a : observable
        Angle [rad], angular speed [rad/s] and angular acceleration [rad/s^2] of the body.
    """

    flange_a = RotFlange("left flange of the body", optional=True)
    flange_b = RotFlange("right flange of the body", optional=True)
    J = Parameter(unit="kg.m^2", positive=True, doc="moment of inertia about the rotation axis")

    coordinate_names = {"flange_a.phi": "phi"}  # name of the body coordinate in the DAE

    @property
    def phi(self):
        return self.flange_a.phi

    @property
    def w(self):
        return self.der(self.phi)

    @property
    def a(self):
        return self.der(self.w)

    def constraints(self):
        return [self.flange_b.phi - self.flange_a.phi]

    def equations(self):
        return [self.flange_a.tau - self.J * self.a]

    def observables(self):
        return {"phi": self.phi, "w": self.w, "a": self.a}
