r"""Component Mode Synthesis reduction with Mode-Displacement and Modal-Acceleration recovery.

Implements thesis Sec 5.2.3 (Eq 5.10-5.18) for an undamped (or modally damped) linear structure

.. math::  M \ddot d + C \dot d + K d = F .

The DOF are split into *exterior* DOF ``e`` (kept: actuated DOF, anchors) and *interior* DOF ``i``
(Eq 5.10).  The coordinate transformation of Eq 5.11-5.12 is

.. math::

    \begin{Bmatrix} d_e \\ d_i \end{Bmatrix} = \Psi \begin{Bmatrix} d_e \\ q_p \end{Bmatrix}, \qquad
    \Psi = \begin{bmatrix} I_{ee} & 0_{ep} \\ \varphi_{ie} & \chi_{ip} \end{bmatrix}, \qquad
    \varphi_{ie} = -K_{ii}^{-1} K_{ie} \quad \text{(Eq 5.13)},

and the reduced model is :math:`M^{red} = \Psi^T M \Psi`, :math:`K^{red} = \Psi^T K \Psi`,
:math:`C^{red} = \Psi^T C \Psi`, :math:`F^{red} = \Psi^T F` (Eq 5.14).

``χ_ip`` is, as Eq 5.12 and the text below Eq 5.13 say, the *interior rows* of normal modes:

* ``interface="free"`` (the thesis's choice for ballscrews, Sec 5.2.3.2): the first ``P`` non-rigid
  eigenvectors of the whole structure, Eq 5.10 (optionally plus its rigid-body modes: the thesis's
  sub-model 1 is reduced to ``E + P + 1`` coordinates, Sec 5.3.2).  Only their interior rows enter
  ``Ψ`` (the exterior rows are zero), so the exact free modes are *not* in the span of ``Ψ`` and
  the reduced frequencies are slightly high (Table 5.3: +0.8 % on mode 1).
* ``interface="fixed"``: eigenvectors of ``(K_ii, M_ii)``, i.e. the classical Craig-Bampton basis.

Either way any column ``[0; x]`` is ``K``-orthogonal to the constraint modes
(:math:`[0; x]^T K [I; \varphi] = x^T (K_{ie} + K_{ii}\varphi) = 0`), so ``K^{red}`` is block-diagonal
and the reduced *static* exterior displacements are those of the full model (Guyan).

Recovery of the full response (Sec 5.2.3.2-5.2.3.3):

* **MD** (Mode Displacement, Eq 5.11): :math:`d = \Psi x`.  Exact statically only if the interior
  DOF carry no load, ``F_i = 0``.
* **MA** (Modal Acceleration, Eq 5.16-5.18): from the interior row partition of Eq 5.10,

  .. math::

      d = \underbrace{\begin{bmatrix} 0 & 0 \\ -K_{ii}^{-1}(M_{ie} + M_{ii}\varphi_{ie}) &
      -K_{ii}^{-1} M_{ii}\chi_{ip} \end{bmatrix}}_{T_1} \ddot x
      + \underbrace{\begin{bmatrix} I_{ee} \\ \varphi_{ie} \end{bmatrix}}_{T_2} d_e
      + \underbrace{\begin{bmatrix} 0_{ei} \\ K_{ii}^{-1} \end{bmatrix}}_{T_3} F_i ,

  which adds the static effect of interior loads (``T_3``) and of inertia loads (``T_1``).  If a
  damping matrix was given *and* the reduced velocities are passed, the analogous damping term
  :math:`-K_{ii}^{-1}(C_{ie}\dot d_e + C_{ii}\dot d_i)` is added (the thesis analyses the structure
  as undamped, Sec 5.2.3.2, and omits it).

Position-dependent loads (Sec 5.2.2.3, Fig 5.7-5.8): the nut acts at an axial position ``z`` that
is generally between nodes; its displacement is ``N(z) d`` and its force enters as ``N(z)^T f``.
:meth:`ReducedModel.port` turns any such row into the small matrices a time simulation needs
(input matrix ``Ψ^T N^T``, MD and MA output matrices and the MA feed-through ``N K^{-1} N^T``)
from quantities computed once, so the nut can move without re-reducing.

All algebra is dense numpy/scipy (``O(n^3)`` once, fine to a few thousand DOF); sparse ``M``, ``K``
are accepted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.errors import ParameterError, SingularSystemError, UsageError, check_names, check_number
from bscomp.kernel.damping import as_dense_symmetric
from bscomp.linear.linearization import SecondOrderModel

__all__ = ["ReducedModel", "ReducedPort", "cms_reduce", "reduce_second_order"]

_SYM_RTOL = 1e-9


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------
def _index_list(dofs: Any, n: int, names: Sequence[str] | None, what: str) -> np.ndarray:
    items = [dofs] if isinstance(dofs, (str, int, np.integer)) else list(dofs)
    out = []
    for d in items:
        if isinstance(d, str):
            if names is None or d not in names:
                raise UsageError(f"{what}: unknown DOF name {d!r} (pass dof_names to use names)")
            out.append(list(names).index(d))
        elif isinstance(d, (int, np.integer)) and not isinstance(d, bool):
            k = int(d)
            if not 0 <= k < n:          # a negative index is an error, not counted from the end
                raise UsageError(f"{what}: DOF index {d} out of range: give indices 0..{n - 1} for {n} DOF "
                                 "(negative indices are not counted from the end)")
            out.append(k)
        else:
            raise UsageError(f"{what}: DOF must be an int index or a name, got {d!r}")
    idx = np.asarray(out, dtype=int)
    if len(set(idx.tolist())) != idx.size:
        raise UsageError(f"{what}: duplicate DOF in {dofs!r}")
    return idx


def _rows(at: Any, n: int, what: str = "at") -> np.ndarray | sp.csr_matrix:
    """Output selection: DOF index/indices -> selection rows; a (k, n) matrix or (n,) row is used as is."""
    if sp.issparse(at):
        R = sp.csr_matrix(at)
    else:
        a = np.asarray(at)
        if a.dtype.kind in "iu" and a.ndim <= 1:
            idx = np.atleast_1d(a).astype(int)
            if np.any(idx < -n) or np.any(idx >= n):
                raise UsageError(f"{what}: DOF index out of range for {n} DOF")
            idx = np.where(idx < 0, idx + n, idx)
            return sp.csr_matrix((np.ones(idx.size), (np.arange(idx.size), idx)), shape=(idx.size, n))
        if a.dtype.kind not in "fc" or a.ndim > 2:
            raise UsageError(f"{what}: give DOF indices (int) or a (k, {n}) row matrix such as N(z), got {at!r}"[:300]
                             + " (the reduced model keeps no DOF names: pass the index)")
        R = np.atleast_2d(np.asarray(a, dtype=float))
    if R.shape[1] != n:
        raise UsageError(f"{what}: a row/matrix with {n} columns is needed, got shape {R.shape}")
    return R


def _finite(name: str, value, rows: int) -> np.ndarray:
    """``value`` as a float array with ``rows`` rows (a vector or a history), finite, else a named UsageError."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise UsageError(f"{name} must be an array of numbers, got {value!r}"[:300]) from None
    if a.ndim not in (1, 2) or a.shape[0] != rows:
        raise UsageError(f"{name} must have {rows} rows ((n,) or (n, nt)), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise UsageError(f"{name} must be finite, got NaN or inf")
    return a


# --------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReducedPort:
    """Position-dependent input/output matrices of a reduced model for one load/sensing row.

    For a row ``N`` (``k x n``, e.g. the nut interpolation ``N(z)`` of Sec 5.2.2.3) and port forces
    ``f`` (``k``), the full load is ``F = N^T f`` and the port displacement ``y = N d``:

    * reduced load (Eq 5.14): ``F_red = B f``;
    * MD output (Eq 5.11): ``y = C_md x``;
    * MA output (Eq 5.18): ``y = C_x x + C_a x'' (+ C_v x') + D f``.

    ``D = N_i K_ii^{-1} N_i^T`` is the static flexibility of the port with the exterior DOF held:
    it makes a spring (e.g. ``K_SN``) attached at the port an algebraic loop that is solved in closed
    form, ``f = -k (y_0 + D f)  =>  f = -(I + k D)^{-1} k y_0``.

    Attributes
    ----------
    B : numpy.ndarray
        (m, k) input matrix ``Ψ^T N^T``.
    C_md : numpy.ndarray
        (k, m) MD output matrix ``N Ψ``.
    C_x, C_a, C_v : numpy.ndarray
        (k, m) MA output matrices ``N T_2``, ``N T_1`` and the damping analogue (zero if no ``C``).
    D : numpy.ndarray
        (k, k) MA feed-through ``N T_3 N^T``, symmetric positive semi-definite.
    """

    B: np.ndarray
    C_md: np.ndarray
    C_x: np.ndarray
    C_a: np.ndarray
    C_v: np.ndarray
    D: np.ndarray

    def output(self, x, xdd=None, f=None, *, method: str = "MA", xd=None) -> np.ndarray:
        """Port displacement ``y`` from reduced coordinates (``(m,)`` or ``(m, nt)`` histories).

        Parameters
        ----------
        x, xdd, xd : array_like
            Reduced displacements, accelerations and (optionally) velocities.
        f : array_like, optional
            Port forces ``(k,)`` or ``(k, nt)``; zero if omitted.
        method : {"MA", "MD"}
        """
        x = np.asarray(x, dtype=float)
        if _method(method) == "MD":
            return self.C_md @ x
        y = self.C_x @ x
        if xdd is not None:
            y = y + self.C_a @ np.asarray(xdd, dtype=float)
        if xd is not None:
            y = y + self.C_v @ np.asarray(xd, dtype=float)
        if f is not None:
            y = y + self.D @ np.asarray(f, dtype=float)
        return y


def _method(method: str) -> str:
    m = str(method).upper()
    if m not in ("MA", "MD"):
        raise UsageError(
            f"method must be 'MA' (modal acceleration) or 'MD' (mode displacement), got {method!r}"
        )
    return m


@dataclass(frozen=True, eq=False)
class ReducedModel:
    """Reduced structure of thesis Eq 5.14 with its recovery matrices (Eq 5.11, 5.18).

    Reduced coordinates ``x = [d_e; q]``: the exterior DOF in the order given to :func:`cms_reduce`,
    followed by the modal coordinates (rigid-body modes first if kept, then elastic modes).

    Attributes
    ----------
    Psi : numpy.ndarray
        (n, m) transformation ``Ψ`` of Eq 5.12, rows in the original DOF order.
    M, K : numpy.ndarray
        (m, m) reduced mass and stiffness ``Ψ^T M Ψ``, ``Ψ^T K Ψ`` (symmetric).
    C : numpy.ndarray or None
        (m, m) reduced damping ``Ψ^T C Ψ`` (Sec 5.2.3.3), if a damping matrix was given.
    exterior, interior : numpy.ndarray
        Original indices of the exterior (kept) and interior DOF.
    names : tuple of str
        Names of the reduced coordinates: exterior DOF names, then ``q_rb1, ..., q1, q2, ...``.
    mode_frequencies : numpy.ndarray
        Frequencies [Hz] of the component modes used in ``χ`` (0 for rigid-body modes).
    interface : str
        ``"free"`` or ``"fixed"``.
    n_rigid : int
        Number of rigid-body modes included in ``χ``.
    T1, T2 : numpy.ndarray
        (n, m) MA recovery matrices of Eq 5.18 (``T2`` acts on the whole ``x``, zero on ``q``).
    T1v : numpy.ndarray or None
        (n, m) damping analogue of ``T1`` (None without ``C``).
    G_ii : numpy.ndarray
        (I, I) ``K_ii^{-1}``, the interior block of ``T3`` (Eq 5.18).
    """

    Psi: np.ndarray
    M: np.ndarray
    K: np.ndarray
    C: np.ndarray | None
    exterior: np.ndarray
    interior: np.ndarray
    names: tuple
    mode_frequencies: np.ndarray
    interface: str
    n_rigid: int
    T1: np.ndarray
    T2: np.ndarray
    T1v: np.ndarray | None
    G_ii: np.ndarray = field(repr=False)

    # ---------------------------------------------------------------- sizes
    @property
    def n_full(self) -> int:
        """Number of DOF of the full model."""
        return self.Psi.shape[0]

    @property
    def n_reduced(self) -> int:
        """Number of reduced coordinates ``E + P (+ rigid)``."""
        return self.Psi.shape[1]

    @property
    def n_exterior(self) -> int:
        """Number of exterior DOF ``E``."""
        return self.exterior.size

    # ---------------------------------------------------------------- analysis
    def natural_frequencies(self) -> np.ndarray:
        """Undamped natural frequencies [Hz] of the reduced model (ascending; rigid modes ~0)."""
        lam = sla.eigh(self.K, self.M, eigvals_only=True)
        return np.sqrt(np.clip(lam, 0.0, None)) / (2.0 * np.pi)

    def force(self, F) -> np.ndarray:
        """Reduced load ``Ψ^T F`` (Eq 5.14); ``F`` is ``(n,)`` or ``(n, nt)``."""
        return self.Psi.T @ _finite("F (full load vector)", F, self.n_full)

    def _T3F(self, F) -> np.ndarray:
        F = np.asarray(F, dtype=float)
        out = np.zeros_like(F, dtype=float)
        out[self.interior] = self.G_ii @ F[self.interior]
        return out

    def recover(self, x, xdd=None, f=None, *, method: str = "MA", at=None, xd=None) -> np.ndarray:
        """Full-model displacements from reduced coordinates (MD Eq 5.11 or MA Eq 5.18).

        Parameters
        ----------
        x : array_like
            Reduced coordinates ``[d_e; q]``, ``(m,)`` or a history ``(m, nt)``.
        xdd : array_like, optional
            Reduced accelerations (same shape as ``x``); MA only.  Omitted = quasi-static (zero).
        f : array_like, optional
            Full load vector ``F`` (``(n,)`` or ``(n, nt)``), e.g. ``N(z)^T f_nut``; MA only.
            Omitted = no interior load.
        method : {"MA", "MD"}
            Modal acceleration (default) or mode displacement recovery.
        at : int, sequence of int, array_like or sparse matrix, optional
            Where to recover: DOF index/indices, or a ``(k, n)`` row matrix such as a shape-function
            row ``N(z)`` (the response at an arbitrary axial point).  Default: all ``n`` DOF.
        xd : array_like, optional
            Reduced velocities; adds the damping term of the MA recovery when the model has ``C``.

        Returns
        -------
        numpy.ndarray
            ``(n,)``/``(k,)`` (or with a trailing time axis) recovered displacements.
        """
        x = _finite("x (reduced coordinates)", x, self.n_reduced)
        if _method(method) == "MD":
            d = self.Psi @ x
        else:
            d = self.T2 @ x
            if xdd is not None:
                d = d + self.T1 @ np.asarray(xdd, dtype=float)
            if xd is not None and self.T1v is not None:
                d = d + self.T1v @ np.asarray(xd, dtype=float)
            if f is not None:
                f = np.asarray(f, dtype=float)
                if f.shape[0] != self.n_full:
                    raise UsageError(f"f must have {self.n_full} rows (full load vector), got {f.shape}")
                d = d + self._T3F(f)
        if at is None:
            return d
        return np.asarray(_rows(at, self.n_full) @ d)

    def port(self, row) -> ReducedPort:
        """Input/output matrices for a load/sensing row ``N`` (see :class:`ReducedPort`).

        Cost: products of the (sparse) row with precomputed ``n x m`` matrices and a ``k x k`` block
        of ``K_ii^{-1}``; no factorisation, so it can be called at every time step as the nut moves.

        Parameters
        ----------
        row : int, sequence of int, array_like or sparse matrix
            DOF index/indices or a ``(k, n)`` matrix such as ``N(z)`` restricted to the model's DOF.
        """
        R = _rows(row, self.n_full, "row")
        Ri = R[:, self.interior]
        if sp.issparse(Ri):
            Ri = Ri.tocsc()
            nzc = np.unique(Ri.nonzero()[1])
            Rn = Ri[:, nzc].toarray()
            D = Rn @ self.G_ii[np.ix_(nzc, nzc)] @ Rn.T
        else:
            D = Ri @ self.G_ii @ Ri.T

        def mat(A):
            return np.asarray(R @ A)

        C_md = mat(self.Psi)
        k = C_md.shape[0]
        C_v = mat(self.T1v) if self.T1v is not None else np.zeros((k, self.n_reduced))
        return ReducedPort(B=C_md.T.copy(), C_md=C_md, C_x=mat(self.T2), C_a=mat(self.T1), C_v=C_v,
                           D=0.5 * (D + D.T))


# --------------------------------------------------------------------------------------------
# reduction
# --------------------------------------------------------------------------------------------
def cms_reduce(
    M: Any,
    K: Any,
    boundary_dofs: Any,
    n_modes: int | None = None,
    *,
    f_cut: float | None = None,
    C: Any = None,
    interface: str = "free",
    rigid_body_modes: bool = True,
    dof_names: Sequence[str] | None = None,
    rigid_tol: float = 1e-8,
) -> ReducedModel:
    r"""Reduce ``(M, K[, C])`` by Component Mode Synthesis, thesis Eq 5.10-5.14.

    Parameters
    ----------
    M, K : (n, n) array_like or scipy.sparse matrix
        Symmetric mass (positive definite) and stiffness (positive semi-definite) matrices.
    boundary_dofs : int, str or sequence
        Exterior DOF ``e`` (indices 0..n-1, or names if ``dof_names`` is given): DOF where actuation or
        joint forces act and anchor DOF (Sec 5.3.2: the motor rotation and a screw node).  They must
        restrain every rigid-body motion, so that ``K_ii`` is invertible (Eq 5.13).
    n_modes : int, optional
        Number ``P`` of elastic normal modes kept in ``χ`` (Eq 5.12).
    f_cut : float, optional
        Alternatively keep every elastic mode with frequency ``<= f_cut`` [Hz].  Give exactly one of
        ``n_modes`` and ``f_cut``.
    C : (n, n) array_like, optional
        Viscous damping matrix; reduced as ``Ψ^T C Ψ`` (Sec 5.2.3.3).
    interface : {"free", "fixed"}
        ``"free"``: interior rows of the free-interface modes of the whole structure (the thesis's
        choice, Sec 5.2.3.2).  ``"fixed"``: modes of ``(K_ii, M_ii)`` (Craig-Bampton).
    rigid_body_modes : bool
        Free interface only: also put the structure's rigid-body modes (interior rows) in ``χ``
        (the thesis's sub-model 1 has ``E + P + 1`` coordinates, Sec 5.3.2).
    dof_names : sequence of str, optional
        Names of the ``n`` DOF; used for ``boundary_dofs`` and :attr:`ReducedModel.names`.
    rigid_tol : float
        A free-structure mode is rigid if its eigenvalue is ``<= rigid_tol * max(eig)`` (``0 < rigid_tol < 1``).

    Returns
    -------
    ReducedModel

    Raises
    ------
    UsageError
        Bad shapes, unknown/duplicate DOF, both or neither of ``n_modes``/``f_cut``, more modes than interior
        DOF, unknown ``interface``, ``rigid_tol`` outside ``(0, 1)``.
    ParameterError
        Non-symmetric or non-finite matrices, or ``K`` not positive semi-definite.
    SingularSystemError
        ``K_ii`` is singular (the exterior DOF leave a rigid-body motion free), ``M`` is not positive
        definite, or the chosen basis ``Ψ`` is rank deficient.

    Notes
    -----
    Ψ (Eq 5.12) stacks the constraint modes ``[I; φ_ie]`` (Eq 5.13) and the columns ``[0; χ_ip]``.
    Normal modes are mass-normalised on the structure they come from.  The reduction has
    ``(I - P)`` fewer DOF than the original (Eq 5.14).
    """
    Md = as_dense_symmetric(M, "M")
    n = Md.shape[0]
    Kd = as_dense_symmetric(K, "K", n)
    Cd = None if C is None else as_dense_symmetric(C, "C", n)
    e, i = _check_cms_arguments(n, boundary_dofs, dof_names, n_modes, f_cut, interface)
    rigid_tol = check_number("rigid_tol", rigid_tol, positive=True)
    if not rigid_tol < 1:
        raise UsageError(f"rigid_tol must be < 1 (a fraction of the largest eigenvalue, e.g. 1e-8), got {rigid_tol!r}")
    lam, V, n_r = _free_modes(Md, Kd, e, rigid_tol)
    G_ii, phi = _constraint_modes(Md, Kd, e, i)
    chi, f_el, P, n_rb = _normal_modes(Md, Kd, lam, V, n_r, i, interface, rigid_body_modes, n_modes, f_cut)
    m = e.size + chi.shape[1]
    Psi = np.zeros((n, m))
    Psi[e, np.arange(e.size)] = 1.0
    Psi[np.ix_(i, np.arange(e.size))] = phi
    Psi[np.ix_(i, np.arange(e.size, m))] = chi

    def congruence(A):
        R = Psi.T @ A @ Psi
        return 0.5 * (R + R.T)

    Mr, Kr = congruence(Md), congruence(Kd)
    Cr = None if Cd is None else congruence(Cd)
    try:
        sla.cholesky(Mr, lower=True)
    except np.linalg.LinAlgError:
        raise SingularSystemError(
            "reduced mass matrix is not positive definite: the CMS basis Ψ is rank deficient "
            "(a kept mode lies in the span of the constraint modes); keep fewer modes"
        ) from None
    T1, T2, T1v = _recovery_matrices(Md, Cd, Psi, G_ii, phi, chi, e, i)
    ext_names = [dof_names[k] for k in e] if dof_names is not None else [f"d{k}" for k in e]
    names = tuple(ext_names + [f"q_rb{k + 1}" for k in range(n_rb)] + [f"q{k + 1}" for k in range(P)])
    return ReducedModel(
        Psi=Psi, M=Mr, K=Kr, C=Cr, exterior=e, interior=i, names=names,
        mode_frequencies=np.concatenate([np.zeros(n_rb), f_el[:P]]), interface=interface, n_rigid=n_rb,
        T1=T1, T2=T2, T1v=T1v, G_ii=G_ii,
    )


def _check_cms_arguments(n, boundary_dofs, dof_names, n_modes, f_cut, interface):
    """Exterior ``e`` and interior ``i`` DOF indices, after checking every argument of :func:`cms_reduce`."""
    if dof_names is not None and len(dof_names) != n:
        raise UsageError(f"dof_names must have {n} entries, got {len(dof_names)}")
    e = _index_list(boundary_dofs, n, dof_names, "boundary_dofs")
    if e.size == 0:
        raise UsageError("boundary_dofs: at least one exterior DOF is needed")
    if (n_modes is None) == (f_cut is None):
        raise UsageError("give exactly one of n_modes and f_cut")
    if n_modes is not None and (isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer))
                                or n_modes < 0):
        raise UsageError(f"n_modes must be a non-negative integer, got {n_modes!r}")
    if f_cut is not None:
        check_number("f_cut (a frequency [Hz])", f_cut, nonnegative=True)
    if interface not in ("free", "fixed"):
        raise UsageError(f"interface must be 'free' or 'fixed', got {interface!r}")
    return e, np.setdiff1d(np.arange(n), e)


