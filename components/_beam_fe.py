"""Stepped ballscrew shaft of Timoshenko beam elements (thesis Sec. 3.3.1, Appendix A): the uniform
sections of a shaft (rows of a table such as thesis Table B.1), their assembly into global sparse ``M``
and ``K`` with the shape-function interpolation ``N(z)`` of Eq. 3.27, and DOF selection (the axial +
torsional model of Ch. 5).

The element matrices, the DOF order ``(u, v, w, θx, θy, θz)`` and the sign and shear conventions are
those of :mod:`components._beam_element`. All quantities are SI.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ._beam_element import (
    STEEL_E,
    STEEL_NU,
    STEEL_RHO,
    _dof,
    _phi,
    circular_section,
    element_shape_matrix,
    timoshenko_element,
)

__all__ = ["BeamModel", "DofSelection", "Section", "assemble_shaft", "select_dofs"]


# --------------------------------------------------------------------------------------------
# Stepped shaft
# --------------------------------------------------------------------------------------------
@dataclass
class Section:
    """One uniform section of a stepped shaft (a row of thesis Table B.1).

    Attributes
    ----------
    length : float
        Section length [m].
    d_out : float
        Outer diameter used for stiffness [m] (root diameter for a threaded section).
    d_in : float
        Bore diameter [m] (0 = solid).
    n_elements : int
        Number of equal beam elements in the section.
    d_mass : float or None
        Outer diameter used for the mass matrix (equivalent diameter of Eq. 3.1 for a threaded
        section); ``None`` means ``d_out``.  The bore ``d_in`` applies to both.
    name : str
        Label (e.g. ``"C"``).
    """

    length: float
    d_out: float
    d_in: float = 0.0
    n_elements: int = 1
    d_mass: float | None = None
    name: str = ""

    def stiffness_section(self) -> dict:
        """Section properties from ``d_out``/``d_in`` (see :func:`circular_section`)."""
        return circular_section(self.d_out, self.d_in)

    def mass_section(self) -> dict:
        """Section properties from ``d_mass`` (or ``d_out``) and ``d_in``."""
        return circular_section(self.d_out if self.d_mass is None else self.d_mass, self.d_in)

    def mass(self, rho: float) -> float:
        """Section mass [kg] for density ``rho``."""
        return rho * self.mass_section()["A"] * self.length


@dataclass
class BeamModel:
    """Assembled stepped-shaft beam model.

    Attributes
    ----------
    M, K : scipy.sparse.csr_matrix
        Global consistent mass and stiffness matrices, (6 n_nodes)², symmetric.
    z_nodes : numpy.ndarray
        Axial node coordinates [m], ``z_nodes[0] = 0``, increasing.
    n_nodes : int
        Number of nodes.
    elem_L, elem_phi_xz, elem_phi_yz : numpy.ndarray
        Per element length and shear parameters Φ (x-z and y-z bending).
    elem_section : numpy.ndarray
        Index of the :class:`Section` each element belongs to.
    sections : list of Section
        The sections the model was built from.
    """

    M: sp.csr_matrix
    K: sp.csr_matrix
    z_nodes: np.ndarray
    n_nodes: int
    elem_L: np.ndarray
    elem_phi_xz: np.ndarray
    elem_phi_yz: np.ndarray
    elem_section: np.ndarray
    sections: list = field(default_factory=list)

    @property
    def n_dof(self) -> int:
        """Total number of DOF (6 per node)."""
        return 6 * self.n_nodes

    @property
    def length(self) -> float:
        """Total shaft length [m]."""
        return float(self.z_nodes[-1])

    def dof_index(self, node: int, dof: str | int) -> int:
        """Global DOF index of ``dof`` (``'u'|'v'|'w'|'tx'|'ty'|'tz'`` or 0..5) at ``node``.

        Negative ``node`` counts from the end (``-1`` = last node).
        """
        n = int(node)
        if n < 0:
            n += self.n_nodes
        if not 0 <= n < self.n_nodes:
            raise IndexError(f"node {node} out of range (n_nodes={self.n_nodes})")
        return 6 * n + _dof(dof)

    def element_at(self, z: float) -> tuple[int, float]:
        """Element index containing axial position ``z`` and the local coordinate ξ ∈ [0, 1]."""
        zn = self.z_nodes
        tol = 1e-12 * max(1.0, zn[-1])
        if z < zn[0] - tol or z > zn[-1] + tol:
            raise ValueError(f"z={z} outside shaft [0, {zn[-1]}]")
        e = int(np.clip(np.searchsorted(zn, z, side="right") - 1, 0, self.n_nodes - 2))
        xi = float(np.clip((z - zn[e]) / (zn[e + 1] - zn[e]), 0.0, 1.0))
        return e, xi

    def shape_matrix(self, z: float) -> sp.csr_matrix:
        """Interpolation matrix ``N(z)`` (thesis Eq. 3.27 / A.7) of shape (6, 6 n_nodes).

        ``N(z) @ d`` returns ``(u, v, w, θx, θy, θz)`` at axial position ``z`` from the nodal vector
        ``d``, using the Timoshenko shape functions of the element containing ``z``.  At a node it
        selects exactly that node's DOF.  This is how a nut between nodes is attached.
        """
        e, xi = self.element_at(z)
        Ne = element_shape_matrix(xi, self.elem_L[e], self.elem_phi_xz[e], self.elem_phi_yz[e])
        Ne[np.abs(Ne) < 1e-15] = 0.0
        rows = np.repeat(np.arange(6), 12)
        cols = np.tile(np.arange(6 * e, 6 * e + 12), 6)
        out = sp.csr_matrix((Ne.ravel(), (rows, cols)), shape=(6, self.n_dof))
        out.eliminate_zeros()
        return out

    def total_mass(self) -> float:
        """Shaft mass [kg] from the mass matrix (rigid translation along z)."""
        r = np.zeros(self.n_dof)
        r[2::6] = 1.0
        return float(r @ (self.M @ r))


def _resolve_G(E, G, nu):
    if G is not None:
        if nu is not None:
            raise ValueError("give either G or nu, not both")
        return float(G)
    if nu is None:
        raise ValueError("give G or nu")
    return E / (2.0 * (1.0 + nu))


def assemble_shaft(
    sections, *, E: float = STEEL_E, rho: float = STEEL_RHO, G: float | None = None,
    nu: float | None = None, kappa: float = 0.9,
) -> BeamModel:
    """Assemble a stepped shaft of Timoshenko elements (thesis Sec. 3.3.1, Appendix A, Table B.1).

    Parameters
    ----------
    sections : sequence of Section
        Sections in order of increasing z; each is split into ``n_elements`` equal elements.
    E : float
        Young's modulus [Pa] (default steel 210 GPa, thesis App. B.1).
    rho : float
        Density [kg/m³] (default 7800).
    G, nu : float, optional
        Shear modulus [Pa] or Poisson's ratio (``G = E / (2 (1 + ν))``).  If neither is given,
        ``nu = 0.27`` (thesis App. B.1).
    kappa : float
        Shear correction factor (9/10, thesis Eq. A.6).

    Returns
    -------
    BeamModel
    """
    if G is None and nu is None:
        nu = STEEL_NU
    Gv = _resolve_G(E, G, nu)
    sections = list(sections)
    if not sections:
        raise ValueError("need at least one section")
    Ls, phx, phy, sec_of = [], [], [], []
    blocks_K, blocks_M = [], []
    for s_i, s in enumerate(sections):
        if s.n_elements < 1 or s.length <= 0:
            raise ValueError(f"section {s.name or s_i}: need length > 0 and n_elements >= 1")
        ks, ms = s.stiffness_section(), s.mass_section()
        Le = s.length / s.n_elements
        Ke, Me = timoshenko_element(
            Le, E, Gv, ks["A"], ks["Iy"], ks["Ix"], ks["J"], rho,
            A_mass=ms["A"], Iy_mass=ms["Iy"], Ix_mass=ms["Ix"], J_mass=ms["J"], kappa=kappa,
        )
        for _ in range(s.n_elements):
            Ls.append(Le)
            phx.append(_phi(E, Gv, ks["Iy"], ks["A"], Le, kappa))
            phy.append(_phi(E, Gv, ks["Ix"], ks["A"], Le, kappa))
            sec_of.append(s_i)
            blocks_K.append(Ke)
            blocks_M.append(Me)
    n_el = len(Ls)
    n_nodes = n_el + 1
    ndof = 6 * n_nodes
    loc = 6 * np.arange(n_el)[:, None] + np.arange(12)[None, :]
    rows = np.repeat(loc, 12, axis=1).ravel()
    cols = np.tile(loc, (1, 12)).ravel()
    K = sp.coo_matrix((np.stack(blocks_K).ravel(), (rows, cols)), shape=(ndof, ndof)).tocsr()
    M = sp.coo_matrix((np.stack(blocks_M).ravel(), (rows, cols)), shape=(ndof, ndof)).tocsr()
    K = ((K + K.T) * 0.5).tocsr()
    M = ((M + M.T) * 0.5).tocsr()
    z = np.concatenate([[0.0], np.cumsum(Ls)])
    return BeamModel(
        M=M, K=K, z_nodes=z, n_nodes=n_nodes, elem_L=np.array(Ls), elem_phi_xz=np.array(phx),
        elem_phi_yz=np.array(phy), elem_section=np.array(sec_of), sections=sections,
    )


@dataclass
class DofSelection:
    """Subset of the DOF of a :class:`BeamModel` (e.g. the axial + torsional model of thesis Ch. 5).

    Attributes
    ----------
    keep : tuple of str
        Kept DOF names per node.
    index : numpy.ndarray
        Global indices of the kept DOF, node-major (node 0 kept DOF, node 1 ...).
    T : scipy.sparse.csr_matrix
        (n_dof, n_kept) selection matrix, ``d_full = T @ d_kept`` (other DOF set to zero).
    M, K : scipy.sparse.csr_matrix
        Reduced matrices ``Tᵀ M T``, ``Tᵀ K T``.
    """

    keep: tuple
    index: np.ndarray
    T: sp.csr_matrix
    M: sp.csr_matrix
    K: sp.csr_matrix

    def local_index(self, node: int, dof: str | int, n_nodes: int | None = None) -> int:
        """Position of (node, dof) in the reduced vector."""
        k = [_dof(d) for d in self.keep].index(_dof(dof))
        if node < 0:
            if n_nodes is None:
                n_nodes = self.index.size // len(self.keep)
            node += n_nodes
        return node * len(self.keep) + k


def select_dofs(model: BeamModel, keep=("w", "tz")) -> DofSelection:
    """Keep only some DOF per node (thesis Ch. 5 axial-torsional model keeps ``w`` and ``θz``).

    For a straight shaft the axial, torsional and two bending fields are uncoupled in ``K`` and ``M``,
    so keeping e.g. ``('w', 'tz')`` or ``('u', 'ty')`` is exact for that sub-problem (not a
    condensation).

    Parameters
    ----------
    model : BeamModel
    keep : sequence of str
        DOF names among ``'u', 'v', 'w', 'tx', 'ty', 'tz'``.

    Returns
    -------
    DofSelection
    """
    ks = [_dof(k) for k in keep]
    if len(set(ks)) != len(ks):
        raise ValueError(f"duplicate DOF in keep={keep}")
    index = (6 * np.arange(model.n_nodes)[:, None] + np.array(ks)[None, :]).ravel()
    T = sp.csr_matrix((np.ones(index.size), (index, np.arange(index.size))), shape=(model.n_dof, index.size))
    Mr = model.M[index][:, index].tocsr()
    Kr = model.K[index][:, index].tocsr()
    return DofSelection(keep=tuple(keep), index=index, T=T, M=Mr, K=Kr)
