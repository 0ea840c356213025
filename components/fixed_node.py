"""Fixed 6-DOF node: the rigid frame (thesis Sec 3.3: "assumed rigid and fixed to the ground").

Ideal constraints ``node.<d> = 0`` for each fixed potential; the reactions are the support forces.
``dofs`` fixes a subset (e.g. ``("w", "tz")`` for a clamped end of an axial + torsional screw whose
other potentials its owner already constrains; fixing a potential twice is a redundant-constraint
error).
"""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import Node6

from ._node_dofs import DOF_NAMES, check_dofs


class FixedNode(Component):
    """Clamped node.

    Parameters
    ----------
    dofs : tuple of str
        Potentials fixed to zero (default all six).

    Attributes
    ----------
    node : Node6
        The clamped node (required).
    """

    node = Node6("fixed node", optional=False)

    def __init__(self, dofs=DOF_NAMES, **params):
        super().__init__(**params)
        self.dofs = check_dofs(dofs, "FixedNode")

    def template_key(self):
        return self.dofs

    def constraints(self):
        return [getattr(self.node, d) for d in self.dofs]

    def equations(self):  # flows of free potentials are zero (nothing acts there)
        return [self.node.F[i] for i, d in enumerate(DOF_NAMES) if d not in self.dofs]
