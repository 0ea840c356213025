"""Partial base classes: shared structure written once (after Modelica's ``Interfaces``).

``PartialCompliant`` fixes, like MSL's ``PartialCompliant``::

    s_rel = flange_b.s - flange_a.s
    flange_b.f = f
    flange_a.f = -f

so a spring or damper only states its constitutive law for ``f``.
"""

from __future__ import annotations

from bscomp.kernel.component import Component, Variable
from bscomp.kernel.ports import Flange, RotFlange

__all__ = ["PartialCompliant", "PartialRotCompliant"]


class PartialCompliant(Component):
    """Two translational flanges joined by a massless compliant element.

    # Connectors
    - ``flange_a``, ``flange_b``: translational flanges [m, N]

    # Variables
    - ``f`` [N]: force transmitted, positive in tension (``flange_b.f = f``, ``flange_a.f = -f``)
    - ``s_rel = flange_b.s - flange_a.s`` [m], ``v_rel`` [m/s] (expressions)
    """

    flange_a = Flange("left flange (force -f acts on it)")
    flange_b = Flange("right flange (force +f acts on it)")
    f = Variable("N", doc="force in the element, positive in tension")

    @property
    def s_rel(self):
        return self.flange_b.s - self.flange_a.s

    @property
    def v_rel(self):
        return self.der(self.s_rel)

    def connector_equations(self):
        return [self.flange_b.f - self.f, self.flange_a.f + self.f]

    def observables(self):
        return {"f": self.f, "s_rel": self.s_rel, "v_rel": self.v_rel}


class PartialRotCompliant(Component):
    """Two rotational flanges joined by a massless compliant element.

    # Connectors
    - ``flange_a``, ``flange_b``: rotational flanges [rad, N.m]

    # Variables
    - ``tau`` [N.m]: transmitted torque (``flange_b.tau = tau``, ``flange_a.tau = -tau``)
    - ``phi_rel = flange_b.phi - flange_a.phi`` [rad], ``w_rel`` [rad/s] (expressions)
    """

    flange_a = RotFlange("left flange (torque -tau acts on it)")
    flange_b = RotFlange("right flange (torque +tau acts on it)")
    tau = Variable("N.m", doc="transmitted torque")

    @property
    def phi_rel(self):
        return self.flange_b.phi - self.flange_a.phi

    @property
    def w_rel(self):
        return self.der(self.phi_rel)

    def connector_equations(self):
        return [self.flange_b.tau - self.tau, self.flange_a.tau + self.tau]

    def observables(self):
        return {"tau": self.tau, "phi_rel": self.phi_rel, "w_rel": self.w_rel}
