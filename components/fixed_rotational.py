"""Fixed rotational flange (``phi = phi0``), an ideal constraint."""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RotFlange


class FixedRotational(Component):
    """Rotational flange fixed at angle ``phi0``."""

    flange = RotFlange("fixed flange")
    phi0 = Parameter(0.0, unit="rad", doc="fixed angle")

    def constraints(self):
        return [self.flange.phi - self.phi0]
