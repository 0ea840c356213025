r"""Position-dependent joints for ``simulate(method="modal")``: the moving screw-nut interface as a low-rank,
position-dependent correction to a linear part that holds the joint frozen at a reference position.

A joint whose contact point moves with a slow coordinate (thesis Sec 5.2.2.3: the nut travelling along the
screw, :class:`~components.moving_screw_nut.MovingScrewNut`, :class:`~components.moving_nut_joint.MovingNutJoint`)
declares itself through ``component.moving_interface(value)``: an interface deflection ``e = E(z) d`` on its
port potentials ``d``, with ``z = z_0 + d_s`` (``d_s`` the slow potential, the nut's axial displacement) and
``E`` a polynomial in the element coordinate ``ξ`` on each screw element (Eq 3.27 / A.7), and the interface
matrices ``K``, ``C`` (Eq 3.35). Its energy and dissipation are ``V = ½ e^T K e``, ``D = ½ ė^T C ė``, so the
port forces are (virtual work, as the components state them)

.. math::
    f(d, \dot d) = J^T (K e + C J \dot d), \qquad J = \frac{\partial e}{\partial d}
    = E(z) + E'(z)\, d\, \mathbf{1}_s^T, \qquad \dot e = J \dot d .

The linear part of the simulation holds the tangent at rest at a reference position ``z_r``,
``K_r = E(z_r)^T K E(z_r)`` (``C_r`` alike: what linearizing the DAE at ``z_0 = z_r`` gives), so the
correction force

.. math:: g(d, \dot d) = f(d, \dot d) - K_r d - C_r \dot d

is exact and acts only on the potentials of the element that holds ``z`` and of the element that holds
``z_r`` (plus the nut): a few of the screw's hundreds of coordinates (:class:`MovingJoint` gives the maps,
:mod:`bscomp.simulation.modal_laws` the expressions on a set ``S`` of those potentials, the step's Newton unknowns).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError

__all__ = ["MovingJoint", "find_moving_joints"]


def find_moving_joints(system) -> list:
    """``(path, component)`` of every component that declares a position-dependent interface."""
    return [(p, c) for p, c in system.leaves() if callable(getattr(c, "moving_interface", None))]


class MovingJoint:
    """One position-dependent joint of a flattened model (see the module docstring).

    Parameters
    ----------
    dae : Dae
        The flattened model holding the joint.
    path : str
        The joint's component path (``"sn"``).
    comp : Component
        The joint.
    p : ndarray
        Parameter vector of the run (the joint's ``z0`` and stiffness parameters are read from it).

    Attributes
    ----------
    P : scipy.sparse.csr_matrix (n_d, n_q)
        Reduced coordinates -> the joint's active port potentials ``d`` (those that are coordinates).
    dof_names : list of str
        Names of the active potentials (``"n12.w"``...).
    slow : int
        Index of the slow potential in ``d``, or -1 when the nut cannot move (the joint is then linear).
    """

    def __init__(self, dae, path, comp, p):
        self.path = path
        names = dae.p_names

        def value(n):
            full = f"{path}.{n}"
            return float(p[names.index(full)]) if full in names else float(comp._values[n])

        info = comp.moving_interface(value)
        self.z_nodes = np.asarray(info["z_nodes"], float)
        self.z0 = float(info["z0"])
        self.K = np.asarray(info["K"], float)
        self.C = None if info.get("C") is None else np.asarray(info["C"], float)
        m = dae.mech
        T = sp.csr_matrix(m.T)
        t0 = np.asarray(m.t0, float).ravel()
        order = list(dict.fromkeys(d for dofs, _ in info["elements"] for d in dofs))
        rows = []
        for d in order:
            key = f"{path}.{d}"
            if key not in m.port_coordinates:
                raise ModelDefinitionError(f"{path}: port potential '{d}' of its moving interface is not in the model")
            c = m.port_coordinates[key]
            if t0[c] != 0.0:
                raise ModelDefinitionError(f"{path}.{d} is offset by a constraint (t0 = {t0[c]:.3g}): the moving joint "
                                           "needs its ports at zero at rest")
            rows.append(c)
        Pall = T[np.asarray(rows, int)].tocsr()
        active = np.flatnonzero(np.diff(Pall.indptr) > 0)
        self.dof_names = [order[i] for i in active]
        self.P = Pall[active]
        where = {order[i]: k for k, i in enumerate(active)}
        self.slow = where.get(info["slow"], -1)
        # per element: the active columns and the polynomial coefficients on them
        self.elements = []
        for dofs, coef in info["elements"]:
            keep = [j for j, d in enumerate(dofs) if d in where]
            self.elements.append((np.array([where[dofs[j]] for j in keep], int), np.asarray(coef, float)[:, :, keep]))
        self.m = self.K.shape[0]
        self.n = len(self.dof_names)
        used = np.zeros(self.m, bool)
        for _, coef in self.elements:
            used |= np.any(coef != 0, axis=(0, 2))
        self.eff_rows = np.flatnonzero(used)        # rows of e that active potentials can move
        self.m_eff = self.eff_rows.size

    # ---- geometry -------------------------------------------------------------------------------------
    @property
    def is_linear(self) -> bool:
        """True when the slow potential is not a coordinate (the contact point cannot move)."""
        return self.slow < 0

    def element_of(self, z: float) -> int:
        """Element holding position ``z`` (clamped to the screw, as the component does)."""
        zn = self.z_nodes
        return min(max(int(np.searchsorted(zn, z, side="right")) - 1, 0), len(zn) - 2)

    def position(self, d_slow: float) -> float:
        """Contact-point position ``z = z0 + d_s`` [m]."""
        return self.z0 + float(d_slow)

    def E(self, z: float):
        """``(cols, E, dE/dz)`` at ``z``: the active columns of its element and the (m, len(cols)) maps."""
        e = self.element_of(z)
        cols, coef = self.elements[e]
        L = self.z_nodes[e + 1] - self.z_nodes[e]
        xi = float(np.clip((z - self.z_nodes[e]) / L, 0.0, 1.0))
        E = sum(coef[k] * xi ** k for k in range(4))
        inside = self.z_nodes[0] <= z <= self.z_nodes[-1]
        dE = sum(k * coef[k] * xi ** (k - 1) for k in range(1, 4)) / L if inside else np.zeros_like(E)
        return cols, E, dE

    def tangent(self, z_r: float):
        """``(K_r, C_r)`` dense (n, n) on the active potentials: the joint's tangent at rest at ``z_r``."""
        cols, E, _ = self.E(z_r)
        Kr = np.zeros((self.n, self.n))
        Kr[np.ix_(cols, cols)] = E.T @ self.K @ E
        Cr = None
        if self.C is not None:
            Cr = np.zeros((self.n, self.n))
            Cr[np.ix_(cols, cols)] = E.T @ self.C @ E
        return Kr, Cr

    def force(self, d, dd=None):
        """Exact port forces ``f(d, ḋ)`` on the active potentials (numpy; the module docstring's formula)."""
        d = np.asarray(d, float)
        z = self.position(d[self.slow]) if self.slow >= 0 else self.z0
        cols, E, dE = self.E(z)
        e = E @ d[cols]
        J = np.zeros((self.m, self.n))
        J[:, cols] = E
        if self.slow >= 0:
            J[:, self.slow] += dE @ d[cols]
        F = self.K @ e
        if self.C is not None and dd is not None:
            F = F + self.C @ (J @ np.asarray(dd, float))
        return J.T @ F

    def dofs_for(self, elems, z_r: float) -> np.ndarray:
        """Active potentials the correction touches while the contact point is in ``elems``: those of the
        elements and of z_r's element, sorted, with the slow potential last."""
        cols = np.unique(np.concatenate([self.elements[e][0] for e in elems]
                                        + [self.elements[self.element_of(z_r)][0]]))
        cols = cols[cols != self.slow]
        return np.append(cols, self.slow).astype(int)
