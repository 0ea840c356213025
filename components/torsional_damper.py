"""Linear torsional damper, ``tau = d w_rel`` (e.g. B reflected at the motor, Eq 4.2)."""

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialRotCompliant


class TorsionalDamper(PartialRotCompliant):
    """Linear torsional damper.

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialRotCompliant`).
    """

    d = Parameter(unit="N.m.s/rad", min=0.0, doc="torsional damping constant")

    def equations(self):
        return [self.tau - self.d * self.w_rel]
