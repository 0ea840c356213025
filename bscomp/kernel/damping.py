"""Viscous damping matrices for linear structural models ``M d'' + C d' + K d = F`` (Eq 3.44).

The thesis builds the model damping matrix ``C_model`` from experimental or empirical *modal*
damping ratios under a proportional-damping assumption (Sec 3.4, Appendix A.3, Eq A.10-A.15).
Rigid-body (zero-frequency) modes receive no modal damping: the viscous damping of the rigid-body
motion (``B`` of Eq 4.2 / Eq 5.6-5.7) is applied separately through the friction law, and must not
be counted twice (Sec 5.2.2.1, text after Eq 5.6).

Functions
---------
modal_damping_matrix
    ``C`` that gives each mass-normalised mode a prescribed damping ratio (Eq A.10-A.15).
rayleigh_damping_matrix
    ``C = alpha M + beta K``, from the coefficients or from two target ratios at two frequencies.
rayleigh_coefficients
    ``(alpha, beta)`` that give ratios ``zeta1`` at ``f1`` and ``zeta2`` at ``f2``.
damped_modal_properties
    Natural frequencies and damping ratios recovered from the eigenvalues of the damped system.

Only numpy and scipy are used. ``M`` and ``K`` may be dense arrays or ``scipy.sparse`` matrices.

These are damping *models* (what a drive declares, ``system.damping = ModalDamping(...)``, and what
flattening applies, :mod:`bscomp.kernel.system_damping`), so they live in the kernel where systems and
the flattening can reach them; :mod:`bscomp.linear` re-exports them for analyses.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.errors import ParameterError
from bscomp.kernel.condensation import SYM_RTOL as _SYM_RTOL
from bscomp.kernel.condensation import real_general_eig

__all__ = [
    "modal_damping_matrix",
    "damping_from_modes",
    "rayleigh_damping_matrix",
    "rayleigh_coefficients",
    "damped_modal_properties",
    "matrix_from_ratios",
    "nonsymmetric_damping",
    "ModalDamping",
    "RayleighDamping",
]


def as_dense_symmetric(A: Any, name: str, n: int | None = None) -> np.ndarray:
    """``A`` as a dense float array after checking it is a finite, square, symmetric matrix (``n x n`` if
    ``n`` is given); raises :class:`~bscomp.errors.ParameterError` naming ``name`` otherwise."""
    if sp.issparse(A):
        A = A.toarray()
    try:
        A = np.array(A, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be a real numeric matrix") from exc
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise ParameterError(f"{name} must be a non-empty square 2-D matrix, got shape {A.shape}")
    if n is not None and A.shape[0] != n:
        raise ParameterError(f"{name} must be {n} x {n} like M, got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ParameterError(f"{name} contains non-finite entries")
    scale = np.max(np.abs(A))
    if scale > 0 and np.max(np.abs(A - A.T)) > _SYM_RTOL * scale:
        raise ParameterError(f"{name} must be symmetric")
    return 0.5 * (A + A.T)


def _check_pair(M: Any, K: Any) -> tuple[np.ndarray, np.ndarray]:
    Md = as_dense_symmetric(M, "M")
    Kd = as_dense_symmetric(K, "K")
    if Md.shape != Kd.shape:
        raise ValueError(f"M and K must have the same shape, got M {Md.shape} and K {Kd.shape}")
    return Md, Kd


def _mass_normalised_modes(Md: np.ndarray, Kd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve Eq A.10 ``K P = M P Lambda``; return eigenvalues and modes with ``P^T M P = I``."""
    try:
        lam, phi = sla.eigh(Kd, Md)
    except np.linalg.LinAlgError as exc:
        raise ValueError("M must be symmetric positive definite") from exc
    return lam, phi


