"""Screw-nut interface stiffness of a ballscrew drive (thesis Section 3.3.4, Appendix B.6).

Pure numpy/scipy implementation of the two lumping methods of the thesis:

* the **rigid-ballscrew method** (Eq 3.12-3.16, 3.30-3.35): the screw section inside the nut
  moves as a rigid body, described by a 6-DOF screw point P (on the screw axis, coincident
  with the nut node); the result is a 12x12 matrix ``K_SN`` (screw DOF first, nut DOF last);
* the **shape-function method** (Eq 3.17-3.29, 3.36-3.39): the screw displacement at each
  ball's axial position is interpolated from the screw's FE nodes by a user-supplied
  ``shape_matrix(z)`` (6 x ndof), giving an (ndof + 6) x (ndof + 6) matrix.

The ball-stiffness relations (Eq 3.40-3.43) and the nut geometry of Appendix B.6 (Eq B.2-B.4) are in
:mod:`components._nut_geometry`.

Conventions
-----------
* SI units throughout (m, rad, N/m); ``k_ball`` in N/m.
* DOF order of every node: ``(u, v, w, theta_x, theta_y, theta_z)``, ``z`` = screw axis.
* Small rotations: the displacement of a point at offset ``r`` from a node is
  ``u + theta x r = [I, -S(r)] {u; theta}`` (Eq 3.16), ``S(r)`` the cross-product matrix.
* Ball centre path (Eq 3.12): ``r(phi) = (R sin(phi), -R cos(phi), hand * r_g * phi)`` measured
  from P, ``phi`` counter-clockwise about +z. ``hand=+1`` (default, the thesis) is a right-hand
  thread; ``hand=-1`` mirrors it (left-hand thread), implemented as ``alpha -> -alpha``,
  ``r_g -> -r_g``.
* The contact normal ``n`` (unit vector along ``k_Ball``, CS_1 z-axis, Eq 3.7-3.11) points from the
  screw contact point to the nut contact point (radially outward). Its axial component is
  ``+cos(alpha) cos(beta)`` for the lower (L) and ``-cos(alpha) cos(beta)`` for the upper (U)
  contact.

Only the relative displacement of the two contact points along ``n`` loads a ball, so the
ball radius offset ``r_Ball = R_Ball n`` (Eq 3.14-3.15) changes neither the rigid-method
stiffness nor its moments (``(r +/- R_Ball n) x n = r x n``); it is kept for fidelity and
matters only in the shape-function method through the axial position of the contact point
(which the thesis, and this module, neglect: the screw section is evaluated at the ball
centre's axial position, Eq 3.18-3.24).

Properties (all tested)
-----------------------
* For the test bed (Table 3.1 / B.3) ``ksn_rigid`` reproduces all ten coefficients of Eq 3.45 with
  the thesis' signs (lengths in m), e.g. ``k_z,thz = -0.1307 k_Ball``; rotations are in the
  right-hand sense about the global axes, the thread is right-handed.
* ``K_SN = [[A, -A], [-A, A]]`` (P is both screw point and nut node), symmetric PSD, rank 5 when
  ``r_g = R tan(alpha)``: the six common rigid-body motions **and** the relative helical motion
  ``w_N - w_BS = hand * r_g (thz_N - thz_BS)`` (the nut running along the thread) are free.
  Note ``k_zz k_thz,thz = k_z,thz^2`` in Eq 3.45 (82.1 x 0.000208 ~ 0.130^2). A model that clamps
  the screw and the nut's rotation only through ``K_SN`` is therefore singular in that mode.
* ``K_SN[2, 2] = k_Ball N_Ball cos^2(alpha) cos^2(beta)`` (x2 oversize) exactly: Eq 3.40 / 3.41.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.sparse import csr_matrix

from ._nut_geometry import _check_preload

__all__ = [
    "rot_x",
    "rot_y",
    "rot_z",
    "skew",
    "contact_normal",
    "ball_centre",
    "contact_vectors",
    "ball_transformations",
    "ball_stiffness_rigid",
    "ball_layout",
    "ksn_rigid",
    "ksn_shape_function",
    "rigid_screw_shape_matrix",
    "rigid_point_map",
]

# ---------------------------------------------------------------------------------------------
# Elementary rotations (Eq A.8) and the cross-product matrix
# ---------------------------------------------------------------------------------------------
def rot_x(t: float) -> np.ndarray:
    """Rotation matrix about x (Eq A.8)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(t: float) -> np.ndarray:
    """Rotation matrix about y (Eq A.8)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(t: float) -> np.ndarray:
    """Rotation matrix about z (Eq A.8)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def skew(r: np.ndarray) -> np.ndarray:
    """Cross-product (tensor) matrix ``S(r)`` with ``S(r) @ x == np.cross(r, x)`` (Sec 3.3.2)."""
    x, y, z = r
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _check_config(config: str) -> str:
    c = config.upper()
    if c not in ("L", "U"):
        raise ValueError(f"contact configuration must be 'L' or 'U', got {config!r}")
    return c


