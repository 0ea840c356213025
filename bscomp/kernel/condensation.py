r"""Massless coordinates and the real modes of a mass-stiffness pair that need not be symmetric.

Shared by the system damping the flattening applies (:mod:`bscomp.kernel.system_damping`) and by
:func:`bscomp.linear.modes`: both condense the coordinates without inertia statically (Guyan) and, for a pair
that is not symmetric (a CMS superelement with Modal-Acceleration recovery applies loads with ``Ψ^T`` and
recovers displacements with ``T_1, T_2, T_3``, thesis Eq 5.14/5.18), solve ``K V = M V Λ`` with the general
eigensolver.

A coordinate is *massless* when no acceleration of it enters any row (a zero column of ``M``); its row may
still carry inertia loads of other coordinates (the MA recovery rows). Condensing row by row,

.. math::
    K_{00} q_0 = -K_{0m} q_m - M_{0m} \ddot q_m \;\Rightarrow\;
    M_c = M_{mm} - K_{m0} K_{00}^{-1} M_{0m} ,\qquad K_c = K_{mm} - K_{m0} K_{00}^{-1} K_{0m} .
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.errors import SingularSystemError

__all__ = ["is_asymmetric", "massless_split", "condense_massless", "real_general_eig", "SYM_RTOL"]

#: Relative tolerance of the symmetry test ``max|A - A^T| <= SYM_RTOL max|A|``
SYM_RTOL = 1e-9


def is_asymmetric(A, rtol: float = SYM_RTOL) -> bool:
    """True when ``max|A - A^T| > rtol max|A|`` (dense or sparse; a zero matrix is symmetric)."""
    if isinstance(A, np.ndarray) and A.ndim == 2:           # dense: no sparse copy (a diagnose fit asks per step)
        scale = float(np.max(np.abs(A))) if A.size else 0.0
        return bool(scale > 0 and np.max(np.abs(A - A.T)) > rtol * scale)
    A = sp.csr_matrix(A)
    scale = abs(A).max() if A.nnz else 0.0
    return bool(scale > 0 and abs(A - A.T).max() > rtol * scale)


def massless_split(M) -> tuple[np.ndarray, np.ndarray]:
    """``(massless, massive)`` coordinate indices: the zero columns of ``M``.

    A column counts as zero when it is exactly zero or round-off of the masses it is coupled with: its
    absolute sum is at most ``1e-14`` of the largest column sum among the coordinates it shares an entry of
    ``M`` with (``M_ij`` or ``M_ji`` nonzero, ``i != j``). A coordinate coupled to no other one through ``M``
    (a lumped mass) is massless only when its mass is exactly zero, so a light rotor next to a very heavy
    table (1e-3 kg m^2 and 1e12 kg) keeps its inertia. All coordinates are massless when ``M`` is zero.
    """
    if isinstance(M, np.ndarray) and M.ndim == 2:           # dense: the same rule without sparse copies
        A = np.abs(M)
        col = A.sum(axis=0)
        coupled = (A + A.T) != 0
        np.fill_diagonal(coupled, False)
        scale = np.max(np.where(coupled, col[:, None], 0.0), axis=0) if M.shape[0] else np.zeros(0)
        massless = np.flatnonzero((col == 0) | (col <= 1e-14 * scale))
        return massless, np.setdiff1d(np.arange(M.shape[0]), massless)
    M = sp.csr_matrix(M)
    n = M.shape[0]
    A = abs(M)
    col = np.asarray(A.sum(axis=0)).ravel()
    coupled = sp.csc_matrix(A + A.T)
    coupled.setdiag(0)
    coupled.eliminate_zeros()
    coupled.data = col[coupled.indices]                 # column j holds the column sums of its neighbours
    scale = coupled.max(axis=0).toarray().ravel() if n else np.zeros(0)
    massless = np.flatnonzero((col == 0) | (col <= 1e-14 * scale))
    return massless, np.setdiff1d(np.arange(n), massless)


def condense_massless(Md: np.ndarray, Kd: np.ndarray, massless, massive, names, what: str):
    """Row-wise static condensation of the massless coordinates (module docstring).

    Returns ``(M_c, K_c, lu, X, Y)``: the condensed pair on the massive coordinates, the LU factors of
    ``K_00`` (for further right-hand sides) and ``X = K_00^{-1} K_{0m}``, ``Y = K_00^{-1} M_{0m}`` (so
    ``q_0 = -X q_m - Y q_m''``). ``what`` prefixes the error.

    Raises
    ------
    SingularSystemError
        The massless coordinates are not held by any stiffness (``K_00`` singular), naming them.
    """
    ml, ma = np.asarray(massless, int), np.asarray(massive, int)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sla.LinAlgWarning)      # an exactly singular K_00 is reported below
            lu = sla.lu_factor(Kd[np.ix_(ml, ml)], check_finite=False)
        if not np.all(np.isfinite(lu[0])) or np.any(np.diag(lu[0]) == 0):
            raise np.linalg.LinAlgError("singular K_00")
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise SingularSystemError(f"{what}: massless coordinates {[names[i] for i in ml][:10]} are not held by "
                                  "any stiffness (a mechanism without mass): add a mass or a spring") from exc
    X = sla.lu_solve(lu, Kd[np.ix_(ml, ma)])
    Y = sla.lu_solve(lu, Md[np.ix_(ml, ma)])
    Km0 = Kd[np.ix_(ma, ml)]
    return Md[np.ix_(ma, ma)] - Km0 @ Y, Kd[np.ix_(ma, ma)] - Km0 @ X, lu, X, Y


def real_general_eig(Kd: np.ndarray, Md: np.ndarray, rigid_rtol: float, error=SingularSystemError,
                     what: str = "the model"):
    """Real modes ``K V = M V Λ`` of a pair that need not be symmetric, by the general (QZ) eigensolver.

    Returns ``(lam, V, rigid)``: eigenvalues ascending (those within ``rigid_rtol`` of zero, relative to the
    largest, set to 0 and flagged ``rigid``) and real right eigenvectors (unnormalised).

    Raises
    ------
    error
        (default :class:`~bscomp.errors.SingularSystemError`) when the eigensolver fails, the mass is
        singular (infinite eigenvalues) or the eigenvalues are complex (no real modes).
    """
    try:
        lam, V = sla.eig(Kd, Md, check_finite=False)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise error(f"{what}: the general eigenproblem K v = w^2 M v failed (singular M?)") from exc
    if not np.all(np.isfinite(lam)):
        raise error(f"{what}: the mass matrix is singular after condensing the massless coordinates")
    scale = max(float(np.max(np.abs(lam))), 1e-300)
    if np.max(np.abs(lam.imag)) > 1e-6 * scale:
        raise error(f"{what}: the non-symmetric mass and stiffness have complex undamped eigenvalues "
                    f"({np.max(np.abs(lam.imag)):.3g}, a flutter-like coupling): its modes are not real (frf() and the "
                    "first-order linearize() still apply)")
    order = np.argsort(lam.real)
    lam, V = lam.real[order], V[:, order].real
    rigid = np.abs(lam) <= rigid_rtol * scale
    return np.where(rigid, 0.0, lam), V, rigid