def modal_damping_matrix(
    M: Any,
    K: Any,
    zeta: float | Any,
    n_rigid: int | None = None,
    rigid_tol: float = 1e-9,
) -> np.ndarray:
    r"""Damping matrix that gives each elastic mode a prescribed modal damping ratio.

    Implements Appendix A.3 of the thesis. The undamped problem (Eq A.10)
    :math:`K P = M P \Lambda` is solved, natural frequencies are
    :math:`(\omega_n)_k = \sqrt{\Lambda_k}` (Eq A.11), the modes are mass-normalised
    (Eq A.12-A.13), the diagonal modal damping is :math:`(c_q)_k = 2 \zeta_k (\omega_n)_k`
    (Eq A.14), and it is transformed back to physical coordinates (Eq A.15):

    .. math::  C = \chi^{-T} C_q \chi^{-1} = M \chi\, C_q\, \chi^T M,

    using :math:`\chi^{-1} = \chi^T M` for mass-normalised modes (:math:`\chi^T M \chi = I`).
    Eq A.13 is printed as :math:`\chi = P M_q^{-1}`; mass normalisation needs
    :math:`\chi = P M_q^{-1/2}`, which is what is used here (``scipy.linalg.eigh`` returns
    mass-normalised modes directly).

    Rigid-body (zero-frequency) modes get :math:`(c_q)_k = 0`, so ``C @ rigid_mode == 0``: the
    viscous damping of the rigid-body motion belongs in the friction law (``B v`` in Eq 5.6/5.7,
    ``B`` of Eq 4.2), not in ``C`` (Sec 5.2.2.1).

    Parameters
    ----------
    M, K : (n, n) array_like or scipy.sparse matrix
        Symmetric mass (positive definite) and stiffness (positive semi-definite) matrices.
    zeta : float or array_like
        Modal damping ratio(s), >= 0. A scalar applies to every elastic mode. An array of length
        ``n - n_rigid`` gives the ratios of the elastic modes in order of increasing frequency; an
        array of length ``n`` gives one ratio per mode in order of increasing eigenvalue, the
        entries of the rigid-body modes being ignored.
    n_rigid : int, optional
        Number of rigid-body modes (the ``n_rigid`` lowest eigenvalues). If None they are detected
        as eigenvalues with ``|Lambda_k| <= rigid_tol * max|Lambda|``. Give it explicitly for
        badly conditioned models where round-off blurs the distinction.
    rigid_tol : float, optional
        Relative tolerance for the automatic detection of rigid-body modes (default 1e-9).

    Returns
    -------
    C : (n, n) numpy.ndarray
        Symmetric positive semi-definite damping matrix (dense: modal damping fills the matrix).

    Raises
    ------
    ValueError
        If ``M``/``K`` are not square, symmetric, finite and of equal shape, ``M`` is not positive
        definite, ``K`` has clearly negative eigenvalues, or ``zeta``, ``n_rigid`` or
        ``rigid_tol`` are invalid. The message names the offending argument.

    Examples
    --------
    >>> import numpy as np
    >>> M = np.diag([1.0, 1.0]); K = np.array([[2.0, -1.0], [-1.0, 2.0]])
    >>> C = modal_damping_matrix(M, K, 0.05)
    >>> np.allclose(C, C.T)
    True
    """
    Md, Kd = _check_pair(M, K)
    _check_rigid_tol(rigid_tol)
    lam, phi = _mass_normalised_modes(Md, Kd)
    return damping_from_modes(Md, lam, phi, zeta, n_rigid, rigid_tol)


def _check_rigid_tol(rigid_tol):
    if not (np.isscalar(rigid_tol) and np.isfinite(rigid_tol) and rigid_tol >= 0):
        raise ValueError(f"rigid_tol must be a finite non-negative number, got {rigid_tol!r}")