# ---------------------------------------------------------------------------------------------
# First stage: local -> global (Eq 3.6-3.11)
# ---------------------------------------------------------------------------------------------
def contact_normal(phi: float, alpha: float, beta: float, config: str = "L", hand: int = 1) -> np.ndarray:
    """Unit contact normal ``T_{3-z1L}`` / ``T_{3-z1U}`` of a ball at azimuth ``phi`` (Eq 3.7-3.11).

    Parameters
    ----------
    phi : float
        Azimuth angle of the ball centre [rad] (Fig 3.14).
    alpha : float
        Pitch (helix) angle [rad], Eq 3.6.
    beta : float
        Contact (mean thread) angle [rad].
    config : {'L', 'U'}
        Lower or upper contact configuration (Fig 3.13).
    hand : {1, -1}
        Thread hand; ``+1`` is the thesis' right-hand helix.

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``T_{3-2} T_{2-1} {0, 0, 1}^T`` in CS_3 (global axes).
    """
    a = hand * alpha
    if _check_config(config) == "L":
        t21 = rot_y(-a) @ rot_x(beta)  # Eq 3.7
        t32 = rot_z(phi)  # Eq 3.10
    else:
        t21 = rot_y(a) @ rot_x(-beta)  # Eq 3.8
        t32 = rot_z(phi) @ np.diag([1.0, -1.0, -1.0])  # Eq 3.10
    return t32 @ t21 @ np.array([0.0, 0.0, 1.0])  # Eq 3.9, 3.11


def ball_centre(phi: float, R: float, r_g: float, hand: int = 1) -> np.ndarray:
    """Position ``r`` of a ball centre from the nut point P (Eq 3.12)."""
    return np.array([R * np.sin(phi), -R * np.cos(phi), hand * r_g * phi])


