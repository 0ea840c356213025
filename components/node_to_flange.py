"""Adapter from a 6-DOF node to a translational flange: ``flange.s = direction * node.w`` (axial motion).

Lets 1-D parts (:class:`Mass`, :class:`Spring`, :class:`IdealLeadScrew`, :class:`Force`...) act on the
axial DOF of an FE node or a rigid body. The kinematic relation is an ideal constraint; its reaction
is ``node.Fz = -direction * flange.f`` (virtual work). The adapter transmits no other load: the other
five flows of the node are zero.

``direction`` (+1 or -1) says where the flange's positive axis points: ``+1`` along the node's +z,
``-1`` along -z. A machine axis need not point the way of the screw's z axis: on the thesis test bed
(right-hand thread) a positive screw rotation about +z moves the nut towards -z, so the table of
:mod:`bscomp.systems.testbed` is attached with ``direction = -1`` to be positive in the direction a
positive motor command moves it (the thesis's convention, G_x = r_g / s).
"""

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, Constraint, Parameter
from bscomp.kernel.ports import Flange, Node6


class NodeToFlange(Component):
    """Node6 ``w`` <-> Flange ``s`` (massless, rigid), ``flange.s = direction * node.w``.

    Attributes
    ----------
    node : Node6
        Axial potential ``w``, flow ``Fz``.
    flange : Flange
        Translational flange.
    """

    node = Node6("6-DOF node (its axial dof w is used)", optional=False)
    flange = Flange("translational flange, s = direction * node.w")
    direction = Parameter(1.0, unit="1", min=-1.0, max=1.0,
                          doc="+1: flange axis along the node's +z (default); -1: along -z")

    def check(self, values):
        """``direction`` is +1 or -1 (an axis direction, not a ratio)."""
        if values["direction"] not in (1.0, -1.0):
            raise ParameterError(f"{self._where('direction')} must be +1 (flange axis along the node's +z) or -1 "
                                 f"(along -z), got {values['direction']!r}")

    def constraints(self):
        return [Constraint(self.flange.s - self.direction * self.node.w, solve_for=self.flange.s)]

    def equations(self):
        n = self.node
        return [n.Fx, n.Fy, n.Mx, n.My, n.Mz]
