"""Linear spring and damper in parallel, ``f = c (s_rel - s_rel0) + d v_rel`` (a contact in engagement)."""

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialCompliant


class SpringDamper(PartialCompliant):
    """Parallel spring-damper (Modelica ``SpringDamper``).

    The small-signal equivalent of an engaged elastic contact with damping (:class:`Backlash`).
    """

    c = Parameter(unit="N/m", min=0.0, doc="spring constant")
    d = Parameter(0.0, unit="N.s/m", min=0.0, doc="damping constant")
    s_rel0 = Parameter(0.0, unit="m", doc="unstretched length")

    def equations(self):
        return [self.f - self.c * (self.s_rel - self.s_rel0) - self.d * self.v_rel]
