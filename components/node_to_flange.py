"""Adapter from a 6-DOF node to a translational flange: ``flange.s = node.w`` (axial motion).

Lets 1-D parts (:class:`Mass`, :class:`Spring`, :class:`IdealLeadScrew`, :class:`Force`...) act on the
axial DOF of an FE node or a rigid body. The kinematic relation is an ideal constraint; its reaction
is ``node.Fz = -flange.f`` (virtual work). The adapter transmits no other load: the other five flows
of the node are zero.
"""

from bscomp.component import Component, Constraint
from bscomp.ports import Flange, Node6


class NodeToFlange(Component):
    """Node6 ``w`` <-> Flange ``s`` (massless, rigid).

    # Connectors
    - ``node``: Node6 (axial potential ``w``, flow ``Fz``)
    - ``flange``: translational flange
    """

    node = Node6("6-DOF node (its axial dof w is used)", optional=False)
    flange = Flange("translational flange, s = node.w")

    def constraints(self):
        return [Constraint(self.flange.s - self.node.w, solve_for=self.flange.s)]

    def equations(self):
        n = self.node
        return [n.Fx, n.Fy, n.Mx, n.My, n.Mz]
