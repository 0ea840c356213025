"""Timoshenko beam elements of the ballscrew shaft (thesis Sec. 3.3.1 and Appendix A): sections, shape
functions, element matrices. The stepped shaft they assemble into is :mod:`components._beam_fe`.

The ballscrew is modelled as a stepped shaft of 2-node Timoshenko beam elements with six
degrees of freedom (DOF) per node (thesis Fig. 3.5 / Fig. A.1, Eq. A.1-A.7).  All quantities are SI.

Conventions
-----------
* **Axes.** ``z`` is the beam (screw) axis; ``x`` and ``y`` are the two radial directions.
* **DOF order per node** (thesis Eq. 3.27): ``(u, v, w, θx, θy, θz)`` = translations along x, y, z and
  small rotations about x, y, z.  Global DOF ``6*node + k``; node 0 sits at ``z = 0``.
* **Sign convention (right-hand rule).**  A small rigid rotation ``θy`` about +y moves a point at
  axial offset ``z`` by ``u = +θy z``; a small rotation ``θx`` about +x moves it by ``v = -θx z``
  (rows of ``[I, -S(r)]`` in thesis Eq. 3.3/3.26 with ``r = (0, 0, z)``).  Hence, in the
  Euler-Bernoulli limit, ``θy = +du/dz`` and ``θx = -dv/dz``.  Bending in the x-z plane couples
  ``(u, θy)`` with the Appendix A functions unchanged; bending in the y-z plane couples ``(v, θx)``
  with the same functions applied to ``ψ = -θx``.  Thesis Eq. (3.27)/(A.7) writes both planes
  with identical functions and does not show this sign flip; it is required for a right-handed frame
  (without it, a rigid rotation about x would strain the element).
* **Shear correction.**  ``Φ = 12 E I / (κ G A L²)`` (thesis Eq. A.6, there written ``k_i^s``) with
  ``κ = 9/10`` for circular cross sections as stated below Eq. (A.6).  The same κ is used for hollow
  sections (the thesis does not distinguish them).  Bending in the x-z plane (u, θy) uses
  ``Iy = ∫ x² dA``; bending in the y-z plane (v, θx) uses ``Ix = ∫ y² dA``.  The thesis's
  ``i/j`` index pairing in Eq. (A.3)-(A.6) is ambiguous; for the (circular) ballscrew ``Ix = Iy``.
* **Torsion** stiffness ``G J / L`` with ``J`` the polar moment (thesis ``I_zz``, exact torsion
  constant for solid and hollow circles); **axial** stiffness ``E A / L``.
* **Mass.**  Consistent mass including rotary inertia, obtained by integrating the Eq. (A.7) shape
  functions; the closed form used here is Przemieniecki's.  The extracted thesis Eq. (A.4) carries sign
  slips in its rotary-inertia terms (e.g. ``m6``); this module uses the corrected form, verified
  against Gauss quadrature of the shape functions (:func:`timoshenko_element_quadrature`).
* **Threaded section.**  Stiffness from the root diameter, mass from the equivalent diameter
  (thesis Eq. 3.1): element functions take separate stiffness (``A, Iy, Ix, J``) and mass
  (``A_mass, ...``) section properties.  The shape functions (and Φ) always come from the stiffness
  section.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DOF_NAMES",
    "STEEL_E",
    "STEEL_NU",
    "STEEL_RHO",
    "circular_section",
    "element_shape_matrix",
    "equivalent_diameter",
    "timoshenko_element",
    "timoshenko_element_quadrature",
]

#: DOF names per node, in order (thesis Eq. 3.27).
DOF_NAMES = ("u", "v", "w", "tx", "ty", "tz")
_DOF_ALIASES = {
    "u": 0, "x": 0, "v": 1, "y": 1, "w": 2, "z": 2,
    "tx": 3, "thetax": 3, "θx": 3, "ty": 4, "thetay": 4, "θy": 4, "tz": 5, "thetaz": 5, "θz": 5,
}

#: Ballscrew steel, thesis Appendix B.1: ρ = 7800 kg/m³, E = 210 GPa, ν = 0.27.
STEEL_E = 210e9
STEEL_NU = 0.27
STEEL_RHO = 7800.0

# local plane DOFs (w1, psi1, w2, psi2) -> element DOF indices and signs (psi = theta for x-z, -theta for y-z)
_XZ_IDX = np.array([0, 4, 6, 10])
_XZ_SGN = np.array([1.0, 1.0, 1.0, 1.0])
_YZ_IDX = np.array([1, 3, 7, 9])
_YZ_SGN = np.array([1.0, -1.0, 1.0, -1.0])


def _dof(name: str | int) -> int:
    if isinstance(name, (int, np.integer)):
        if not 0 <= int(name) < 6:
            raise ValueError(f"DOF index must be 0..5, got {name}")
        return int(name)
    try:
        return _DOF_ALIASES[str(name).lower()]
    except KeyError:
        raise ValueError(f"unknown DOF name {name!r}; expected one of {DOF_NAMES}") from None


# --------------------------------------------------------------------------------------------
# Cross sections
# --------------------------------------------------------------------------------------------
def circular_section(d_out: float, d_in: float = 0.0) -> dict:
    """Section properties of a solid or hollow circle.

    Parameters
    ----------
    d_out : float
        Outer diameter [m].
    d_in : float, optional
        Inner (bore) diameter [m], 0 for a solid shaft.

    Returns
    -------
    dict
        ``A`` area [m²], ``Ix``, ``Iy`` second moments of area about x and y [m⁴], ``J`` polar
        moment ``Ix + Iy`` [m⁴] (thesis ``I_zz``; also the torsion constant of a circle).
    """
    if d_out <= 0 or d_in < 0 or d_in >= d_out:
        raise ValueError(f"need 0 <= d_in < d_out, got d_out={d_out}, d_in={d_in}")
    A = np.pi / 4.0 * (d_out**2 - d_in**2)
    I = np.pi / 64.0 * (d_out**4 - d_in**4)
    return {"A": A, "Ix": I, "Iy": I, "J": 2.0 * I}


def equivalent_diameter(d_r: float, L: float, V_threads: float) -> float:
    """Equivalent mass diameter of a threaded section, thesis Eq. (3.1).

    ``d_e = sqrt(4 (π d_r² L / 4 + V_threads) / (π L))``: a cylinder of diameter ``d_e`` has the
    mass of the root cylinder plus the threads.

    Parameters
    ----------
    d_r : float
        Root diameter [m].
    L : float
        Length of the threaded section [m].
    V_threads : float
        Total volume of the threads [m³].

    Returns
    -------
    float
        Equivalent diameter [m].
    """
    return float(np.sqrt(4.0 * (np.pi * d_r**2 / 4.0 * L + V_threads) / (np.pi * L)))


# --------------------------------------------------------------------------------------------
# Element
# --------------------------------------------------------------------------------------------
def _plane_shape(xi, L: float, phi: float):
    """Appendix A Eq. (A.7) functions for one bending plane and their ξ-derivatives.

    Returns ``Nw, Nt, dNw, dNt`` each of shape (4, n) for local DOFs ``(w1, ψ1, w2, ψ2)``; ψ is the
    section rotation with ψ = dw/dz in the Euler-Bernoulli limit.  ``dN`` are d/dξ.
    (The extracted thesis labels the last rotation function ``N_θj3`` twice; it is ``N_θj4``.)
    """
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    c = 1.0 / (1.0 + phi)
    x2, x3 = xi**2, xi**3
    Nw = c * np.array([
        2 * x3 - 3 * x2 - phi * xi + (1 + phi),
        L * (x3 - (2 + phi / 2) * x2 + (1 + phi / 2) * xi),
        -(2 * x3 - 3 * x2 - phi * xi),
        L * (x3 - (1 - phi / 2) * x2 - (phi / 2) * xi),
    ])
    dNw = c * np.array([
        6 * x2 - 6 * xi - phi,
        L * (3 * x2 - (4 + phi) * xi + (1 + phi / 2)),
        -(6 * x2 - 6 * xi - phi),
        L * (3 * x2 - (2 - phi) * xi - phi / 2),
    ])
    Nt = c * np.array([
        6.0 / L * (x2 - xi),
        3 * x2 - (4 + phi) * xi + (1 + phi),
        -6.0 / L * (x2 - xi),
        3 * x2 - (2 - phi) * xi,
    ])
    dNt = c * np.array([
        6.0 / L * (2 * xi - 1),
        6 * xi - (4 + phi),
        -6.0 / L * (2 * xi - 1),
        6 * xi - (2 - phi),
    ])
    return Nw, Nt, dNw, dNt


def _shape_and_derivs(xi, L: float, phi_xz: float, phi_yz: float):
    """6x12 shape matrix N and dN/dz at each ξ (arrays of shape (n, 6, 12))."""
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    n = xi.size
    N = np.zeros((n, 6, 12))
    D = np.zeros((n, 6, 12))
    for (row_w, row_t, idx, sgn, phi) in ((0, 4, _XZ_IDX, _XZ_SGN, phi_xz), (1, 3, _YZ_IDX, _YZ_SGN, phi_yz)):
        Nw, Nt, dNw, dNt = _plane_shape(xi, L, phi)
        # theta = +psi (x-z plane) or -psi (y-z plane); psi-DOF columns carry sgn
        t_sign = 1.0 if row_t == 4 else -1.0
        N[:, row_w, idx] = (Nw * sgn[:, None]).T
        D[:, row_w, idx] = (dNw * sgn[:, None]).T / L
        N[:, row_t, idx] = t_sign * (Nt * sgn[:, None]).T
        D[:, row_t, idx] = t_sign * (dNt * sgn[:, None]).T / L
    lin = np.stack([1.0 - xi, xi], axis=1)
    for row, (a, b) in ((2, (2, 8)), (5, (5, 11))):
        N[:, row, a] = lin[:, 0]
        N[:, row, b] = lin[:, 1]
        D[:, row, a] = -1.0 / L
        D[:, row, b] = 1.0 / L
    return N, D


def element_shape_matrix(xi: float, L: float, phi_xz: float, phi_yz: float) -> np.ndarray:
    """Shape-function matrix ``T_BSξ-BSi`` of thesis Eq. (3.27) with the functions of Eq. (A.7).

    Parameters
    ----------
    xi : float
        Non-dimensional position in the element, 0 at node 1 and 1 at node 2.
    L : float
        Element length [m].
    phi_xz, phi_yz : float
        Shear parameters Φ (Eq. A.6) of bending in the x-z plane (u, θy; uses ``Iy``) and in the
        y-z plane (v, θx; uses ``Ix``).

    Returns
    -------
    numpy.ndarray
        (6, 12) matrix mapping ``(u1, v1, w1, θx1, θy1, θz1, u2, ..., θz2)`` to
        ``(u, v, w, θx, θy, θz)`` at ξ, with the right-hand sign convention of this module.
    """
    return _shape_and_derivs(xi, L, phi_xz, phi_yz)[0][0]


def _phi(E, G, I, A, L, kappa):
    return 12.0 * E * I / (kappa * G * A * L**2)


def _plane_stiffness(EI: float, L: float, phi: float) -> np.ndarray:
    c = EI / (L**3 * (1.0 + phi))
    L2 = L * L
    return c * np.array([
        [12.0, 6 * L, -12.0, 6 * L],
        [6 * L, (4 + phi) * L2, -6 * L, (2 - phi) * L2],
        [-12.0, -6 * L, 12.0, -6 * L],
        [6 * L, (2 - phi) * L2, -6 * L, (4 + phi) * L2],
    ])


def _plane_mass(rhoA: float, rhoI: float, L: float, phi: float) -> np.ndarray:
    """Przemieniecki consistent Timoshenko mass for one plane, DOFs (w1, ψ1, w2, ψ2).

    Corrected form of thesis Eq. (A.4) (translational ``m1, m3, m5, m6, m9, m10`` and rotary parts).
    """
    p, p2, L2 = phi, phi * phi, L * L
    d = (1.0 + p) ** 2
    a11 = 13 / 35 + 7 / 10 * p + p2 / 3
    a12 = (11 / 210 + 11 / 120 * p + p2 / 24) * L
    a13 = 9 / 70 + 3 / 10 * p + p2 / 6
    a14 = (13 / 420 + 3 / 40 * p + p2 / 24) * L
    a22 = (1 / 105 + p / 60 + p2 / 120) * L2
    a24 = (1 / 140 + p / 60 + p2 / 120) * L2
    Mt = rhoA * L / d * np.array([
        [a11, a12, a13, -a14],
        [a12, a22, a14, -a24],
        [a13, a14, a11, -a12],
        [-a14, -a24, -a12, a22],
    ])
    b12 = (1 / 10 - p / 2) * L
    b22 = (2 / 15 + p / 6 + p2 / 3) * L2
    b24 = (-1 / 30 - p / 6 + p2 / 6) * L2
    Mr = rhoI / (L * d) * np.array([
        [6 / 5, b12, -6 / 5, b12],
        [b12, b22, -b12, b24],
        [-6 / 5, -b12, 6 / 5, -b12],
        [b12, b24, -b12, b22],
    ])
    return Mt + Mr


def _mass_props(A, Iy, Ix, J, A_mass, Iy_mass, Ix_mass, J_mass):
    return (
        A if A_mass is None else A_mass,
        Iy if Iy_mass is None else Iy_mass,
        Ix if Ix_mass is None else Ix_mass,
        J if J_mass is None else J_mass,
    )


def timoshenko_element(
    L: float, E: float, G: float, A: float, Iy: float, Ix: float, J: float, rho: float,
    A_mass: float | None = None, Iy_mass: float | None = None, Ix_mass: float | None = None,
    J_mass: float | None = None, kappa: float = 0.9,
) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass matrices of a 2-node Timoshenko beam element (thesis Eq. A.1-A.7).

    Parameters
    ----------
    L : float
        Element length [m].
    E, G : float
        Young's and shear modulus [Pa].
    A, Iy, Ix, J : float
        Stiffness section: area [m²], second moments ``Iy = ∫x² dA`` (x-z bending, u/θy) and
        ``Ix = ∫y² dA`` (y-z bending, v/θx) [m⁴], torsion constant / polar moment [m⁴].
    rho : float
        Density [kg/m³].
    A_mass, Iy_mass, Ix_mass, J_mass : float, optional
        Mass section (e.g. from the equivalent diameter of Eq. 3.1); default to the stiffness section.
    kappa : float, optional
        Shear correction factor κ (thesis ``k^s``, 9/10 for circular sections, below Eq. A.6).

    Returns
    -------
    Ke, Me : numpy.ndarray
        (12, 12) symmetric matrices, DOFs ``(u1, v1, w1, θx1, θy1, θz1, u2, ..., θz2)``.

    Notes
    -----
    ``Φ = 12 E I / (κ G A L²)`` per plane (Eq. A.6).  Stiffness per Eq. (A.3); mass is Przemieniecki's
    consistent Timoshenko mass with rotary inertia ``ρ I``, equal to the integral of the Eq. (A.7) shape
    functions (Eq. A.4 of the extracted thesis has sign slips in the rotary terms).  Axial and torsional
    parts use linear shape functions (``m2 = 1/3, m7 = 1/6`` of Eq. A.4).
    """
    Am, Iym, Ixm, Jm = _mass_props(A, Iy, Ix, J, A_mass, Iy_mass, Ix_mass, J_mass)
    Ke = np.zeros((12, 12))
    Me = np.zeros((12, 12))
    for idx, sgn, I, Im in ((_XZ_IDX, _XZ_SGN, Iy, Iym), (_YZ_IDX, _YZ_SGN, Ix, Ixm)):
        phi = _phi(E, G, I, A, L, kappa)
        S = np.outer(sgn, sgn)
        Ke[np.ix_(idx, idx)] += S * _plane_stiffness(E * I, L, phi)
        Me[np.ix_(idx, idx)] += S * _plane_mass(rho * Am, rho * Im, L, phi)
    bar = np.array([[1.0, -1.0], [-1.0, 1.0]])
    cons = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6.0
    for idx, k, m in (([2, 8], E * A / L, rho * Am * L), ([5, 11], G * J / L, rho * Jm * L)):
        Ke[np.ix_(idx, idx)] += k * bar
        Me[np.ix_(idx, idx)] += m * cons
    return Ke, Me


