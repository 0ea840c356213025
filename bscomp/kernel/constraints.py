"""Constraint elimination: ideal holonomic constraints removed by a coordinate map (flattening step 3).

The affine constraints ``A q + b = 0`` that components declare (rigid joints, the ideal lead screw
``s = r_g phi`` -- Modelica's ``IdealGearR2T`` --, fixed points) are eliminated by sparse Gauss-Jordan
with partial pivoting, giving ``q = T q_r + t0`` over independent coordinates ``q_r``. Their reactions
``A^T lambda`` vanish in the projected balance ``T^T Q(q, q', q'') = 0`` (principle of virtual work,
d'Alembert), so no Lagrange multipliers and no index reduction are needed. The linear structural blocks
(FE beams, lumped bodies, the screw-nut stiffness ``K_SN``, thesis Eq 3.44) are projected the same way,
``M_r = T^T M T`` etc., as sparse products.
"""

from __future__ import annotations

from collections import defaultdict

import casadi as ca
import numpy as np
import scipy.sparse as sp

from bscomp.errors import OverdeterminedError
from bscomp.kernel.dae import dm_sparse

__all__ = ["eliminate_constraints", "substitution_stages", "apply_stages", "project_balance", "project_blocks"]


def _reduce_row(coeffs, b, dep):
    """One constraint row with the already-eliminated coordinates substituted: ``(lin, const)``."""
    lin = defaultdict(float)
    const = b
    for c, a in coeffs.items():
        if c in dep:
            d, k = dep[c]
            for j, t in d.items():
                lin[j] += a * t
            const += a * k
        else:
            lin[c] += a
    scale = max([abs(a) for a in coeffs.values()] + [1e-300])
    return {c: a for c, a in lin.items() if abs(a) > 1e-12 * scale}, const


def _coordinate_map(dep, nq):
    """``T`` (sparse), ``t0`` and the independent coordinates of the map ``q = T q_r + t0``."""
    indep = [c for c in range(nq) if c not in dep]
    col = {c: i for i, c in enumerate(indep)}
    rows, cols, vals = [], [], []
    for c in indep:
        rows.append(c)
        cols.append(col[c])
        vals.append(1.0)
    t0 = np.zeros(nq)
    for c, (d, k) in dep.items():
        t0[c] = k
        for j, a in d.items():
            if a != 0.0:
                rows.append(c)
                cols.append(col[j])
                vals.append(a)
    T = sp.coo_matrix((vals, (rows, cols)), shape=(nq, len(indep)))
    return T, t0, indep


def eliminate_constraints(constraints, nq, coord_names):
    """Sparse Gauss-Jordan with partial pivoting: ``q = T q_r + t0``.

    Parameters
    ----------
    constraints : list of (dict, float, int or None, str)
        Rows ``{coordinate: coefficient}``, constant ``b``, preferred pivot, origin (for messages).
    nq : int
        Number of coordinates.
    coord_names : list of str

    Returns
    -------
    T : scipy.sparse.coo_matrix, t0 : ndarray, indep : list of int, dep : dict
        The map, the independent coordinates, and each dependent one's ``({coordinate: coef}, const)``.

    Raises
    ------
    OverdeterminedError
        For an inconsistent or redundant constraint (a closed kinematic loop, a point fixed twice).
    """
    dep = {}                      # coordinate -> (dict{coord: coef}, const)
    users = defaultdict(set)      # independent coordinate -> dependents that reference it
    origin_of = {}
    for coeffs, b, sf, origin in constraints:
        lin, const = _reduce_row(coeffs, b, dep)
        if not lin:
            names = ", ".join(coord_names[c] for c in coeffs)
            who = ", ".join(dict.fromkeys(origin_of[c] for c in coeffs if c in origin_of)) or (
                "the connections (ports it ties together are connected to each other, directly or through "
                "other joints)")
            if abs(const) > 1e-9 * max(1.0, abs(b)):
                raise OverdeterminedError(f"inconsistent constraints on {names}: {origin} contradicts {who}; "
                                          "remove one of them")
            raise OverdeterminedError(f"redundant constraint on {names}: {origin} repeats what {who} already "
                                      "imposes (a closed kinematic loop or a point fixed twice); remove one of them")
        if sf is not None and sf in lin:
            piv = sf
        else:
            piv = max(lin, key=lambda c: (abs(lin[c]) * (1 + 1e-9), c))
        ap = lin.pop(piv)
        expr = {j: -a / ap for j, a in lin.items()}
        kconst = -const / ap
        # substitute pivot into existing dependents
        for d_c in list(users.get(piv, ())):
            d, k = dep[d_c]
            t = d.pop(piv)
            for j, a in expr.items():
                d[j] = d.get(j, 0.0) + t * a
                users[j].add(d_c)
            dep[d_c] = (d, k + t * kconst)
        users.pop(piv, None)
        dep[piv] = (expr, kconst)
        origin_of[piv] = origin
        for j in expr:
            users[j].add(piv)
    T, t0, indep = _coordinate_map(dep, nq)
    return T, t0, indep, dep