def damping_from_modes(Md: np.ndarray, lam: np.ndarray, phi: np.ndarray, zeta: float | Any,
                       n_rigid: int | None = None, rigid_tol: float = 1e-9) -> np.ndarray:
    r"""Eq A.14-A.15 from modes already solved: ``C = M chi diag(2 zeta omega) chi^T M`` with ``(lam, phi)``
    the ascending, mass-normalised solution of ``K phi = M phi lam`` (``scipy.linalg.eigh(K, M)``) -- what
    :func:`modal_damping_matrix` does after its own ``eigh``; for callers that need the modes anyway (the
    ratios by mode character, :func:`matrix_from_ratios`), so the pair is decomposed once. ``zeta``,
    ``n_rigid``, ``rigid_tol`` as in :func:`modal_damping_matrix`."""
    _check_rigid_tol(rigid_tol)
    n = Md.shape[0]
    lam_scale = max(float(np.max(np.abs(lam))), np.finfo(float).tiny)
    if n_rigid is None:
        rigid = np.abs(lam) <= rigid_tol * lam_scale
        n_r = int(np.count_nonzero(rigid))
    else:
        if isinstance(n_rigid, bool) or not isinstance(n_rigid, (int, np.integer)) or not 0 <= n_rigid <= n:
            raise ValueError(f"n_rigid must be an integer in [0, {n}], got {n_rigid!r}")
        n_r = int(n_rigid)
    # eigh sorts ascending, so the rigid modes are the first n_r
    elastic_lam = lam[n_r:]
    if elastic_lam.size and elastic_lam[0] < -rigid_tol * lam_scale:
        raise ValueError("K must be positive semi-definite (negative eigenvalue of K v = lambda M v)")
    omega = np.sqrt(np.clip(elastic_lam, 0.0, None))

    z = np.asarray(zeta, dtype=float)
    if z.ndim == 0:
        z_el = np.full(n - n_r, float(z))
    elif z.ndim == 1 and z.size == n - n_r:
        z_el = z.copy()
    elif z.ndim == 1 and z.size == n:
        z_el = z[n_r:].copy()
    else:
        raise ValueError(
            f"zeta must be a scalar or a 1-D array of length {n - n_r} (elastic modes) or {n} "
            f"(all modes), got shape {z.shape}"
        )
    if not np.all(np.isfinite(z_el)) or np.any(z_el < 0):
        raise ValueError("zeta must be finite and non-negative")

    chi = phi[:, n_r:]
    c_q = 2.0 * z_el * omega  # Eq A.14
    Mchi = Md @ chi  # chi^{-T} restricted to the elastic modes, Eq A.15
    C = (Mchi * c_q) @ Mchi.T
    return 0.5 * (C + C.T)


def rayleigh_coefficients(zeta: float | Any, f1: float, f2: float) -> tuple[float, float]:
    r"""Rayleigh coefficients that give damping ratios ``zeta1`` at ``f1`` and ``zeta2`` at ``f2``.

    For :math:`C = \alpha M + \beta K` the ratio of a mode at circular frequency :math:`\omega` is
    :math:`\zeta(\omega) = \alpha / (2\omega) + \beta\omega / 2`; the two conditions give a
    2x2 linear system for :math:`(\alpha, \beta)`.

    Parameters
    ----------
    zeta : float or sequence of two floats
        Target ratio(s) at ``f1`` and ``f2`` (a scalar means the same ratio at both), >= 0.
    f1, f2 : float
        Distinct positive frequencies in Hz.

    Returns
    -------
    alpha : float
        Mass-proportional coefficient [1/s].
    beta : float
        Stiffness-proportional coefficient [s].

    Raises
    ------
    ValueError
        If ``zeta``, ``f1`` or ``f2`` are invalid (named in the message).
    """
    for name, f in (("f1", f1), ("f2", f2)):
        if f is None or not np.isscalar(f) or not np.isfinite(f) or f <= 0:
            raise ValueError(f"{name} must be a positive finite frequency in Hz, got {f!r}")
    if np.isclose(f1, f2, rtol=1e-12, atol=0.0):
        raise ValueError(f"f1 and f2 must differ, got f1 = f2 = {f1!r}")
    z = np.asarray(zeta, dtype=float)
    if z.ndim == 0:
        z = np.array([float(z), float(z)])
    if z.shape != (2,):
        raise ValueError(f"zeta must be a scalar or a pair (zeta1, zeta2), got shape {z.shape}")
    if not np.all(np.isfinite(z)) or np.any(z < 0):
        raise ValueError("zeta must be finite and non-negative")
    w1, w2 = 2.0 * np.pi * float(f1), 2.0 * np.pi * float(f2)
    A = np.array([[1.0 / (2.0 * w1), w1 / 2.0], [1.0 / (2.0 * w2), w2 / 2.0]])
    alpha, beta = np.linalg.solve(A, z)
    return float(alpha), float(beta)