def _free_modes(Md, Kd, e, rigid_tol):
    """Normal modes of the whole structure (Eq 5.10) and the number of rigid-body modes, which the
    exterior DOF must restrain (else ``K_ii`` is singular, Eq 5.13)."""
    try:
        sla.cholesky(Md, lower=True)
    except np.linalg.LinAlgError as exc:
        raise SingularSystemError("M must be positive definite for a CMS reduction") from exc
    lam, V = sla.eigh(Kd, Md)
    scale = max(float(np.max(np.abs(lam))), np.finfo(float).tiny)
    if lam[0] < -rigid_tol * scale:
        neg = int(np.count_nonzero(lam < -rigid_tol * scale))
        raise ParameterError(f"K must be positive semi-definite for a CMS reduction: its most negative eigenvalue "
                             f"(K phi = lam M phi) is {lam[0]:.4g}, of {neg} negative one(s); check the stiffness "
                             "matrix's signs and assembly")
    n_r = int(np.count_nonzero(lam <= rigid_tol * scale))
    if n_r:
        s = sla.svdvals(V[np.ix_(e, np.arange(n_r))]) if e.size >= n_r else np.zeros(1)
        if s.size < n_r or s.min() <= 1e-6 * np.max(np.abs(V[:, :n_r])):
            raise SingularSystemError(
                f"K_ii is singular: the structure has {n_r} rigid-body mode(s) and the exterior DOF do "
                "not restrain all of them (Eq 5.13 needs K_ii invertible); add a DOF of each free "
                "motion (e.g. the motor rotation) to boundary_dofs"
            )
    return lam, V, n_r


