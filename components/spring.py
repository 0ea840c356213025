"""Linear translational spring, ``f = c (s_rel - s_rel0)`` (joint springs of Sec 3.3.3)."""

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialCompliant


class Spring(PartialCompliant):
    """Linear translational spring.

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`).
    """

    c = Parameter(unit="N/m", positive=True, doc="spring constant")
    s_rel0 = Parameter(0.0, unit="m", doc="unstretched length")

    def equations(self):
        return [self.f - self.c * (self.s_rel - self.s_rel0)]