def rayleigh_damping_matrix(
    M: Any,
    K: Any,
    alpha: float | None = None,
    beta: float | None = None,
    zeta: float | Any = None,
    f1: float | None = None,
    f2: float | None = None,
):
    r"""Rayleigh (proportional) damping matrix :math:`C = \alpha M + \beta K`.

    Either give ``alpha`` and/or ``beta`` directly (a missing one is taken as 0), or give
    ``zeta``, ``f1`` and ``f2`` to obtain the coefficients from :func:`rayleigh_coefficients`
    (ratio ``zeta1`` at ``f1`` Hz and ``zeta2`` at ``f2`` Hz). Rayleigh damping is a special case
    of the proportional damping assumed in Appendix A.3; unlike :func:`modal_damping_matrix`, a
    non-zero ``alpha`` damps rigid-body modes.

    Parameters
    ----------
    M, K : (n, n) array_like or scipy.sparse matrix
        Symmetric mass and stiffness matrices of equal shape.
    alpha : float, optional
        Mass-proportional coefficient [1/s], >= 0.
    beta : float, optional
        Stiffness-proportional coefficient [s], >= 0.
    zeta : float or sequence of two floats, optional
        Target damping ratio(s) at ``f1`` and ``f2``.
    f1, f2 : float, optional
        Frequencies [Hz] at which ``zeta`` is met exactly.

    Returns
    -------
    C : numpy.ndarray or scipy.sparse.csr_matrix
        Sparse (CSR) if ``M`` or ``K`` is sparse, otherwise a dense array.

    Raises
    ------
    ValueError
        If both or neither parameterisation is given, the target specification is incomplete, a
        coefficient is negative or non-finite, or ``M``/``K`` are invalid (named in the message).
    """
    direct = alpha is not None or beta is not None
    target = zeta is not None or f1 is not None or f2 is not None
    if direct and target:
        raise ValueError("give either alpha/beta or zeta/f1/f2, not both")
    if not direct and not target:
        raise ValueError("give alpha and/or beta, or zeta with f1 and f2")
    if target:
        missing = [n for n, v in (("zeta", zeta), ("f1", f1), ("f2", f2)) if v is None]
        if missing:
            raise ValueError(f"zeta, f1 and f2 are all needed; missing {', '.join(missing)}")
        alpha, beta = rayleigh_coefficients(zeta, f1, f2)
    else:
        alpha = 0.0 if alpha is None else alpha
        beta = 0.0 if beta is None else beta
        for name, v in (("alpha", alpha), ("beta", beta)):
            if not np.isscalar(v) or not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")
    Md, Kd = _check_pair(M, K)  # validation (shape, symmetry, finiteness)
    if sp.issparse(M) or sp.issparse(K):
        return (float(alpha) * sp.csr_matrix(M) + float(beta) * sp.csr_matrix(K)).tocsr()
    return float(alpha) * Md + float(beta) * Kd


