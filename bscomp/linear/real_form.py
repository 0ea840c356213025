"""Real block-diagonal (modal) form of a state matrix: ``A P = P Λ`` with ``Λ`` block diagonal.

A 2 x 2 block ``[[σ, ω], [-ω, σ]]`` per oscillating mode (eigenvalues ``σ ± jω``), 1 x 1 blocks for real
eigenvalues and one dense block for the eigenvalues at zero (a free rigid body: a Jordan block when
undamped). Exact for any damping (modal, discrete, non-proportional): the damping is part of ``A`` and
ends up in the blocks. Used by the modal transcription of :mod:`bscomp.optimal` and by the compiled
time series of :mod:`bscomp.simulation.compiled_time` (an ``O(n)`` state update per step).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from bscomp.errors import BscompError

__all__ = ["ModalError", "modal_basis"]


class ModalError(BscompError):
    """The model cannot be put in modal coordinates (not linear, or not block-diagonalisable)."""


def modal_basis(A, zero_tol: float = 1e-7):
    """Real block-diagonalising transform of ``A``.

    Parameters
    ----------
    A : (n, n) array
    zero_tol : float
        Eigenvalues with ``|λ| <= zero_tol * max|λ|`` form the zero (rigid-body) block.

    Returns
    -------
    dict
        ``P``, ``Pinv``, ``Lam`` (block diagonal, ``Pinv A P``), ``blocks``: list of ``(columns, kind, λ)``,
        kind ``"real"`` or ``"pair"`` (λ with ω > 0), then ``"zero"`` (one block for all zero eigenvalues),
        contiguous and in that order; ``cond``: the condition number of the basis of the balanced ``A``.
        Columns are normalised to unit 2-norm (a pair: ``|a|² + |b|² = 1``) before the balancing is undone.

    Raises
    ------
    ModalError
        A non-real spectrum, a singular (defective) transform, or one that leaves off-block terms above
        1e-6 of ``max|Λ|``.
    """
    A = np.asarray(A, float)
    n = A.shape[0]
    if n == 0:
        return {"P": np.zeros((0, 0)), "Pinv": np.zeros((0, 0)), "Lam": np.zeros((0, 0)), "blocks": [], "cond": 1.0}
    # balance first (states in rad, m, rad/s, m/s differ by decades; a balanced A has well-conditioned
    # eigenvectors): A = D Ab D⁻¹, the basis of Ab is mapped back by D
    Ab, (scl, _) = sla.matrix_balance(A, permute=False, separate=True)
    bb = _block_basis(Ab, zero_tol)
    P = scl[:, None] * bb["P"]
    Pinv = bb["Pinv"] / scl[None, :]
    return {"P": P, "Pinv": Pinv, "Lam": bb["Lam"], "blocks": bb["blocks"], "cond": bb["cond"]}


def _block_basis(A, zero_tol):
    n = A.shape[0]
    lam_all = np.linalg.eigvals(A)
    tol = zero_tol * max(float(np.max(np.abs(lam_all))), 1e-300)
    # Schur form with the non-zero eigenvalues first, then decouple the zero cluster (Sylvester)
    T, Z, sdim = sla.schur(A, output="real", sort=lambda x, y: abs(complex(x, y)) > tol)
    T11, T12, T22 = T[:sdim, :sdim], T[:sdim, sdim:], T[sdim:, sdim:]
    S = np.eye(n)
    if 0 < sdim < n:
        Y = sla.solve_sylvester(T11, -T22, -T12)
        S[:sdim, sdim:] = Y
    lam, V = np.linalg.eig(T11) if sdim else (np.zeros(0), np.zeros((0, 0)))
    cols, blocks, k = [], [], 0
    done = np.zeros(len(lam), bool)
    for i in np.argsort(np.abs(lam), kind="stable"):
        if done[i]:
            continue
        li, v = lam[i], V[:, i]
        if abs(li.imag) <= 1e-12 * abs(li):
            v = v.real / np.linalg.norm(v.real)
            cols.append(v[:, None])
            blocks.append((np.array([k]), "real", complex(li.real, 0.0)))
            done[i] = True
            k += 1
            continue
        j = [m for m in range(len(lam)) if not done[m] and m != i and abs(lam[m] - np.conj(li)) <= 1e-9 * abs(li)]
        if not j:
            raise ModalError(f"eigenvalue {li} has no complex conjugate (A not real?)")
        done[i] = done[j[0]] = True
        if li.imag < 0:
            li, v = np.conj(li), np.conj(v)
        v = v / np.linalg.norm(v)
        cols.append(np.column_stack([v.real, v.imag]))
        blocks.append((np.array([k, k + 1]), "pair", complex(li)))
        k += 2
    V1 = np.hstack(cols) if cols else np.zeros((sdim, 0))
    W = np.zeros((n, n))
    W[:sdim, :sdim] = V1
    W[sdim:, sdim:] = np.eye(n - sdim)
    if n - sdim:
        blocks.append((np.arange(sdim, n), "zero", 0j))
    P = Z @ S @ W
    try:
        Pinv = np.linalg.solve(P, np.eye(n))
    except np.linalg.LinAlgError as exc:
        raise ModalError("the modal transform is singular (repeated, defective non-zero eigenvalues)") from exc
    Lam_full = Pinv @ A @ P
    Lam = np.zeros_like(Lam_full)
    for idx, _, _ in blocks:
        Lam[np.ix_(idx, idx)] = Lam_full[np.ix_(idx, idx)]
    off = float(np.max(np.abs(Lam_full - Lam))) if n else 0.0
    scale = max(float(np.max(np.abs(Lam))), 1e-300)
    if off > 1e-6 * scale:
        raise ModalError(f"modal transform inaccurate: off-block residue {off:.3g} vs |Λ| {scale:.3g} "
                         f"(cond(P) = {np.linalg.cond(P):.3g})")
    # a defective non-zero eigenvalue (a Jordan block away from zero) gives nearly parallel eigenvectors:
    # P^-1 A P then looks block diagonal by cancellation while P Λ P^-1 is not A
    rec = float(np.max(np.abs(P @ Lam @ Pinv - A)))
    if rec > 1e-6 * max(float(np.max(np.abs(A))), 1e-300):
        raise ModalError(f"the modal transform does not reproduce A (residue {rec:.3g}, cond(P) = "
                         f"{np.linalg.cond(P):.3g}): a defective (repeated) non-zero eigenvalue")
    return {"P": P, "Pinv": Pinv, "Lam": Lam, "blocks": blocks, "cond": float(np.linalg.cond(P))}