def timoshenko_element_quadrature(
    L: float, E: float, G: float, A: float, Iy: float, Ix: float, J: float, rho: float,
    A_mass: float | None = None, Iy_mass: float | None = None, Ix_mass: float | None = None,
    J_mass: float | None = None, kappa: float = 0.9, n_gauss: int = 6,
) -> tuple[np.ndarray, np.ndarray]:
    """Element matrices by Gauss quadrature of the Eq. (A.7) shape functions (reference/check).

    ``K = ∫ [E Iy θy'² + κGA (u' - θy)² + E Ix θx'² + κGA (v' + θx)² + EA w'² + GJ θz'²] dz`` and
    ``M = ∫ [ρA_m (u² + v² + w²) + ρ Iy_m θy² + ρ Ix_m θx² + ρ J_m θz²] dz`` (as quadratic forms).
    Same arguments and return value as :func:`timoshenko_element`.
    """
    Am, Iym, Ixm, Jm = _mass_props(A, Iy, Ix, J, A_mass, Iy_mass, Ix_mass, J_mass)
    phi_xz = _phi(E, G, Iy, A, L, kappa)
    phi_yz = _phi(E, G, Ix, A, L, kappa)
    g, wg = np.polynomial.legendre.leggauss(n_gauss)
    xi = 0.5 * (g + 1.0)
    wz = 0.5 * wg * L
    N, D = _shape_and_derivs(xi, L, phi_xz, phi_yz)
    mdiag = rho * np.array([Am, Am, Am, Ixm, Iym, Jm])
    Ke = np.zeros((12, 12))
    Me = np.zeros((12, 12))
    kGA = kappa * G * A
    for q in range(xi.size):
        Nq, Dq = N[q], D[q]
        Me += wz[q] * Nq.T @ (mdiag[:, None] * Nq)
        gxz = Dq[0] - Nq[4]          # shear strain in x-z plane: u' - θy
        gyz = Dq[1] + Nq[3]          # shear strain in y-z plane: v' + θx
        Ke += wz[q] * (
            E * Iy * np.outer(Dq[4], Dq[4]) + E * Ix * np.outer(Dq[3], Dq[3])
            + kGA * (np.outer(gxz, gxz) + np.outer(gyz, gyz))
            + E * A * np.outer(Dq[2], Dq[2]) + G * J * np.outer(Dq[5], Dq[5])
        )
    return Ke, Me