def substitution_stages(sig, Tcsr, t0, dep_of, full, reduced):
    """The substitutions that express everything in (x, x', z, u, p): signals first (their definitions
    may use dependent coordinates), then dependent coordinates ``q_d = T_d q_r + t0_d`` and their
    derivatives.

    ``full`` and ``reduced`` are the (position, velocity, acceleration) symbol lists of all and of the
    independent coordinates.
    """
    dep_idx = sorted(dep_of)
    q_full, qd_full, qdd_full = full
    qr, qdr, qddr = reduced
    sub_from = []
    sub_to = []
    if dep_idx:
        Td = dm_sparse(Tcsr[dep_idx, :])
        qr_v, qdr_v, qddr_v = ca.vertcat(*qr), ca.vertcat(*qdr), ca.vertcat(*qddr)
        qdep = ca.mtimes(Td, qr_v) + ca.DM(t0[dep_idx])
        qddep = ca.mtimes(Td, qdr_v)
        qdddep = ca.mtimes(Td, qddr_v)
        for j, c in enumerate(dep_idx):
            sub_from += [q_full[c], qd_full[c], qdd_full[c]]
            sub_to += [qdep[j], qddep[j], qdddep[j]]
    return [(sig.sig_from, sig.sig_to), (sub_from, sub_to)]


def apply_stages(e, stages):
    """Apply substitution stages in order (each stage simultaneous)."""
    for frm, to in stages:
        if frm:
            e = ca.substitute(e, ca.vertcat(*frm), ca.densify(ca.vertcat(*to)))
    return e


def project_balance(Q, TT, nr, eqs, stages):
    """Projected force balances ``R = T^T Q`` (sparse, never dense) and the internal equations, both
    with the substitutions applied. Returns ``(R, eqs)`` as lists/SX."""
    Qsum = [ca.sum1(ca.vertcat(*lst)) if lst else ca.SX(0) for lst in Q]
    R = []
    for j in range(nr):
        row = slice(TT.indptr[j], TT.indptr[j + 1])
        terms = [float(a) * Qsum[c] if a != 1.0 else Qsum[c] for c, a in zip(TT.indices[row], TT.data[row])]
        R.append(ca.sum1(ca.vertcat(*terms)) if terms else ca.SX(0))
    big = apply_stages(ca.vertcat(*(R + eqs)), stages)
    return big[:nr], big[nr:]


def project_blocks(blocks, nq, Tcsr, TT, t0):
    """Structural blocks summed over the coordinates and projected: ``(M_r, C_r, K_r, T^T K t0)``."""
    Ms, Cs, Ks = (sp.csr_matrix((nq, nq)) for _ in range(3))
    for idx, Mb, Cb, Kb in blocks:
        P = sp.csr_matrix((np.ones(len(idx)), (idx, np.arange(len(idx)))), shape=(nq, len(idx)))
        if Mb is not None:
            Ms = Ms + P @ sp.csr_matrix(Mb) @ P.T
        if Cb is not None:
            Cs = Cs + P @ sp.csr_matrix(Cb) @ P.T
        if Kb is not None:
            Ks = Ks + P @ sp.csr_matrix(Kb) @ P.T
    Mr = (TT @ Ms @ Tcsr).tocsc()
    Cr = (TT @ Cs @ Tcsr).tocsc()
    Kr = (TT @ Ks @ Tcsr).tocsc()
    # affine offset of dependent coordinates acting through structural stiffness
    Kt0 = TT @ (Ks @ t0) if np.any(t0) else np.zeros(TT.shape[0])
    return Mr, Cr, Kr, Kt0

