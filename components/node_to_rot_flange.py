"""Adapter from a 6-DOF node to a rotational flange: ``flange.phi = node.tz`` (rotation about z).

Lets 1-D rotational parts (:class:`Inertia`, :class:`Torque`, :class:`TorsionalSpring`,
:class:`IdealLeadScrew`...) act on the torsional DOF of an FE node or a rigid body. The kinematic
relation is an ideal constraint; its reaction is ``node.Mz = -flange.tau``. The other five flows of
the node are zero.
"""

from bscomp.kernel.component import Component, Constraint
from bscomp.kernel.ports import Node6, RotFlange


class NodeToRotFlange(Component):
    """Node6 ``tz`` <-> RotFlange ``phi`` (massless, rigid).

    Attributes
    ----------
    node : Node6
        Torsional potential ``tz``, flow ``Mz``.
    flange : RotFlange
        Rotational flange, ``phi = node.tz``.
    """

    node = Node6("6-DOF node (its rotation tz about the screw axis is used)", optional=False)
    flange = RotFlange("rotational flange, phi = node.tz")

    def constraints(self):
        return [Constraint(self.flange.phi - self.node.tz, solve_for=self.flange.phi)]

    def equations(self):
        n = self.node
        return [n.Fx, n.Fy, n.Fz, n.Mx, n.My]
