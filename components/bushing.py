"""Bushing: general linear 6x6 spring-damper between two nodes (joint interfaces, thesis Sec 3.3.3).

.. math:: F_b = -K (d_b - d_a) - C (\\dot d_b - \\dot d_a),\\qquad F_a = -F_b

``K`` and ``C`` are full 6x6 matrices over ``(u, v, w, θx, θy, θz)`` (a 6-vector gives a diagonal),
symmetric positive semi-definite; coupling terms (e.g. the 6x6 block ``A`` of a lumped K_SN, Eq 3.45)
are allowed. ``grounded=True`` ties ``node_a`` to the rigid frame.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ParameterError
from bscomp.kernel.component import Parameter

from ._joint6 import PartialJoint6
from ._node_dofs import as_6x6


class Bushing(PartialJoint6):
    """Linear 6-DOF bushing.

    Parameters
    ----------
    grounded : bool
        True: ``node_b`` is the rigid frame and only ``node_a`` exists.

    Attributes
    ----------
    node_a, node_b : Node6
        The two joined nodes (``node_b`` absent if ``grounded=True``).
    """

    K = Parameter(unit="N/m|N|N.m/rad", doc="6x6 stiffness on (u, v, w, tx, ty, tz), or a 6-vector "
                  "diagonal; symmetric positive semi-definite")
    C = Parameter(np.zeros(6), unit="N.s/m|N.s|N.m.s/rad", doc="6x6 viscous damping (or a 6-vector diagonal)")

    def check(self, values):
        """``K`` and ``C`` symmetric positive semi-definite (a passive joint stores and dissipates energy)."""
        for name in ("K", "C"):
            if values[name] is None:
                continue  # reported by flatten (missing parameter)
            A = as_6x6(values[name], f"Bushing.{name}")
            if not np.allclose(A, A.T, atol=1e-12 * max(1.0, np.abs(A).max())):
                raise ParameterError(f"{self._where(name)} must be symmetric (a 6x6 matrix equal to its transpose, "
                                     "or a 6-vector diagonal)")
            if np.linalg.eigvalsh(A).min() < -1e-9 * max(1.0, np.abs(A).max()):
                raise ParameterError(f"{self._where(name)} must be positive semi-definite (a passive joint): "
                                     f"its smallest eigenvalue is {np.linalg.eigvalsh(A).min():.6g}")

    def stiffness(self):
        return as_6x6(self.K, "Bushing.K")

    def damping(self):
        return as_6x6(self.C, "Bushing.C")
