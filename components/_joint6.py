"""Partial base class of the 6-DOF linear joints (thesis Sec 3.3.3): bushing, bearing, fastener.

A joint is a massless spring-damper between two nodes, relative displacement ``d_b - d_a``:

.. math:: F_b = -K (d_b - d_a) - C (\\dot d_b - \\dot d_a),\\qquad F_a = -F_b

i.e. the structure block ``[[K, -K], [-K, K]]`` (and the same for C) over ``(d_a, d_b)``. With
``grounded=True`` the ``node_b`` port does not exist and the joint ties ``node_a`` to the rigid frame
(the thesis' frame is rigid and fixed to the ground, Sec 3.3): the block is ``K`` on ``d_a`` alone.
Subclasses give the 6x6 matrices through :meth:`stiffness` and :meth:`damping` (numeric parameters).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.kernel.component import Component, LinearStructure
from bscomp.kernel.ports import Node6

from ._node_dofs import DOF_NAMES

__all__ = ["PartialJoint6"]


class PartialJoint6(Component):
    """Two Node6 ports (``node_a``, ``node_b``) joined by linear 6x6 stiffness and damping.

    Parameters
    ----------
    grounded : bool
        True: ``node_b`` is the rigid frame and only ``node_a`` exists.

    Attributes
    ----------
    node_a : Node6
        First node (required).
    node_b : Node6
        Second node (required), absent if ``grounded=True``.
    """

    node_a = Node6("first node (e.g. the shaft side)", optional=False)

    def __init__(self, grounded: bool = False, **params):
        super().__init__(**params)
        self.grounded = bool(grounded)
        if not self.grounded:
            self.add_port("node_b", Node6("second node (e.g. the housing side)", optional=False))

    def stiffness(self) -> np.ndarray:
        """6x6 stiffness on the relative displacement ``d_b - d_a`` (override)."""
        raise NotImplementedError

    def damping(self) -> np.ndarray | None:
        """6x6 viscous damping on the relative velocity, or None (override)."""
        return None

    def structure(self):
        K, C = self.stiffness(), self.damping()
        if self.grounded:
            dofs = [f"node_a.{d}" for d in DOF_NAMES]
            pair = sp.csr_matrix(np.ones((1, 1)))
        else:
            dofs = [f"node_a.{d}" for d in DOF_NAMES] + [f"node_b.{d}" for d in DOF_NAMES]
            pair = sp.csr_matrix(np.array([[1.0, -1.0], [-1.0, 1.0]]))
        Kb = sp.kron(pair, sp.csr_matrix(K)).tocsr()
        Cb = None if C is None or not np.any(C) else sp.kron(pair, sp.csr_matrix(C)).tocsr()
        return LinearStructure(dofs=dofs, K=Kb, C=Cb)
