"""Linear torsional spring, ``tau = c (phi_rel - phi_rel0)`` (the coupling's k_T, Fig 3.7)."""

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialRotCompliant


class TorsionalSpring(PartialRotCompliant):
    """Linear torsional spring.

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialRotCompliant`).
    """

    c = Parameter(unit="N.m/rad", positive=True, doc="torsional stiffness")
    phi_rel0 = Parameter(0.0, unit="rad", doc="unstretched angle")

    def equations(self):
        return [self.tau - self.c * (self.phi_rel - self.phi_rel0)]
