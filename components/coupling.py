"""Shaft coupling: torsional spring with the jaw inertias lumped at its ends (thesis Sec 3.3.3.1).

Fig 3.7: a jaw coupling is a torsional spring ``k_T`` (the polyurethane insert) with the two jaw
inertias ``J1`` and ``J2`` lumped at its ends and attached to the adjoining parts (motor shaft and
screw). With the end angles ``phi_a``, ``phi_b``:

.. math::

    \\begin{bmatrix} J_1 & 0 \\\\ 0 & J_2 \\end{bmatrix} \\ddot\\varphi
    + d \\begin{bmatrix} 1 & -1 \\\\ -1 & 1 \\end{bmatrix} \\dot\\varphi
    + k_T \\begin{bmatrix} 1 & -1 \\\\ -1 & 1 \\end{bmatrix} \\varphi = \\tau

Test bed (Table 3.1, Sec B.4): ``k_T = 3938 N.m/rad``, ``J1 = 3.09e-4``, ``J2 = 3.06e-4 kg.m^2``; the
free jaw-insert-jaw system has ``f = sqrt(k_T (1/J1 + 1/J2)) / (2 pi)`` (Eq B.1). ``ends="flange"``
gives rotational flanges ``flange_a``/``flange_b``; ``ends="node"`` gives Node6 ports
``node_a``/``node_b`` acting on ``tz`` only (the coupling transmits no other load).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import Component, LinearStructure, Parameter
from bscomp.kernel.ports import Node6, RotFlange

from ._node_dofs import DOF_NAMES


class Coupling(Component):
    """Torsional coupling with lumped jaw inertias (Fig 3.7).

    Parameters
    ----------
    ends : {"flange", "node"}
        Port kind at both ends.

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        Ends a and b for ``ends="flange"`` (optional).
    node_a, node_b : Node6
        Ends a and b for ``ends="node"`` (``tz`` only, required).
    """

    k_T = Parameter(unit="N.m/rad", positive=True, doc="torsional stiffness of the insert")
    J1 = Parameter(0.0, unit="kg.m^2", min=0.0, doc="jaw inertia lumped at end a (0 = massless end)")
    J2 = Parameter(0.0, unit="kg.m^2", min=0.0, doc="jaw inertia lumped at end b (0 = massless end)")
    d = Parameter(0.0, unit="N.m.s/rad", min=0.0, doc="torsional viscous damping")

    def __init__(self, ends: str = "flange", **params):
        super().__init__(**params)
        if ends not in ("flange", "node"):
            raise ModelDefinitionError(f"Coupling: ends must be 'flange' or 'node', got {ends!r}")
        self.ends = ends
        for side, which in (("a", "motor"), ("b", "screw")):
            if ends == "flange":
                self.add_port(f"flange_{side}", RotFlange(f"end {side} (e.g. {which} side)", optional=True))
            else:
                self.add_port(f"node_{side}",
                              Node6(f"end {side} (e.g. {which} side), tz only", optional=False))

    def template_key(self):
        return self.ends

    def structure(self):
        pair = np.array([[1.0, -1.0], [-1.0, 1.0]])
        M, K, C = np.diag([self.J1, self.J2]), self.k_T * pair, self.d * pair
        if self.ends == "flange":
            dofs = ["flange_a.phi", "flange_b.phi"]
        else:  # all 12 node dofs (zero rows except tz): the coupling defines every flow of its ports
            dofs = [f"node_{s}.{d}" for s in "ab" for d in DOF_NAMES]
            embed = sp.csr_matrix(([1.0, 1.0], ([5, 11], [0, 1])), shape=(12, 2))
            M, K, C = (embed @ sp.csr_matrix(A) @ embed.T for A in (M, K, C))
        return LinearStructure(dofs=dofs, M=sp.csr_matrix(M), K=sp.csr_matrix(K),
                               C=sp.csr_matrix(C) if self.d > 0 else None)
