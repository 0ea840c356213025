"""Bolted fastener: axial spring between two nodes (thesis Sec 3.3.3.3).

A nut-and-bolt joint is a linear spring whose stiffness is the bolt and the clamped members in
series, ``1/k = 1/k_bolt + 1/k_members`` (computed from the geometry as in the thesis' ref [41]).
It acts along the bolt axis ``n`` (unit vector, default the z axis) on the relative translation:

.. math:: F_b = -k\\, n n^T (u_b - u_a) - c\\, n n^T (\\dot u_b - \\dot u_a),\\qquad F_a = -F_b

Use :meth:`series` to combine bolt and member stiffnesses.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ParameterError
from bscomp.kernel.component import Parameter

from ._joint6 import PartialJoint6


class BoltedFastener(PartialJoint6):
    """Axial spring-damper along a bolt axis.

    Parameters
    ----------
    grounded : bool
        True: ``node_b`` is the rigid frame and only ``node_a`` exists.

    Attributes
    ----------
    node_a, node_b : Node6
        The two clamped parts (``node_b`` absent if ``grounded=True``).
    """

    k = Parameter(unit="N/m", positive=True, doc="axial stiffness (bolt and members in series)")
    c = Parameter(0.0, unit="N.s/m", min=0.0, doc="axial viscous damping")
    axis = Parameter(np.array([0.0, 0.0, 1.0]), unit="1", doc="bolt axis direction (3-vector, normalised)")

    @staticmethod
    def series(k_bolt: float, k_members: float) -> float:
        """Stiffness of bolt and clamped members in series [N/m]."""
        return 1.0 / (1.0 / k_bolt + 1.0 / k_members)

    def check(self, values):
        """``axis`` is a non-zero 3-vector (it is normalised)."""
        n = np.asarray(values["axis"], dtype=float)
        if n.shape != (3,) or not np.linalg.norm(n) > 0.0:
            raise ParameterError(f"{self._where('axis')} must be a non-zero 3-vector (the bolt direction), got "
                                 f"{n.tolist()!r}")

    def _nn(self):
        n = np.asarray(self.axis, dtype=float)
        if n.shape != (3,) or np.linalg.norm(n) == 0.0:
            raise ParameterError(f"BoltedFastener.axis must be a non-zero 3-vector, got {n!r}")
        n = n / np.linalg.norm(n)
        P = np.zeros((6, 6))
        P[:3, :3] = np.outer(n, n)
        return P

    def stiffness(self):
        return self.k * self._nn()

    def damping(self):
        return self.c * self._nn()
