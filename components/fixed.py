"""Fixed translational flange (the rigid frame, Sec 3.3: ``s = s0``), an ideal constraint."""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import Flange


class Fixed(Component):
    """Flange fixed at position ``s0``."""

    flange = Flange("fixed flange")
    s0 = Parameter(0.0, unit="m", doc="fixed position")

    def constraints(self):
        return [self.flange.s - self.s0]