def contact_vectors(
    phi: float,
    alpha: float,
    beta: float,
    R: float,
    r_g: float,
    R_ball: float = 0.0,
    config: str = "L",
    hand: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contact position vectors ``r_BS`` and ``r_N`` from P and the normal ``n`` (Eq 3.12-3.15).

    Returns
    -------
    r_bs, r_n, n : numpy.ndarray, each shape (3,)
        ``r_BS = r - R_Ball n``, ``r_N = r + R_Ball n`` (Eq 3.14, 3.15) and the unit normal.
    """
    n = contact_normal(phi, alpha, beta, config, hand)
    r = ball_centre(phi, R, r_g, hand)
    r_ball = R_ball * n  # Eq 3.15
    return r - r_ball, r + r_ball, n


def ball_transformations(
    phi: float,
    alpha: float,
    beta: float,
    R: float,
    r_g: float,
    R_ball: float = 0.0,
    config: str = "L",
    hand: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Row transformations ``T_{z1-BS}`` and ``T_{z1-N}`` (1 x 6 each) of one ball (Eq 3.16, 3.31-3.32).

    ``T_{z1-BS} = n^T [I, -S(r_BS)] = [n^T, (r_BS x n)^T]``, and likewise for the nut.
    """
    r_bs, r_n, n = contact_vectors(phi, alpha, beta, R, r_g, R_ball, config, hand)
    t_bs = n @ np.hstack([np.eye(3), -skew(r_bs)])
    t_n = n @ np.hstack([np.eye(3), -skew(r_n)])
    return t_bs, t_n


def ball_stiffness_rigid(
    k_ball: float,
    phi: float,
    alpha: float,
    beta: float,
    R: float,
    r_g: float,
    R_ball: float = 0.0,
    config: str = "L",
    hand: int = 1,
) -> np.ndarray:
    """12x12 stiffness ``K_L`` or ``K_U`` of one ball at azimuth ``phi`` (Eq 3.30-3.34).

    Rows/columns: screw point P DOF (6) then nut node DOF (6).
    """
    t_bs, t_n = ball_transformations(phi, alpha, beta, R, r_g, R_ball, config, hand)
    t = np.concatenate([-t_bs, t_n])  # K_Ball = k [[1,-1],[-1,1]] on (d_BS, d_N) (Eq 3.30, 3.33)
    return k_ball * np.outer(t, t)


# ---------------------------------------------------------------------------------------------
# Ball layout and quadrature over azimuth ranges (Eq 3.35, 3.39)
# ---------------------------------------------------------------------------------------------
def ball_layout(
    n_ball: int,
    phi_range: tuple[float, float] | np.ndarray,
    preload: str = "oversize",
    two_point_layout: str = "interleaved",
) -> list[tuple[float, float, tuple[str, ...], float]]:
    """Groups of balls: ``(phi_st, phi_end, configs, count)``.

    Parameters
    ----------
    n_ball : int
        Number of balls in contact, ``N_Ball``.
    phi_range : (phi_st, phi_end) or array of shape (n_ball, 2)
        Azimuth motion range [rad] shared by all balls (Eq B.2) or one range per ball.
    preload : {'spacer', 'offset', 'oversize'}
        ``'oversize'``: every ball contacts L and U (four-point contact, Eq 3.41).
        ``'spacer'``/``'offset'``: two-point contact, half the balls L and half U (Sec 3.3.4).
    two_point_layout : {'interleaved', 'lower_first', 'upper_first'}
        Where the L and U balls of a two-point preload sit when a single shared ``phi_range`` is
        given. ``'interleaved'`` (default): both halves travel the whole range (the thesis'
        uniform-distribution assumption, App B.6). ``'lower_first'``: L balls in the first
        half of the range (``phi_st`` .. mid), U balls in the second half, as in a double nut;
        ``'upper_first'`` the reverse. With per-ball ranges, the first half of the rows
        (``n_ball // 2``) are L, the rest U.
    """
    preload = _check_preload(preload)
    rng = np.asarray(phi_range, dtype=float)
    if rng.ndim == 2:
        if rng.shape != (n_ball, 2):
            raise ValueError("per-ball phi_range must have shape (n_ball, 2)")
        if preload == "oversize":
            return [(a, b, ("L", "U"), 1.0) for a, b in rng]
        n_l = n_ball // 2
        return [(a, b, ("L",) if k < n_l else ("U",), 1.0) for k, (a, b) in enumerate(rng)]
    phi_st, phi_end = float(rng[0]), float(rng[1])
    if not phi_end > phi_st:
        raise ValueError("phi_range must satisfy phi_end > phi_st")
    if preload == "oversize":
        return [(phi_st, phi_end, ("L", "U"), float(n_ball))]
    half = 0.5 * n_ball
    if two_point_layout == "interleaved":
        return [(phi_st, phi_end, ("L",), half), (phi_st, phi_end, ("U",), half)]
    mid = 0.5 * (phi_st + phi_end)
    if two_point_layout == "lower_first":
        return [(phi_st, mid, ("L",), half), (mid, phi_end, ("U",), half)]
    if two_point_layout == "upper_first":
        return [(phi_st, mid, ("U",), half), (mid, phi_end, ("L",), half)]
    raise ValueError(f"unknown two_point_layout {two_point_layout!r}")


def _quadrature(
    phi_st: float, phi_end: float, n_per_panel: int, breaks: Sequence[float] = ()
) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre nodes/weights on [phi_st, phi_end], panels <= pi/2 and split at breaks.

    The weights are normalised to sum to one (the average of Eq 3.35).
    """
    n_panels = max(1, int(np.ceil((phi_end - phi_st) / (0.5 * np.pi))))
    edges = np.linspace(phi_st, phi_end, n_panels + 1)
    extra = [b for b in breaks if phi_st < b < phi_end]
    if extra:
        edges = np.unique(np.concatenate([edges, extra]))
    x, w = np.polynomial.legendre.leggauss(n_per_panel)
    a, b = edges[:-1, None], edges[1:, None]
    nodes = (0.5 * (b - a) * x + 0.5 * (a + b)).ravel()
    weights = (0.5 * (b - a) * w).ravel()
    return nodes, weights / (phi_end - phi_st)


def _resolve_rg(alpha: float, R: float, r_g: float | None) -> float:
    # Eq 3.6 with d_p = 2R and Eq 3.13: tan(alpha) = p / (pi d_p) = r_g / R.
    return R * np.tan(alpha) if r_g is None else float(r_g)


# ---------------------------------------------------------------------------------------------
# Rigid-ballscrew method (Eq 3.35)
# ---------------------------------------------------------------------------------------------
def ksn_rigid(
    k_ball: float,
    n_ball: int,
    alpha: float,
    beta: float,
    R: float,
    phi_range: tuple[float, float] | np.ndarray = (-np.pi, np.pi),
    preload: str = "oversize",
    R_ball: float = 0.0,
    r_g: float | None = None,
    hand: int = 1,
    two_point_layout: str = "interleaved",
    n_quad: int = 12,
) -> np.ndarray:
    """Screw-nut interface stiffness ``K_SN`` by the rigid-ballscrew method (Eq 3.35).

    ``K_SN = sum_k 1/(phi_k,end - phi_k,st) int K_{L/U}(phi) dphi`` with ``K_L``, ``K_U`` of
    Eq 3.34. The screw point P and the nut node coincide (on the screw axis at the nut centre).

    Parameters
    ----------
    k_ball : float
        Ball (contact-normal) stiffness [N/m].
    n_ball : int
        Number of balls in contact ``N_Ball`` (Eq B.3).
    alpha : float
        Pitch angle [rad] (Eq 3.6).
    beta : float
        Contact angle [rad].
    R : float
        Radius from the screw axis to the ball centres [m] (Eq 3.12).
    phi_range : (phi_st, phi_end) or array (n_ball, 2)
        Azimuth range(s) of the balls [rad], e.g. from :func:`components._nut_geometry.azimuth_range` (Eq B.2).
    preload : {'spacer', 'offset', 'oversize'}
        See :func:`ball_layout`.
    R_ball : float
        Ball radius [m] (Eq 3.15). Has no effect on the result (see module notes).
    r_g : float, optional
        Lead per radian ``p / (2 pi)`` [m] (Eq 3.13); default ``R tan(alpha)``.
    hand : {1, -1}
        Thread hand (+1 right-hand, the thesis' Eq 3.12).
    two_point_layout : str
        See :func:`ball_layout`.
    n_quad : int
        Gauss points per quarter-turn panel (12 integrates the trig-polynomial integrand to
        round-off).

    Returns
    -------
    numpy.ndarray, shape (12, 12)
        Symmetric PSD stiffness; DOF 0-5 screw point, 6-11 nut node.
    """
    r_g = _resolve_rg(alpha, R, r_g)
    K = np.zeros((12, 12))
    for phi_st, phi_end, configs, count in ball_layout(n_ball, phi_range, preload, two_point_layout):
        nodes, weights = _quadrature(phi_st, phi_end, n_quad)
        for cfg in configs:
            T = np.empty((nodes.size, 12))
            for j, phi in enumerate(nodes):
                t_bs, t_n = ball_transformations(phi, alpha, beta, R, r_g, R_ball, cfg, hand)
                T[j, :6] = -t_bs
                T[j, 6:] = t_n
            K += count * k_ball * (T.T * weights) @ T
    return 0.5 * (K + K.T)


# ---------------------------------------------------------------------------------------------
# Shape-function method (Eq 3.17-3.29, 3.36-3.39)
# ---------------------------------------------------------------------------------------------
def ksn_shape_function(
    k_ball: float,
    n_ball: int,
    alpha: float,
    beta: float,
    R: float,
    shape_matrix: Callable[[float], np.ndarray],
    z_nut: float,
    phi_range: tuple[float, float] | np.ndarray = (-np.pi, np.pi),
    preload: str = "oversize",
    R_ball: float = 0.0,
    r_g: float | None = None,
    hand: int = 1,
    two_point_layout: str = "interleaved",
    z_breaks: Sequence[float] = (),
    n_quad: int = 12,
    sparse: bool = False,
):
    """Screw-nut interface stiffness by the shape-function method (Eq 3.36-3.39).

    A ball at azimuth ``phi`` has its centre at axial coordinate ``z = z_nut + hand r_g phi``.
    The screw cross-section there (point ``P_xi`` on the axis, Eq 3.17-3.24) moves as
    ``{u; theta}(z) = shape_matrix(z) @ q`` (Eq 3.27-3.28), and the screw contact point by
    ``[I, -S(r_BSi)]`` with ``r_BSi = r_BS - (z - z_nut) e_z`` (Eq 3.25-3.26). The nut is rigid
    (``T_{3-N}`` of Eq 3.16). Summing Eq 3.39 over all nodes equals integrating each ball over its
    whole range with the global interpolation matrix, which is what is done here.

    Parameters
    ----------
    k_ball, n_ball, alpha, beta, R, phi_range, preload, R_ball, r_g, hand, two_point_layout
        As in :func:`ksn_rigid`.
    shape_matrix : callable
        ``shape_matrix(z) -> (6, ndof)`` interpolation of the screw's (u, v, w, θx, θy, θz) at the
        absolute axial coordinate ``z`` [m] from the screw DOF vector ``q`` (ndof entries).
    z_nut : float
        Absolute axial coordinate of the nut node P [m] (the nut's reference point, on the axis).
    z_breaks : sequence of float
        Axial coordinates where ``shape_matrix`` has kinks (FE node positions); quadrature
        panels are split there so the piecewise-polynomial integrand is integrated exactly.
    n_quad : int
        Gauss points per panel.
    sparse : bool
        Return a ``scipy.sparse.csr_matrix`` instead of a dense array.

    Returns
    -------
    numpy.ndarray or scipy.sparse.csr_matrix, shape (ndof + 6, ndof + 6)
        DOF ``0 .. ndof-1`` the screw DOF ``q``, the last 6 the nut node.
    """
    r_g = _resolve_rg(alpha, R, r_g)
    ndof = np.asarray(shape_matrix(z_nut)).shape[1]
    K = np.zeros((ndof + 6, ndof + 6))
    ez = np.array([0.0, 0.0, 1.0])
    for phi_st, phi_end, configs, count in ball_layout(n_ball, phi_range, preload, two_point_layout):
        phi_breaks = [(zb - z_nut) / (hand * r_g) for zb in z_breaks] if r_g != 0 else []
        nodes, weights = _quadrature(phi_st, phi_end, n_quad, phi_breaks)
        T = np.empty((nodes.size * len(configs), ndof + 6))
        W = np.empty(nodes.size * len(configs))
        row = 0
        for phi, w in zip(nodes, weights, strict=True):
            z_rel = hand * r_g * phi
            N = np.asarray(shape_matrix(z_nut + z_rel), dtype=float)
            for cfg in configs:
                r_bs, r_n, n = contact_vectors(phi, alpha, beta, R, r_g, R_ball, cfg, hand)
                r_bsi = r_bs - z_rel * ez  # Eq 3.24-3.25
                t_bsi = (n @ np.hstack([np.eye(3), -skew(r_bsi)])) @ N  # Eq 3.26, 3.29, 3.36
                t_n = n @ np.hstack([np.eye(3), -skew(r_n)])
                T[row, :ndof] = -t_bsi
                T[row, ndof:] = t_n
                W[row] = w
                row += 1
        K += count * k_ball * (T.T * W) @ T
    K = 0.5 * (K + K.T)
    if sparse:

        K[np.abs(K) < 1e-14 * np.abs(K).max()] = 0.0
        return csr_matrix(K)
    return K


def rigid_screw_shape_matrix(z0: float) -> Callable[[float], np.ndarray]:
    """Shape matrix of a rigid screw represented by one 6-DOF node at ``z0``.

    ``{u; theta}(z) = [[I, -S((z - z0) e_z)], [0, I]] q``. With it, :func:`ksn_shape_function`
    reduces exactly to :func:`ksn_rigid` (the screw point P being the node at ``z0 = z_nut``).
    """

    def shape(z: float) -> np.ndarray:
        return rigid_point_map(np.array([0.0, 0.0, z - z0]))

    return shape


def rigid_point_map(offset: np.ndarray) -> np.ndarray:
    """6x6 map from the motion of a point to that of a rigidly attached point at ``offset``."""
    G = np.eye(6)
    G[:3, 3:] = -skew(np.asarray(offset, dtype=float))
    return G
