"""Ideal (rigid, lossless) lead screw: rotation of ``flange_a`` drives translation of ``flange_b``.

Modelica's ``IdealGearR2T`` with ``ratio = 1/r_g``:

.. math:: s_b = r_g \\varphi_a,\\qquad r_g = p / (2\\pi), \\qquad \\tau_a + r_g f_b = 0

The kinematic relation is an ideal constraint; the torque/force relation is its reaction (virtual work),
so two inertias joined by the screw give the reflected inertia ``J + m r_g^2`` of Eq 4.2 with no index
problem. ``r_g = 1.59e-3 m/rad`` for the thesis test bed (p = 10 mm, Sec 4.2.1).
"""

import math

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, Constraint, Parameter
from bscomp.kernel.ports import Flange, RotFlange


class IdealLeadScrew(Component):
    """Ideal lead screw (rotary -> linear).

    Attributes
    ----------
    flange_a : RotFlange
        Rotational flange (screw).
    flange_b : Flange
        Translational flange (nut).
    r_g : observable
        Lead per radian ``p / (2 pi)`` [m/rad].
    """

    flange_a = RotFlange("screw side (rotation)")
    flange_b = Flange("nut side (translation)")
    lead = Parameter(0.010, unit="m/rev", doc="lead p: advance per revolution (negative for a left-hand thread)")

    def check(self, values):
        """``lead != 0``: a zero lead decouples the nut from the screw (the sign is the thread hand)."""
        if values["lead"] == 0.0:
            raise ParameterError(f"{self._where('lead')}: lead = 0 m/rev decouples the nut from the screw; give a "
                                 "nonzero lead (> 0 right-hand thread, < 0 left-hand), e.g. 0.010 m/rev")

    @property
    def r_g(self):
        return self.lead / (2 * math.pi)

    def constraints(self):
        return [Constraint(self.flange_b.s - self.r_g * self.flange_a.phi, solve_for=self.flange_b.s)]

    def observables(self):
        return {"r_g": self.r_g}