def damped_modal_properties(
    M: Any, C: Any, K: Any, zero_tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    r"""Undamped natural frequencies and damping ratios from the damped eigenvalues.

    Solves the state-space eigenproblem of :math:`M\ddot d + C\dot d + K d = 0` (Eq 5.2-5.3 with
    :math:`A = [[0, I], [-M^{-1}K, -M^{-1}C]]`). For each underdamped pair
    :math:`s = -\zeta\omega_n \pm i\omega_n\sqrt{1-\zeta^2}` it returns :math:`\omega_n = |s|`
    and :math:`\zeta = -\mathrm{Re}(s)/|s|`. Eigenvalues with ``|s| <= zero_tol * max|s|`` (rigid
    modes) are dropped.

    Parameters
    ----------
    M, C, K : (n, n) array_like or scipy.sparse matrix
        Mass, damping and stiffness matrices.
    zero_tol : float, optional
        Relative tolerance below which an eigenvalue is treated as zero (rigid-body). An undamped
        rigid-body mode is a defective double zero eigenvalue, which round-off splits by about
        ``sqrt(eps * |A|)``; hence the loose default 1e-6.

    Returns
    -------
    omega_n : numpy.ndarray
        Natural frequencies [rad/s] of the underdamped modes, ascending.
    zeta : numpy.ndarray
        Matching damping ratios.

    Raises
    ------
    ValueError
        If the matrices are invalid or ``M`` is singular.
    """
    Md, Kd = _check_pair(M, K)
    Cd = as_dense_symmetric(C, "C")
    if Cd.shape != Md.shape:
        raise ValueError(f"C must have the shape of M {Md.shape}, got {Cd.shape}")
    n = Md.shape[0]
    try:
        MiK = np.linalg.solve(Md, Kd)
        MiC = np.linalg.solve(Md, Cd)
    except np.linalg.LinAlgError as exc:
        raise ValueError("M must be non-singular") from exc
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-MiK, -MiC]])
    s = np.linalg.eigvals(A)
    mag = np.abs(s)
    keep = (mag > zero_tol * max(mag.max(), np.finfo(float).tiny)) & (s.imag > 0)
    s = s[keep]
    order = np.argsort(np.abs(s))
    s = s[order]
    omega = np.abs(s)
    return omega, -s.real / omega


def matrix_from_ratios(option, M, K, coordinates=None) -> np.ndarray:
    """The damping matrix (Eq A.10-A.15) of an option that gives a ratio per mode (``modal_ratios(lam,
    phi, M, coordinates)``): one ``eigh`` of (K, M), the ratios, :func:`damping_from_modes` (the same modes:
    the pair is decomposed once)."""
    Md, Kd = _check_pair(M, K)
    lam, phi = _mass_normalised_modes(Md, Kd)
    rigid = np.abs(lam) <= 1e-9 * np.max(np.abs(lam))
    z = option.modal_ratios(lam, phi, Md, coordinates)
    return damping_from_modes(Md, lam, phi, z, n_rigid=int(rigid.sum()))


def nonsymmetric_damping(option, M, K, coordinates=None) -> np.ndarray:
    """A system damping option's matrix for a mass and stiffness that are not symmetric (a CMS superelement with
    Modal-Acceleration recovery couples its loads and displacements through different matrices, Eq 5.14/5.18).

    With ``K V = M V Λ`` (right eigenvectors, real eigenvalues) the damping ``C = M V diag(2 ζ_k ω_k) V^{-1}``
    gives every mode exactly the option's ratio ``ζ_k`` (``modal_ratios``; rigid-body modes none): in the
    coordinates ``η = V^{-1} q`` the equations decouple as ``η'' + 2 ζ ω η' + ω² η = 0``. For a symmetric pair
    with mass-normalised modes ``V^{-1} = V^T M`` and this is Eq A.15, ``M Φ diag(2ζω) Φ^T M``. Rayleigh
    damping is ``α M + β K`` as for any pair.

    Raises
    ------
    ParameterError
        Complex undamped eigenvalues (the pair has no real modes), or an option with neither ``modal_ratios``
        nor Rayleigh coefficients.
    """
    Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M, float)
    Kd = K.toarray() if hasattr(K, "toarray") else np.asarray(K, float)
    if isinstance(option, RayleighDamping):
        return option.alpha * Md + option.beta * Kd
    if not hasattr(option, "modal_ratios"):
        raise ParameterError(f"system damping {option!r} has no modal ratios to apply to a non-symmetric model")
    lam, V, _ = real_general_eig(Kd, Md, 1e-9, error=ParameterError, what="system damping")
    zeta = np.asarray(option.modal_ratios(lam, V, Md, coordinates), float)
    return Md @ (V * (2.0 * zeta * np.sqrt(np.clip(lam, 0.0, None)))) @ np.linalg.inv(V)


