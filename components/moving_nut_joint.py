"""Screw-nut joint whose contact point moves with the nut (thesis Sec 5.2.2.3, Fig 5.7/5.8).

For the axial + torsional screw model (Chapter 5) the interface acts on the axial displacement ``w``
and the rotation ``θz`` of the screw *at the nut's current axial position* ``z = z0 + nut.w``, reached
through the element shape functions (linear for the bar and torsion fields, Eq A.7), so the drive's
modes change continuously during a long move instead of jumping from node to node:

.. math::
    e = \\begin{bmatrix} \\sum_i N_i(z)\\, w_i - w_N \\\\ \\sum_i N_i(z)\\, θ_{z,i} - θ_{z,N} \\end{bmatrix},
    \\qquad V = \\tfrac12 e^T K_{SN} e, \\qquad D = \\tfrac12 \\dot e^T C_{SN} \\dot e

with ``K_SN`` the (w, θz) block of Eq 3.45. Port forces are the gradients ``∂V/∂d + (∂e/∂d)^T C ė``
(virtual work), so the joint is conservative for C = 0 and forces reach the screw nodes as ``N(z)^T F``.
The helical null space of ``K_SN`` (``Δw = r_g Δθ``) carries the rigid-body travel exactly, so a nut
that has travelled metres still sees zero force at rest. Linearized at any nut position it equals the
frozen joint (``ScrewNut`` at a fixed point): the extra ``∂N/∂z`` terms multiply ``e``, which is zero
at equilibrium.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import Node6

from .moving_screw_nut import check_on_screw

_OTHER = (("u", "Fx"), ("v", "Fy"), ("tx", "Mx"), ("ty", "My"))


def _hat(z, z_nodes, i):
    """Linear shape function of node i at position z (1 at z_i, 0 at the neighbours)."""
    one = ca.SX(1.0)
    parts = []
    if i > 0:
        parts.append((z - z_nodes[i - 1]) / (z_nodes[i] - z_nodes[i - 1]))
    else:
        parts.append(one)
    if i < len(z_nodes) - 1:
        parts.append((z_nodes[i + 1] - z) / (z_nodes[i + 1] - z_nodes[i]))
    else:
        parts.append(one)
    return ca.fmax(0.0, ca.fmin(ca.fmin(parts[0], parts[1]), 1.0))


class MovingNutJoint(Component):
    """Axial + torsional screw-nut joint at the nut's current position (Sec 5.2.2.3).

    Parameters
    ----------
    z_nodes : array
        Axial coordinates [m] of the screw nodes it attaches to (``Ballscrew.z_nodes``).

    Attributes
    ----------
    n0 ... n<N> : Node6
        Connect to the screw nodes (``w`` and ``tz`` are used).
    nut : Node6
        The nut body (``w`` and ``tz`` are used).
    """

    nut = Node6("nut node", optional=False)
    k_w = Parameter(unit="N/m", positive=True, doc="axial stiffness k_zz of the (w, θz) block of K_SN (Eq 3.45)")
    k_t = Parameter(unit="N.m/rad", positive=True, doc="torsional stiffness k_θzθz of K_SN (Eq 3.45)")
    k_wt = Parameter(0.0, unit="N/rad", doc="axial-torsional coupling k_zθz of K_SN (Eq 3.45)")
    c_w = Parameter(0.0, unit="N.s/m", min=0.0, doc="axial joint damping")
    c_t = Parameter(0.0, unit="N.m.s/rad", min=0.0, doc="torsional joint damping")
    z0 = Parameter(unit="m", doc="nut position along the screw at nut.w = 0")

    def __init__(self, z_nodes, **params):
        self.z_nodes = np.asarray(z_nodes, float)            # before the parameter check (range of z0)
        if self.z_nodes.ndim != 1 or len(self.z_nodes) < 2 or np.any(np.diff(self.z_nodes) <= 0):
            raise ParameterError(f"MovingNutJoint: z_nodes must be an increasing array of at least 2 positions "
                                 f"[m] (Ballscrew.z_nodes), got {np.asarray(z_nodes).tolist()!r}")
        super().__init__(**params)
        for i, z in enumerate(self.z_nodes):
            self.add_port(f"n{i}", Node6(f"screw node {i} at z = {z:.6g} m"))

    def check(self, values):
        """``z0`` lies on the screw, ``z_nodes[0] <= z0 <= z_nodes[-1]`` (the hat functions exist there only)."""
        check_on_screw(self, values["z0"], self.z_nodes)

    @classmethod
    def from_screw_nut(cls, screw_nut, z_nodes, z0, c_w=0.0, c_t=0.0) -> "MovingNutJoint":
        """Take the (w, θz) block of a :class:`~components.screw_nut.ScrewNut`'s K_SN (Eq 3.35/3.45)."""
        K = screw_nut.stiffness_matrix()
        return cls(z_nodes, k_w=K[2, 2], k_t=K[5, 5], k_wt=K[2, 5], c_w=c_w, c_t=c_t, z0=z0)

    def template_key(self):
        return tuple(self.z_nodes)

    def position(self):
        """Current nut position along the screw [m]."""
        return self.z0 + self.nut.w

    def equations(self):
        z = self.position()
        nodes = [getattr(self, f"n{i}") for i in range(len(self.z_nodes))]
        N = [_hat(z, self.z_nodes, i) for i in range(len(nodes))]
        w_s = sum(n_i * p.w for n_i, p in zip(N, nodes))
        t_s = sum(n_i * p.tz for n_i, p in zip(N, nodes))
        e = ca.vertcat(w_s - self.nut.w, t_s - self.nut.tz)
        K = ca.vertcat(ca.horzcat(self.k_w, self.k_wt), ca.horzcat(self.k_wt, self.k_t))
        C = ca.diag(ca.vertcat(self.c_w, self.c_t))
        q = ca.vertcat(*[v for p in nodes for v in (p.w, p.tz)], self.nut.w, self.nut.tz)
        V = 0.5 * ca.mtimes([e.T, K, e])
        f = ca.gradient(V, q) + ca.mtimes(ca.jacobian(e, q).T, ca.mtimes(C, self.der(e)))
        eqs = []
        for k, p in enumerate(nodes + [self.nut]):
            eqs += [p.Fz - f[2 * k], p.Mz - f[2 * k + 1]]
            eqs += [getattr(p, fl) for _, fl in _OTHER]
        return eqs

    def moving_interface(self, value):
        """The joint as a position-dependent interface ``e = E(z) d`` (for ``simulate(method="modal")``):
        hat functions over each element's two nodes (w, θz) and the nut, see
        :meth:`MovingScrewNut.moving_interface <components.moving_screw_nut.MovingScrewNut.moving_interface>`."""
        K = np.array([[value("k_w"), value("k_wt")], [value("k_wt"), value("k_t")]], float)
        C = np.diag([value("c_w"), value("c_t")]).astype(float)
        elements = []
        for e in range(len(self.z_nodes) - 1):
            dofs = [f"n{e}.w", f"n{e}.tz", f"n{e + 1}.w", f"n{e + 1}.tz", "nut.w", "nut.tz"]
            coef = np.zeros((4, 2, 6))
            coef[0] = [[1, 0, 0, 0, -1, 0], [0, 1, 0, 0, 0, -1]]
            coef[1] = [[-1, 0, 1, 0, 0, 0], [0, -1, 0, 1, 0, 0]]
            elements.append((dofs, coef))
        return {"z_nodes": self.z_nodes, "slow": "nut.w", "z0": float(value("z0")), "K": K,
                "C": C if np.any(C) else None, "elements": elements}

    def observables(self):
        return {"z": self.position()}
