"""Bearing housing: a block on its fasteners, movable along the screw axis only (thesis Sec 3.5.2.3).

Sec 3.5.2.3 blames a missing mode of the test bed on the angular-contact bearing's housing: "a huge
block within which the bearing sits ... connected to the machine's frame using fasteners", which
"should have been more realistically modeled as a lumped mass attached to the frame by springs" but
was taken as rigid. This is that block, seen along the axis: a mass ``m`` on an axial fastener spring
``c`` and damper ``d`` to the rigid frame,

.. math:: F_z = m \\ddot w + d \\dot w + c\\, w ,

acting on the ``w`` potential of its node (the bearing's outer ring: connect it to ``node_b`` of an
un-grounded :class:`~components.bearing.Bearing`). The other five potentials of the node are held at
zero by ideal constraints (their reactions go to the frame): the housing adds exactly one coordinate.

Limits: radial and tilting compliance of the fasteners are not modelled (held rigid); the axial
fastener stiffness is lumped (no bolt-by-bolt detail); the damping is viscous.
"""

from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import Node6

from ._node_dofs import pin_unused


class Housing(Component):
    """Axially compliant bearing housing (mass on a fastener spring to ground).

    Attributes
    ----------
    node : Node6
        The housing side of the bearing (only ``w`` moves).
    s : observable
        Axial housing displacement [m].
    f : observable
        Fastener force on the housing [N] (``c w + d w'``).
    """

    node = Node6("housing node (bearing outer ring); only its axial potential w moves", optional=False)
    m = Parameter(unit="kg", positive=True, doc="housing mass")
    c = Parameter(unit="N/m", min=0.0, doc="axial fastener stiffness to the frame")
    d = Parameter(0.0, unit="N.s/m", min=0.0, doc="axial fastener damping")

    def constraints(self):
        return pin_unused(self.node, ("w",))

    def equations(self):
        w = self.node.w
        v = self.der(w)
        return [self.node.Fz - (self.m * self.der(v) + self.d * v + self.c * w)]

    def observables(self):
        w = self.node.w
        return {"s": w, "f": self.c * w + self.d * self.der(w)}