class ModalDamping:
    """System-level option: modal damping ratios turned into ``C`` (Eq A.10-A.15) at flattening.

    Set ``system.damping = ModalDamping(zeta)``; :func:`bscomp.flatten` linearizes the mechanical part at
    the start point, builds ``C`` over the reduced coordinates with :func:`modal_damping_matrix` and
    adds it to the structural damping. Rigid-body modes get none (Sec 5.2.2.1).

    Parameters
    ----------
    zeta : float or sequence
        One ratio for every elastic mode, or one per elastic mode in ascending frequency (the last
        value is used for the remaining modes).
    """

    def __init__(self, zeta):
        z = np.atleast_1d(np.asarray(zeta, float))
        if np.any(z < 0) or np.any(z >= 1) or not np.all(np.isfinite(z)):
            raise ValueError(f"ModalDamping: zeta must be in [0, 1), got {zeta!r}")
        self.zeta = z

    def matrix(self, M, K):
        n = M.shape[0]
        Md, Kd = _check_pair(M, K)
        w2, _ = _mass_normalised_modes(Md, Kd)
        n_el = int(np.sum(np.sqrt(np.clip(w2, 0, None)) > 1e-6 * max(np.sqrt(np.abs(w2).max()), 1e-300)))
        z = self.zeta
        if z.size > 1:
            full = np.full(n, z[-1])
            full[n - n_el:n - n_el + min(z.size, n_el)] = z[:n_el]
            z = full
        else:
            z = float(z[0])
        return modal_damping_matrix(M, K, z)

    def modal_ratios(self, lam, phi, M, coordinates=None) -> np.ndarray:
        """The ratio of each mode of ``K phi = M phi lam`` (ascending): the ratios of :meth:`matrix` (one for
        every elastic mode, or one per elastic mode in ascending frequency), 0 for rigid-body modes."""
        lam = np.asarray(lam, float)
        rigid = np.abs(lam) <= 1e-9 * max(float(np.max(np.abs(lam))), 1e-300)
        out = np.zeros(lam.size)
        el = np.flatnonzero(~rigid)
        z = self.zeta
        out[el] = z[-1] if z.size > 1 else float(z[0])
        if z.size > 1:
            out[el[:min(z.size, el.size)]] = z[:el.size]
        return out

    def __repr__(self):
        return f"ModalDamping({self.zeta.tolist()})"


class RayleighDamping:
    """System-level option ``C = alpha M + beta K`` (from coefficients, or ratios ``zeta`` at f1, f2)."""

    def __init__(self, alpha=None, beta=None, zeta=None, f1=None, f2=None):
        if zeta is not None:
            alpha, beta = rayleigh_coefficients(zeta, f1, f2)
        if alpha is None or beta is None or alpha < 0 or beta < 0:
            raise ValueError("RayleighDamping needs alpha >= 0 and beta >= 0, or zeta with f1 and f2")
        self.alpha, self.beta = float(alpha), float(beta)

    def matrix(self, M, K):
        return self.alpha * sp.csr_matrix(M) + self.beta * sp.csr_matrix(K)

    def __repr__(self):
        return f"RayleighDamping(alpha={self.alpha:.4g}, beta={self.beta:.4g})"
