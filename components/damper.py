"""Linear translational damper, ``f = d v_rel`` (e.g. the guideway viscous coefficient, Table 5.2)."""

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialCompliant


class Damper(PartialCompliant):
    """Linear translational damper.

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`).
    """

    d = Parameter(unit="N.s/m", min=0.0, doc="damping constant")

    def equations(self):
        return [self.f - self.d * self.v_rel]
