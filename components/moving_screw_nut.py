"""6-DOF screw-nut interface whose contact point P moves with the nut (thesis Sec 5.2.2.3 with Eq 3.35).

The rigid-ballscrew interface (:class:`~components.screw_nut.ScrewNut`, Eq 3.35) couples the six DOF of
the screw point P to the six of the nut through the 12x12 stiffness ``K_SN``. Frozen, P is a fixed
point port of the :class:`~components.ballscrew.Ballscrew` (shape functions baked into a constraint).
Here P sits at the nut's *current* axial position ``z = z0 + nut.w`` and is reached through the
Timoshenko shape functions of the element that contains it (Eq 3.27 / A.7, cubic in ξ for bending,
linear for the axial and torsional fields):

.. math::
    d_P(z) = \\sum_e \\chi_e(z)\\, N_e(\\xi_e(z))\\, d_e, \\qquad
    V = \\tfrac12 \\begin{bmatrix} d_P \\\\ d_N \\end{bmatrix}^T K_{SN}
        \\begin{bmatrix} d_P \\\\ d_N \\end{bmatrix},
    \\qquad f = \\frac{\\partial V}{\\partial q} + \\Big(\\frac{\\partial e}{\\partial q}\\Big)^T C\\, \\dot e

(``χ_e`` the indicator of element e, ``e = [d_P; d_N]``). Port forces are gradients of V (virtual work),
so the joint is conservative for C = 0 and forces reach the screw nodes as ``N(z)^T F_P``.

Two uses:

* **position as a parameter**: linearized at ``nut.w = 0`` it equals the frozen joint at ``z0`` (the
  ``∂N/∂z`` terms multiply the interface deflection, zero at rest), and ``z0`` is an ordinary
  (non-structural) parameter: one flattening serves every nut position, which is what makes
  :func:`bscomp.linear.sweeps.position_sweep` fast;
* **moving nut in the time domain**: the nut travels along the screw and the modes change continuously.

The axial + torsional special case is :class:`~components.moving_nut_joint.MovingNutJoint`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError, ParameterError
from bscomp.kernel.component import Component, LinearStructure, Parameter
from bscomp.kernel.ports import Node6

from ._beam_element import _shape_and_derivs
from ._node_dofs import DOF_NAMES

_FLOWS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def element_polynomials(beam) -> np.ndarray:
    """Coefficients ``A[e, k]`` (6x12) with ``N_e(ξ) = Σ_k A[e, k] ξ^k`` (k = 0..3) for every element.

    The Timoshenko shape functions of Eq A.7 are cubic in ξ, so four samples determine them exactly.
    """
    xi = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])
    V = np.vander(xi, 4, increasing=True)                      # (4 samples, 4 powers)
    Vinv = np.linalg.inv(V)
    out = np.empty((len(beam.elem_L), 4, 6, 12))
    for e, (L, pxz, pyz) in enumerate(zip(beam.elem_L, beam.elem_phi_xz, beam.elem_phi_yz, strict=True)):
        N = _shape_and_derivs(xi, L, pxz, pyz)[0]               # (4, 6, 12)
        out[e] = np.einsum("ks,sij->kij", Vinv, N)
    return out


def check_on_screw(comp, z0, z_nodes) -> None:
    """Raise :class:`~bscomp.errors.ParameterError` naming ``z0`` and the screw range unless
    ``z_nodes[0] <= z0 <= z_nodes[-1]`` to round-off (1e-9 of the length; ``z0`` None: not given yet, reported
    by flatten)."""
    tol = 1e-9 * (z_nodes[-1] - z_nodes[0])
    if z0 is None or z_nodes[0] - tol <= z0 <= z_nodes[-1] + tol:
        return
    raise ParameterError(f"{comp._where('z0')}: z0 = {z0!r} m puts the nut off the screw; give a position in "
                         f"[{z_nodes[0]:.6g}, {z_nodes[-1]:.6g}] m (the screw's first and last node)")


class MovingScrewNut(Component):
    """Screw-nut interface (12x12 ``K_SN``, Eq 3.35) attached at the nut's current position (Sec 5.2.2.3).

    Parameters
    ----------
    screw : Ballscrew
        The screw it attaches to (mesh and shape functions at its current parameter values).
    K : (12, 12) array_like
        Interface stiffness, screw point P dofs first then nut dofs (``ScrewNut.stiffness_matrix()``).
    C : (12, 12) array_like, optional
        Interface damping on the same deflections (default none).

    Attributes
    ----------
    n0 ... n<N> : Node6
        Connect to the screw's nodes of the same name.
    nut : Node6
        The nut node at P.
    """

    nut = Node6("nut node at P", optional=False)
    z0 = Parameter(unit="m", doc="position of P along the screw axis when nut.w = 0 (the nut position)")

    def __init__(self, screw, K, C=None, **params):
        beam = screw.beam_model()
        self.z_nodes = np.asarray(beam.z_nodes, float)       # before the parameter check (range of z0)
        super().__init__(**params)
        self.K = np.asarray(K, float)
        self.C = None if C is None else np.asarray(C, float)
        for name, A in (("K", self.K), ("C", self.C)):
            if A is None:
                continue
            if A.shape != (12, 12) or not np.allclose(A, A.T, rtol=1e-10, atol=1e-12 * np.abs(A).max()):
                raise ModelDefinitionError(f"MovingScrewNut: {name} must be a symmetric 12x12 matrix "
                                           f"(screw point P dofs, then nut dofs), got shape {A.shape}")
        self.poly = element_polynomials(beam)
        for i, z in enumerate(self.z_nodes):
            self.add_port(f"n{i}", Node6(f"screw node {i} at z = {z:.6g} m"))

    def check(self, values):
        """``z0`` lies on the screw, ``z_nodes[0] <= z0 <= z_nodes[-1]`` (the shape functions exist there only)."""
        check_on_screw(self, values["z0"], self.z_nodes)

    @classmethod
    def from_screw_nut(cls, screw, screw_nut, z0: float, C=None) -> "MovingScrewNut":
        """The interface of a :class:`~components.screw_nut.ScrewNut` (its K_SN at current values)."""
        return cls(screw, screw_nut.stiffness_matrix(), C=C, z0=z0)

    def template_key(self):
        c = None if self.C is None else self.C.tobytes()
        return (tuple(self.z_nodes), self.K.tobytes(), c, self.poly.tobytes())

    def position(self):
        """Current position of P along the screw [m]."""
        return self.z0 + self.nut.w

    def point_displacement(self, z, nodes):
        """``d_P(z) = A(z) d`` (6 symbols) through the element shape functions.

        Built column block by column block: node n's 6x6 block of ``A(z)`` is ``N_{n-1}(ξ)[:, 6:]`` inside
        element n-1, ``N_n(ξ)[:, :6]`` inside element n and zero elsewhere, so each entry is a cheap
        function of z alone (two cubic branches) and Jacobians stay small expressions.
        """
        zn = self.z_nodes
        ne = len(zn) - 1
        zc = ca.fmin(ca.fmax(z, zn[0]), zn[-1])
        inside, powers = [], []
        for e in range(ne):
            xi = (zc - zn[e]) / (zn[e + 1] - zn[e])
            inside.append(ca.logic_and(zc >= zn[e], zc < zn[e + 1]) if e < ne - 1 else zc >= zn[e])
            powers.append((xi, xi * xi, xi * xi * xi))

        def poly(e, r, c):
            a = self.poly[e, :, r, c]
            if not np.any(a):
                return None
            xi, xi2, xi3 = powers[e]
            a0, a1, a2, a3 = (float(v) for v in a)            # Python floats: no numpy ufunc dispatch on SX
            return a0 + a1 * xi + a2 * xi2 + a3 * xi3

        dP = [ca.SX(0)] * 6
        for n, node in enumerate(nodes):
            for c, dof in enumerate(DOF_NAMES):
                d = getattr(node, dof)
                for r in range(6):
                    left = poly(n - 1, r, c + 6) if n > 0 else None        # node n = 2nd node of element n-1
                    right = poly(n, r, c) if n < ne else None             # node n = 1st node of element n
                    if left is None and right is None:
                        continue
                    a = ca.if_else(inside[n], right, 0.0) if right is not None else ca.SX(0)
                    if left is not None:
                        a = ca.if_else(inside[n - 1], left, a)
                    dP[r] = dP[r] + a * d
        return ca.vertcat(*dP)

    def equations(self):
        nodes = [getattr(self, f"n{i}") for i in range(len(self.z_nodes))]
        d_N = ca.vertcat(*[getattr(self.nut, d) for d in DOF_NAMES])
        e = ca.vertcat(self.point_displacement(self.position(), nodes), d_N)
        q = ca.vertcat(*[getattr(p, d) for p in nodes + [self.nut] for d in DOF_NAMES])
        f = ca.gradient(0.5 * ca.mtimes([e.T, ca.DM(self.K), e]), q)
        if self.C is not None:
            f += ca.mtimes(ca.jacobian(e, q).T, ca.mtimes(ca.DM(self.C), self.der(e)))
        eqs = []
        for k, p in enumerate(nodes + [self.nut]):
            eqs += [getattr(p, fl) - f[6 * k + j] for j, fl in enumerate(_FLOWS)]
        return eqs

    def tangent(self):
        """Exact linearization at rest at the current ``z0``: ``A^T K_SN A`` (and ``A^T C A``) with
        ``A = [N(z0) 0; 0 I]`` mapping the screw nodes and the nut to the interface deflection (the
        ``∂N/∂z`` terms multiply the deflection, zero at rest)."""
        z0 = float(self._values["z0"])
        n_s = 6 * len(self.z_nodes)
        e = int(np.clip(np.searchsorted(self.z_nodes, z0, side="right") - 1, 0, len(self.z_nodes) - 2))
        xi = (z0 - self.z_nodes[e]) / (self.z_nodes[e + 1] - self.z_nodes[e])
        Ne = np.einsum("k,kij->ij", xi ** np.arange(4), self.poly[e])
        B = np.zeros((12, 18))                                   # A restricted to its 18 non-zero columns
        B[:6, :12] = Ne
        B[6:, 12:] = np.eye(6)
        cols = np.r_[6 * e:6 * e + 12, n_s:n_s + 6]
        ii, jj = np.meshgrid(cols, cols, indexing="ij")

        def scatter(X):
            return sp.csr_matrix(((B.T @ X @ B).ravel(), (ii.ravel(), jj.ravel())), shape=(n_s + 6, n_s + 6))

        dofs = [f"n{i}.{d}" for i in range(len(self.z_nodes)) for d in DOF_NAMES] + [f"nut.{d}" for d in DOF_NAMES]
        K = scatter(self.K)
        C = None if self.C is None else scatter(self.C)
        return LinearStructure(dofs=dofs, K=K, C=C)

    def moving_interface(self, value):
        """The joint as a position-dependent interface ``e = E(z) d`` (for ``simulate(method="modal")``).

        ``value(name)`` returns a parameter's value in the run. Returns a dict: ``z_nodes``; ``slow`` (the
        port potential that moves P, ``z = z0 + nut.w``); ``z0``; ``K``, ``C`` (12x12, on ``e``); and per
        element ``(dofs, coef)`` with ``E_e(ξ) = Σ_k ξ^k coef[k]`` over the element's two nodes and the nut
        (Eq 3.27 / A.7; the ``N_e(ξ)`` of :func:`element_polynomials`).
        """
        elements = []
        for e in range(len(self.z_nodes) - 1):
            dofs = [f"n{n}.{d}" for n in (e, e + 1) for d in DOF_NAMES] + [f"nut.{d}" for d in DOF_NAMES]
            coef = np.zeros((4, 12, 18))
            coef[:, :6, :12] = self.poly[e]
            coef[0, 6:, 12:] = np.eye(6)
            elements.append((dofs, coef))
        return {"z_nodes": self.z_nodes, "slow": "nut.w", "z0": float(value("z0")), "K": self.K, "C": self.C,
                "elements": elements}

    def observables(self):
        return {"z": self.position()}
