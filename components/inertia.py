"""Rotational rigid inertia (Modelica ``Rotational.Components.Inertia``; the rotor of Sec 3.3.2).

.. math:: J \\ddot\\varphi = \\tau_a + \\tau_b

with both flanges rigidly attached (ideal constraint) and ``flange_a.tau = J a`` explicit.
"""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RotFlange


class Inertia(Component):
    """Rotating inertia.

    # Parameters
    - ``J`` [kg.m^2]: moment of inertia about the rotation axis (> 0)

    # Connectors
    - ``flange_a``, ``flange_b``: rotational flanges (optional)

    # Observables
    - ``phi`` [rad], ``w`` [rad/s], ``a`` [rad/s^2]
    """

    flange_a = RotFlange("left flange of the body", optional=True)
    flange_b = RotFlange("right flange of the body", optional=True)
    J = Parameter(unit="kg.m2", positive=True, doc="moment of inertia")

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
