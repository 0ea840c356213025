"""Screw-nut interface by the shape-function method (thesis Eq 3.17-3.29, 3.36-3.39), for long nuts and
flexible screws.

The rigid-ballscrew method (:class:`~components.screw_nut.ScrewNut`, Eq 3.35) lumps every ball on one
screw point P. Here each ball at azimuth φ loads the screw cross-section at its own axial position
``z = z_nut + r_g φ``, reached through the beam shape functions ``N(z)`` (Eq 3.27): the 12x12 K_SN
becomes a stiffness coupling every screw node under the nut to the (rigid) nut node,

.. math:: K = \\sum_{balls} \\int \\begin{bmatrix} N(z)^T T_{BS}^T \\\\ -T_N^T \\end{bmatrix} k_{ball}\\, n n^T
          \\begin{bmatrix} T_{BS} N(z) & -T_N \\end{bmatrix} d\\varphi / \\Delta\\varphi

computed by :func:`components._screw_nut_fe.ksn_shape_function` (quadrature split at the FE nodes,
exact for the piecewise-polynomial integrand). For a short nut on a stiff screw it equals the rigid
method; for a long nut on a slender screw the rigid method is too stiff (it feeds the whole load into
one section): see tests/components/test_screw_nut_shape_function.py.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, LinearStructure
from bscomp.kernel.ports import Node6

from ._node_dofs import DOF_NAMES
from ._screw_nut_fe import ksn_shape_function


class ScrewNutShapeFunction(Component):
    """Shape-function screw-nut interface between a :class:`~components.ballscrew.Ballscrew` and a nut.

    Parameters
    ----------
    screw : Ballscrew
        The screw it attaches to (its mesh and shape functions at the current parameter values).
    z_nut : float
        Axial position of the nut reference point P on the screw axis [m].
    interface : ScrewNut
        Ball and thread data (k_ball, n_ball, alpha, beta, R, azimuth range, r_g, preload, hand), e.g.
        the test bed's ``bscomp.systems.thesis_parts.thesis_screw_nut()``.

    Attributes
    ----------
    n0 ... n<N> : Node6
        Connect to the screw's nodes of the same name.
    nut : Node6
        The nut reference node at P.
    """

    def __init__(self, screw, z_nut: float, interface):
        super().__init__()
        self.screw_z = tuple(float(z) for z in screw.z_nodes)
        self.z_nut = float(z_nut)
        if not self.screw_z[0] <= self.z_nut <= self.screw_z[-1]:
            raise ParameterError(f"ScrewNutShapeFunction: z_nut = {z_nut!r} m puts the nut off the screw; give a "
                                 f"position in [{self.screw_z[0]:.6g}, {self.screw_z[-1]:.6g}] m (the screw's first "
                                 "and last node)")
        v = interface._values
        phi = (v["phi_start"], v["phi_end"])
        beam = screw.beam_model()
        K = ksn_shape_function(
            v["k_ball"], int(round(v["n_ball"])), v["alpha"], v["beta"], v["R"],
            lambda z: beam.shape_matrix(z).toarray(),
            self.z_nut, phi_range=phi, preload=interface.preload, r_g=None if v["r_g"] == 0.0 else v["r_g"],
            hand=interface.hand, z_breaks=self.screw_z, sparse=True)
        K = sp.csr_matrix(K)
        n_screw = 6 * len(self.screw_z)
        used = np.unique(np.concatenate([K[:n_screw].nonzero()[0], K[:n_screw].nonzero()[1]]))
        used = used[used < n_screw]
        self.nodes = sorted({int(i) // 6 for i in used})
        for i in self.nodes:
            self.add_port(f"n{i}", Node6(f"screw node {i} at z = {self.screw_z[i]:.6g} m"))
        self.add_port("nut", Node6("nut node at P", optional=False))
        keep = [6 * i + k for i in self.nodes for k in range(6)] + list(range(n_screw, n_screw + 6))
        self.K = K[keep][:, keep]

    def template_key(self):
        return (self.screw_z, self.z_nut, tuple(self.nodes))

    def structure(self):
        dofs = [f"n{i}.{d}" for i in self.nodes for d in DOF_NAMES] + [f"nut.{d}" for d in DOF_NAMES]
        return LinearStructure(dofs=dofs, K=self.K)