def _constraint_modes(Md, Kd, e, i):
    """``G_ii = K_ii^-1`` and the constraint modes ``phi_ie = -K_ii^-1 K_ie`` (Eq 5.13)."""
    Kii, Kie = Kd[np.ix_(i, i)], Kd[np.ix_(i, e)]
    try:
        Kii_f = sla.cho_factor(Kii, lower=True)
    except np.linalg.LinAlgError:
        raise SingularSystemError(
            "K_ii is singular: the exterior DOF leave a rigid-body motion of the interior free "
            "(Eq 5.13 needs K_ii invertible); add a DOF of each free motion (e.g. the motor rotation) "
            "to boundary_dofs"
        ) from None
    G_ii = sla.cho_solve(Kii_f, np.eye(i.size))
    G_ii = 0.5 * (G_ii + G_ii.T)
    return G_ii, -G_ii @ Kie


def _normal_modes(Md, Kd, lam, V, n_r, i, interface, rigid_body_modes, n_modes, f_cut):
    """The kept normal modes ``chi`` (interior rows, Eq 5.12), their frequencies, count P and rigid count."""
    if interface == "free":
        lam_el, V_el = lam[n_r:], V[:, n_r:]
        V_rb = V[:, :n_r] if rigid_body_modes else V[:, :0]
    else:
        lam_el, V_el = sla.eigh(Kd[np.ix_(i, i)], Md[np.ix_(i, i)])
        V_rb = np.zeros((i.size, 0))
    f_el = np.sqrt(np.clip(lam_el, 0.0, None)) / (2.0 * np.pi)
    P = int(np.count_nonzero(f_el <= f_cut)) if f_cut is not None else int(n_modes)
    n_rb = V_rb.shape[1]
    if P + n_rb > i.size:
        rb = f" (+{n_rb} rigid-body)" if n_rb else ""
        raise UsageError(f"{P} mode(s){rb} requested but only {i.size} interior DOF exist: keep fewer modes"
                         + (" or pass rigid_body_modes=False" if n_rb else "") + " or fewer boundary DOF")
    chi = np.hstack([V_rb, V_el[:, :P]])
    return (chi[i] if interface == "free" else chi), f_el, P, n_rb


