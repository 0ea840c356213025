"""Force source driven by a signal: the input ``f`` acts on ``flange`` (``flange.f = -f``).

With a positive input the flange is pushed in the positive direction (Modelica ``Force``).
"""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import Flange, RealInput


class Force(Component):
    """Ideal force source.

    Attributes
    ----------
    flange : Flange
        Translational flange the force acts on.
    f : RealInput
        Force [N]; unconnected, it becomes the system input ``<name>.f``.
    """

    flange = Flange("flange the force acts on")
    f = RealInput("force [N], positive in +s direction", unit="N")

    def equations(self):
        return [self.flange.f + self.f.u]
