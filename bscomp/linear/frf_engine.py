r"""The one FRF engine: every frequency response bscomp computes goes through these functions.

All evaluate the second-order response (thesis Eq 4.2-4.9)

.. math:: H(j\omega) = (C_q + j\omega C_v - \omega^2 C_a)\,(K + j\omega C - \omega^2 M)^{-1} B + D

and differ only in how the inverse is applied, chosen by what the caller knows:

* :func:`direct_frf` -- one sparse LU per frequency: any model, singular ``M`` included (the reference).
* :func:`state_space_modal_frf` -- one eigen-decomposition of the first-order form ``(q, q')``
  (:func:`state_space_decomposition`), then the partial-fraction sum: any viscous damping.
* :func:`modal_frf` -- from mass-normalised undamped modes ``(lam, phi)``: modal damping on the diagonal,
  discrete dampers by the Woodbury identity (a low-rank correction), optionally a subset of modes with
  the static residual flexibility of the others, and an exact delay ``e^{-s tau}``. Used by position
  sweeps (:mod:`bscomp.linear.sweeps`) and the compiled model fits (:class:`bscomp.CompiledModel`).

:meth:`SecondOrderModel.frf <bscomp.linear.SecondOrderModel.frf>` and :func:`bscomp.frf` pick between the
first two. Only numpy/scipy; nothing here knows about Dae or System.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["direct_frf", "state_space_decomposition", "state_space_modal_frf", "modal_frf", "dense"]

#: discrete dampers acting on more coordinates than this are handled by a dense modal solve
WOODBURY_LIMIT = 40


def dense(A, dtype=None) -> np.ndarray:
    """A dense ndarray from a dense or scipy.sparse matrix (cast to ``dtype`` if given)."""
    return np.asarray(A.toarray() if sp.issparse(A) else A, dtype)


def direct_frf(M, C, K, B, Cq, Cv, Ca, D, freqs_hz) -> np.ndarray:
    """``H[k, out, in]`` by one sparse LU of ``K + j w C - w^2 M`` per frequency (no dense inverse)."""
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    n = M.shape[0]
    Bd, Dd = dense(B), dense(D)
    H = np.zeros((f.size, Dd.shape[0], Bd.shape[1]), complex)
    M, C, K = (sp.csc_matrix(m, dtype=complex) for m in (M, C, K))
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        Z = (K + 1j * w * C - w * w * M).tocsc()
        X = spla.splu(Z).solve(Bd.astype(complex)) if Bd.size else np.zeros((n, 0), complex)
        H[k] = np.asarray((Cq + 1j * w * Cv - w * w * Ca) @ X) + Dd
    return H


def state_space_decomposition(M, C, K, B, Cq, Cv, Ca):
    """Eigen-decomposition of ``A = [[0, I], [-M^-1 K, -M^-1 C]]`` with input/output projections, or
    None when ``M`` is singular or the eigenvectors are defective (repeated rigid-body poles)."""
    n = M.shape[0]
    Md = dense(M)
    try:
        cho = sla.cho_factor(Md)
    except np.linalg.LinAlgError:
        return None
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-sla.cho_solve(cho, dense(K)), -sla.cho_solve(cho, dense(C))]])
    lam, V = sla.eig(A)
    if np.linalg.cond(V) > 1e12:
        return None
    Bd = dense(B)
    W = np.linalg.solve(V, np.vstack([np.zeros((n, Bd.shape[1])), sla.cho_solve(cho, Bd)]))
    return lam, W, dense(Cq) @ V[:n], dense(Cv) @ V[n:], dense(Ca) @ V[n:]


def state_space_modal_frf(decomposition, D, freqs_hz) -> np.ndarray:
    """``H`` from :func:`state_space_decomposition`: ``y = Cq q + Cv v + Ca s v`` with ``x = (q, v)``."""
    lam, W, CqV, CvV, CaV = decomposition
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    Dd = dense(D)
    H = np.zeros((f.size, CqV.shape[0], W.shape[1]), complex)
    for k, fk in enumerate(f):
        s = 2j * np.pi * fk
        H[k] = (CqV + CvV + s * CaV) @ (W / (s - lam)[:, None]) + Dd
    return H


def modal_frf(lam, phi, c_modal, C_struct, B, Cq, Cv, Ca, D, freqs_hz, *, modes=None, delay: float = 0.0):
    r"""Exact FRF from mass-normalised undamped modes, with discrete dampers and residual flexibility.

    ``C = M phi diag(c_modal) phi^T M + C_struct``: proportional modal damping plus discrete dampers.
    The modal part is diagonal; the dampers, acting on the few coordinates ``S`` where ``C_struct`` is
    non-zero, enter by the Woodbury identity
    ``(Dg + U^T W U)^{-1} = Dg^{-1} - Dg^{-1} U^T (I + W U Dg^{-1} U^T)^{-1} W U Dg^{-1}`` with
    ``U = phi[S]``, ``W = j w C_struct[S, S]`` (cost per frequency O(m (r + n_in + n_out)) for m modes
    and r damped coordinates); beyond :data:`WOODBURY_LIMIT` coordinates a dense modal solve is used.

    ``modes`` (indices) keeps only those modes dynamically; the others, which must be elastic, enter as
    the static residual flexibility ``R = sum_k phi_k phi_k^T / lam_k`` (so the low-frequency
    compliance stays exact). ``delay`` multiplies by ``e^{-j w delay}``.

    Returns
    -------
    ndarray, shape (n_freqs, n_out, n_in)
    """
    w = 2.0 * np.pi * np.atleast_1d(np.asarray(freqs_hz, float))
    lam, phi, c_modal = np.asarray(lam, float), np.asarray(phi, float), np.asarray(c_modal, float)
    Bd, Cqd, Cvd, Cad = dense(B), dense(Cq), dense(Cv), dense(Ca)
    Cs = sp.csr_matrix(C_struct)
    residual = None
    if modes is not None:
        modes = np.asarray(modes, int)
        rest = np.setdiff1d(np.arange(lam.size), modes)
        if rest.size:
            pt = phi[:, rest]
            residual = (pt / lam[rest]) @ (pt.T @ Bd)
        lam, phi, c_modal = lam[modes], phi[:, modes], c_modal[modes]
    S = np.unique(np.concatenate([Cs.nonzero()[0], Cs.nonzero()[1]])) if Cs.nnz else np.zeros(0, int)
    if S.size > WOODBURY_LIMIT:
        H = _dense_modal(w, lam, phi, c_modal, Cs, Bd, Cqd, Cvd, Cad)
    else:
        H = _woodbury_modal(w, lam, phi, c_modal, Cs, S, Bd, Cqd, Cvd, Cad)
    if residual is not None:
        s = 1j * w
        H = H + (Cqd[None] + s[:, None, None] * Cvd[None] + (s ** 2)[:, None, None] * Cad[None]) @ residual[None]
    H = H + dense(D)[None]
    if delay:
        H = H * np.exp(-1j * w * delay)[:, None, None]
    return H


def _dense_modal(w, lam, phi, c_modal, Cs, B, Cq, Cv, Ca):
    """``(Cq + s Cv + s^2 Ca) phi (s^2 + s Cm + Lambda)^{-1} phi^T B`` with a full modal damping matrix."""
    s = 1j * w
    m = lam.size
    Cm = np.diag(c_modal) + phi.T @ (Cs @ phi)
    Z = (np.diag(lam)[None] + s[:, None, None] * Cm[None] + (s ** 2)[:, None, None] * np.eye(m)[None])
    eta = np.linalg.solve(Z, np.broadcast_to((phi.T @ B).astype(complex), (w.size, m, B.shape[1])))
    return (Cq[None] + s[:, None, None] * Cv[None] + (s ** 2)[:, None, None] * Ca[None]) @ (phi[None] @ eta)


def _woodbury_modal(w, lam, phi, c_modal, Cs, S, B, Cq, Cv, Ca):
    """The diagonal modal response plus the low-rank correction of the discrete dampers on ``S``."""
    nf, m = w.size, lam.size
    re = lam[None, :] - w[:, None] ** 2                                                   # Dg = re + j im
    im = w[:, None] * c_modal[None, :]
    den = re * re + im * im
    Dr, Dm = re / den, -im / den                                                           # Dg^-1 (nf, m)
    # output rows (Cq + jw Cv - w^2 Ca) phi, grouped by their factor (1, jw, -w^2)
    A = [(Cq @ phi, np.ones(nf))]
    if np.any(Cv):
        A.append((Cv @ phi, 1j * w))
    if np.any(Ca):
        A.append((Ca @ phi, -(w ** 2)))
    b = phi.T @ B                                                                          # (m, ni)
    U = phi[S]                                                                             # (r, m)
    # every sum_k X[:, k] Dg^-1[f, k] Y[k, :] needed below as one pair of real GEMMs
    X = np.vstack([a for a, _ in A] + [U])
    Y = np.hstack([b, U.T])
    P = np.einsum("ak,kb->kab", X, Y).reshape(m, -1)
    XY = (Dr @ P + 1j * (Dm @ P)).reshape(nf, X.shape[0], Y.shape[1])
    no, ni, r = A[0][0].shape[0], b.shape[1], S.size
    aD = [(XY[:, j * no:(j + 1) * no], f_) for j, (_, f_) in enumerate(A)]
    H = sum(f_[:, None, None] * blk[:, :, :ni] for blk, f_ in aD)                           # a Dg^-1 b
    if r:
        W = 1j * w[:, None, None] * Cs[S][:, S].toarray()[None]                              # (nf, r, r)
        G = XY[:, -r:, ni:]                                                                  # U Dg^-1 U^T
        inner = np.linalg.solve(np.eye(r)[None] + W @ G, W @ XY[:, -r:, :ni])               # (nf, r, ni)
        aDU = sum(f_[:, None, None] * blk[:, :, ni:] for blk, f_ in aD)                     # a Dg^-1 U^T
        H = H - aDU @ inner
    return H