def _recovery_matrices(Md, Cd, Psi, G_ii, phi, chi, e, i):
    """MA recovery matrices ``T1``, ``T2`` (and ``T1v`` with damping), Eq 5.18."""
    n, m = Psi.shape
    Mii, Mie = Md[np.ix_(i, i)], Md[np.ix_(i, e)]
    T1 = np.zeros((n, m))
    T1[np.ix_(i, np.arange(e.size))] = -G_ii @ (Mie + Mii @ phi)
    T1[np.ix_(i, np.arange(e.size, m))] = -G_ii @ (Mii @ chi)
    T2 = np.zeros((n, m))
    T2[:, : e.size] = Psi[:, : e.size]
    T1v = None
    if Cd is not None:
        Cii, Cie = Cd[np.ix_(i, i)], Cd[np.ix_(i, e)]
        T1v = np.zeros((n, m))
        T1v[np.ix_(i, np.arange(e.size))] = -G_ii @ (Cie + Cii @ phi)
        T1v[np.ix_(i, np.arange(e.size, m))] = -G_ii @ (Cii @ chi)
    return T1, T2, T1v


def reduce_second_order(model, boundary, n_modes: int | None = None, *, f_cut: float | None = None,
                        interface: str = "free", rigid_body_modes: bool = True):
    """CMS-reduce a :class:`bscomp.linear.SecondOrderModel` (inputs, outputs and damping included).

    The reduced model has ``M_r = Ψ^T M Ψ`` etc. (Eq 5.14), inputs ``Ψ^T B`` and mode-displacement
    outputs ``C Ψ`` (Eq 5.11); use :meth:`ReducedModel.recover` with ``method="MA"`` for loads on
    interior DOF. Returns ``(SecondOrderModel, ReducedModel)``; put the first into a system with
    :class:`~components.second_order_block.SecondOrderBlock`.

    Parameters
    ----------
    model : SecondOrderModel
    boundary : str or sequence of str
        Coordinate names kept exactly (actuated DOF, joint DOF, anchors; Sec 5.3.2).
    """

    red = cms_reduce(model.M, model.K, check_names("boundary", boundary), n_modes, f_cut=f_cut, C=model.C,
                     interface=interface, rigid_body_modes=rigid_body_modes, dof_names=list(model.coordinates))
    Psi = sp.csr_matrix(red.Psi)

    def out(A):
        return sp.csr_matrix(sp.csr_matrix(A) @ Psi)

    C = red.C if red.C is not None else np.zeros_like(red.M)
    reduced = SecondOrderModel(
        M=sp.csr_matrix(red.M), C=sp.csr_matrix(C), K=sp.csr_matrix(red.K), B=sp.csr_matrix(Psi.T @ model.B),
        Cq=out(model.Cq), Cv=out(model.Cv), Ca=out(model.Ca), D=sp.csr_matrix(model.D),
        coordinates=list(red.names), units=["" for _ in red.names], inputs=list(model.inputs),
        outputs=list(model.outputs))
    return reduced, red
