"""Modal coordinates and residual-vibration bounds for :mod:`bscomp.optimal` (linear models).

Two pieces, both built on one real block-diagonalisation of the state matrix of a linear(ized) model,
``x' = xd0 + A (x - x0) + B u`` (:func:`bscomp.linear.explicit_form`):

* :func:`modal_basis`: ``A P = P Λ`` with ``Λ`` block diagonal -- a 2 x 2 block ``[[σ, ω], [-ω, σ]]`` per
  oscillating mode (eigenvalues ``σ ± jω``; ``σ = -ζω_n`` for a viscously damped mode), 1 x 1 blocks for
  real eigenvalues (e.g. ``-B/J`` of a rigid body on a viscous bearing) and one dense block for the
  eigenvalues at zero (a free rigid body: a Jordan block when undamped). It is exact for any damping
  (modal, a discrete motor damper, non-proportional): the damping is part of ``A`` and ends up in the
  blocks, not in an approximation of it.
* :class:`ModalDae`: the model in those coordinates, ``ξ' = Λ ξ + P⁻¹ (x'0 + B u)`` with ``x = x0 + P ξ``;
  outputs and original states are linear maps of ξ. :func:`solve_condensed` transcribes it with the
  Radau IIA equations solved block by block, so only the inputs and T are unknowns (a dense 98 x 98
  damping matrix would otherwise give dense 196 x 196 Jacobian blocks at every collocation point); with
  ``sparse=True`` it keeps the scaled modal collocation states as variables instead (O(N nx) sparse rows,
  for large models: the condensed expressions are O(N² nx)).
* :func:`residual_rows`: rows ``L`` such that ``||L (x_T - x0) + l|| <= a`` guarantees that the free
  response after ``T`` (input held) stays within ``± a`` of its final value in a named output.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.linalg as sla

from bscomp.errors import BscompError


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
    dict with ``P``, ``Pinv``, ``Lam`` (block diagonal, ``Pinv A P``) and ``blocks``: list of
    ``(columns, kind, λ)``, kind ``"zero"`` (one block for all zero eigenvalues), ``"real"`` or ``"pair"``
    (λ with ω > 0). Columns are normalised to unit 2-norm (a pair: ``|a|² + |b|² = 1``).
    """
    A = np.asarray(A, float)
    n = A.shape[0]
    if n == 0:
        return {"P": np.zeros((0, 0)), "Pinv": np.zeros((0, 0)), "Lam": np.zeros((0, 0)), "blocks": []}
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
    return {"P": P, "Pinv": Pinv, "Lam": Lam, "blocks": blocks, "cond": float(np.linalg.cond(P))}


def _affine(dae, p, x0, u0=None):
    """Linearization of ``dae`` at ``(x0, u0)``: dict A, B, Zx, Zu, xd0, z0 and output Jacobians builder."""
    from bscomp.kernel.dae import _sp
    from bscomp.linear.linearize import explicit_form

    u0 = np.zeros(dae.nu) if u0 is None else u0
    xd0, z0 = dae.initialize(x0, u0, p, store=False)
    _, Jxd, Jx, Jz, Ju = dae.jacobians(xd0, x0, z0, u0, p)
    A, B, Zx, Zu = explicit_form(dae, _sp(Jxd), _sp(Jx), _sp(Jz), _sp(Ju))
    return {"x0": np.asarray(x0, float), "u0": np.asarray(u0, float), "xd0": np.asarray(xd0, float).ravel(),
            "z0": np.asarray(z0, float).ravel(), "A": np.asarray(A), "B": np.asarray(B), "Zx": np.asarray(Zx),
            "Zu": np.asarray(Zu)}


def output_rows(dae, p, lin, names):
    """Exact affine output map of a linear model: ``y = y0 + Cx (x - x0) + Du u`` for each name (an
    observable or a state), derivatives and algebraic variables eliminated through ``A``, ``Zx``."""
    nx, nu = dae.nx, dae.nu
    Cx, Du, y0 = np.zeros((len(names), nx)), np.zeros((len(names), nu)), np.zeros(len(names))
    obs = [n for n in names if n not in dae.x_names]
    if obs:
        f = dae.output_function(obs)
        xd, x, z, u = (ca.SX.sym(s, m) for s, m in (("xd", nx), ("x", nx), ("z", dae.nz), ("u", nu)))
        y = f(xd, x, z, u, p)
        J = ca.Function("J", [xd, x, z, u], [y, ca.jacobian(y, xd), ca.jacobian(y, x), ca.jacobian(y, z),
                                             ca.jacobian(y, u)])
        yv, Jxd, Jx, Jz, Ju = (np.asarray(ca.DM(m)) for m in J(lin["xd0"], lin["x0"], lin["z0"], lin["u0"]))
        Jz = Jz.reshape(len(obs), dae.nz)
        Cobs = Jxd @ lin["A"] + Jx + Jz @ lin["Zx"]
        Dobs = Jxd @ lin["B"] + Ju + Jz @ lin["Zu"]
    for r, n in enumerate(names):
        if n in dae.x_names:
            i = dae.x_names.index(n)
            Cx[r, i], y0[r] = 1.0, lin["x0"][i]
        else:
            o = obs.index(n)
            Cx[r], Du[r], y0[r] = Cobs[o], Dobs[o], float(yv.ravel()[o]) - Dobs[o] @ lin["u0"]
    return y0, Cx, Du


def check_linear(dae, p, lin, rel_tol=1e-8):
    """Raise :class:`ModalError` if the Jacobians of ``F`` differ at a second, perturbed point."""
    from bscomp.kernel.dae import _sp

    rng = np.random.default_rng(0)
    x0, xd0, z0 = lin["x0"], lin["xd0"], lin["z0"]
    pert = [v + (1e-3 + np.abs(v)) * rng.standard_normal(v.shape) for v in (xd0, x0, z0, np.zeros(dae.nu))]
    J0 = dae.jacobians(xd0, x0, z0, lin["u0"], p)[1:]
    J1 = dae.jacobians(*pert, p)[1:]
    for a, b in zip(J0, J1):
        a, b = _sp(a), _sp(b)
        if a.nnz or b.nnz:
            d = abs(a - b).max() if (a - b).nnz else 0.0
            if d > rel_tol * max(abs(a).max() if a.nnz else 0.0, abs(b).max() if b.nnz else 0.0, 1e-300):
                raise ModalError(f"'{dae.name}' is not linear (its Jacobian changes with the state): modal "
                                 "coordinates need a linear model; use coordinates='physical'")


class ModalDae:
    """A linear model in real modal coordinates ``ξ``: ``x = x0 + P ξ``, ``ξ' = Λ ξ + P⁻¹ (B u + x'0)`` with
    ``P``, ``Λ`` from :func:`modal_basis` (block diagonal: every damping of the model -- modal, discrete,
    non-proportional -- is inside the blocks). It presents the part of the :class:`bscomp.kernel.dae.Dae` interface
    the OCP uses (``F``, ``jacobians``, ``initialize``, ``output_function`` for the original observables and
    states, names, sizes); :func:`solve_condensed` transcribes it. Built by :meth:`from_dae`.
    """

    def __init__(self, name, lin, p, u_names, out_map, P, Pinv, Lam, Bm, fm, blocks, info=None):
        self.name = f"{name} (modal)"
        self.lin, self.p = lin, np.asarray(p, float)
        self.P, self.Pinv, self.Asp, self.Bm, self.fm = P, Pinv, Lam, Bm, fm
        n = P.shape[0]
        self.x_names = [f"xi{i}" for i in range(n)]
        self.z_names, self.u_names = [], list(u_names)
        self.x_start, self.z_start = np.zeros(n), np.zeros(0)
        self.structural_parameters = []
        self._out_map = out_map
        self.observables = out_map.names
        self._cache = {}
        self.info = info or {}
        self.self_basis = {"P": np.eye(n), "Pinv": np.eye(n), "Lam": Lam, "blocks": blocks}

    @classmethod
    def from_dae(cls, dae, p, x0, zero_tol=1e-7):
        lin = _affine(dae, p, x0)
        check_linear(dae, p, lin)
        basis = modal_basis(lin["A"], zero_tol)
        n = lin["A"].shape[0]
        return cls(dae.name, lin, p, dae.u_names, _OutputMap(dae, p, lin), basis["P"], basis["Pinv"], basis["Lam"],
                   basis["Pinv"] @ lin["B"], basis["Pinv"] @ lin["xd0"], basis["blocks"],
                   info={"cond_P": basis["cond"], "n_blocks": len(basis["blocks"]), "n_states": n})

    # sizes
    nx = property(lambda self: self.P.shape[0])
    nz = property(lambda self: 0)
    nu = property(lambda self: len(self.u_names))

    def parameter_vector(self, params=None):
        return self.p

    def _mx(self):
        return (ca.MX.sym("xd", self.nx), ca.MX.sym("x", self.nx), ca.MX.sym("z", self.nz),
                ca.MX.sym("u", self.nu), ca.MX.sym("p", len(self.p)))

    @property
    def F(self):
        if "F" not in self._cache:
            xd, x, z, u, p = self._mx()
            res = xd - ca.mtimes(ca.sparsify(ca.DM(self.Asp)), x) - ca.mtimes(ca.DM(self.Bm), u) - self.fm
            self._cache["F"] = ca.Function("F", [xd, x, z, u, p], [res], ["xd", "x", "z", "u", "p"], ["res"])
        return self._cache["F"]

    def jacobians(self, xd, x, z, u, p):
        n = self.nx
        xd, x, u = (np.asarray(a, float).ravel() for a in (xd, x, u))
        res = xd - self.Asp @ x - self.Bm @ u - self.fm
        return (ca.DM(res), ca.sparsify(ca.DM(np.eye(n))), ca.sparsify(ca.DM(-self.Asp)), ca.DM(n, 0),
                ca.DM(-self.Bm))

    def initialize(self, x0=None, u0=None, p=None, store=False, **_):
        x = self.x_start if x0 is None else np.asarray(x0, float).ravel()
        u = np.zeros(self.nu) if u0 is None else np.asarray(u0, float).ravel()
        return self.Asp @ x + self.Bm @ u + self.fm, np.zeros(0)

    def output_function(self, names):
        key = tuple(names)
        if key not in self._cache:
            y0, Cm, Du = self.rows(list(names))
            xd, x, z, u, p = self._mx()
            y = ca.mtimes(ca.DM(Cm), x) + ca.mtimes(ca.DM(Du), u) + ca.DM(y0)
            self._cache[key] = ca.Function("y", [xd, x, z, u, p], [y])
        return self._cache[key]

    def rows(self, names):
        """``(y0, C, D)`` with ``y = y0 + C ξ + D u`` for names (observables or original states)."""
        y0, Cx, Du = self._out_map(list(names))
        C = Cx @ self.P
        C[np.abs(C) < 1e-14 * max(float(np.max(np.abs(C))) if C.size else 0.0, 1e-300)] = 0.0
        return y0, C, Du

    def to_physical(self, xi):
        """Original states of modal states ``xi`` ((..., n) rows)."""
        return self.lin["x0"][None, :] + np.atleast_2d(xi) @ self.P.T

    def from_physical(self, x):
        return (np.atleast_2d(x) - self.lin["x0"][None, :]) @ self.Pinv.T


class _OutputMap:
    def __init__(self, dae, p, lin):
        self.dae, self.p, self.lin = dae, p, lin
        self.names = _NameSet(dae)

    def __call__(self, names):
        return output_rows(self.dae, self.p, self.lin, names)


class _NameSet:
    """Membership test for 'observable or state of the original model' (used as ``observables``)."""

    def __init__(self, dae):
        self.dae = dae

    def __contains__(self, name):
        return name in self.dae.observables or name in self.dae.x_names

    def __iter__(self):
        return iter(list(self.dae.observables) + list(self.dae.x_names))


def residual_rows(lin, C, D, hold_u, zero_tol=1e-7, basis=None):
    """Rows bounding the free response after arrival.

    With the input held at ``hold_u`` from ``T`` on, the state of a linear model moves from ``x_T`` to an
    equilibrium ``x_∞`` as a sum of modes, ``x(t) - x_∞ = Σ_k P_k e^{Λ_k (t-T)} e_k`` with
    ``e_k = Pinv_k (x_T - x0) + Λ_k⁻¹ Pinv_k b`` (``b = xd0 + B hold_u``) for every non-zero block ``k``.
    An output ``y = C x + D u`` then deviates from its final value by at most
    ``Σ_k G_k |e_k|`` with ``G_k = |C P_k|`` (a damped block only shrinks ``|e_k|``), and by Cauchy-Schwarz
    ``Σ_k G_k |e_k| <= sqrt(Σ_k G_k) sqrt(Σ_k G_k |e_k|²) = |L (x_T - x0) + l|``.

    Returns ``(L, l)`` (rows for blocks with ``G_k > 1e-12 max G``). Raises :class:`ModalError` if the held
    input has no equilibrium (it drives the zero-eigenvalue block, e.g. a torque held on a free rigid
    body) or a mode is unstable.
    """
    basis = basis or modal_basis(lin["A"], zero_tol)
    P, Pinv = basis["P"], basis["Pinv"]
    b = lin["xd0"] + lin["B"] @ np.asarray(hold_u, float)
    pb = Pinv @ b
    G, rows, offs = [], [], []
    for idx, kind, lam in basis["blocks"]:
        if kind == "zero":
            drift = float(np.linalg.norm(P[:, idx] @ pb[idx]))
            if drift > 1e-6 * max(float(np.linalg.norm(b)), 1e-300) and float(np.linalg.norm(b)) > 0:
                raise ModalError("the held input has no equilibrium: it accelerates the rigid-body (zero-eigenvalue) "
                                 "mode; hold an input that leaves the model at rest (e.g. zero torque)")
            continue
        if lam.real > 0:
            raise ModalError(f"unstable mode (eigenvalue {lam}): no residual-vibration bound")
        Lk = basis["Lam"][np.ix_(idx, idx)]
        G.append(float(np.linalg.norm(C @ P[:, idx])))
        rows.append(Pinv[idx])
        offs.append(np.linalg.solve(Lk, pb[idx]))
    if not G:
        return np.zeros((0, P.shape[0])), np.zeros(0)
    G = np.array(G)
    keep = G > 1e-12 * np.max(G)
    S = float(np.sum(G[keep]))
    L = np.vstack([np.sqrt(g * S) * r for g, r, k in zip(G, rows, keep) if k])
    l_ = np.concatenate([np.sqrt(g * S) * o for g, o, k in zip(G, offs, keep) if k])
    return L, l_


def solve_condensed(ocp, solver_options=None, sparse=False):
    """Transcribe and solve ``ocp`` (an :class:`bscomp.optimal.Ocp` whose model is a first-order
    :class:`ModalDae`) with the states eliminated.

    The Radau IIA collocation equations of a block-diagonal linear model are solved exactly, block by block:
    on interval k the stage values of block ``b`` are ``Ξ_k = Mx(h) ξ_k + Mb(h) β_k`` with
    ``(Cᵀ ⊗ I - h I ⊗ Λ_b) Ξ = h 1 ⊗ β - c0 ⊗ ξ_k`` (``β_k = P⁻¹(B u_k + x'0)``) and ``ξ_{k+1}`` the last stage;
    ``Mx``, ``Mb`` are 3m x m symbolic functions of the step h = T/N, built once per block. The unknowns are
    the free inputs and T only: the same collocation solution as the full transcription, but the NLP has
    ``N nu + 1`` variables, so the KKT systems are small and dense instead of large with long fill-in chains.
    ``sparse=True``: the states are kept instead (:func:`_sparse_collocation`, built in MX), the rest of the
    problem (final rows, residual limit, path bounds, objective) is the same.
    Returns an :class:`bscomp.optimal.OcpResult` in modal coordinates.
    """
    from bscomp.optimal.problem import OcpError, OcpResult, _radau, _radau_weights, active_fraction

    md, N, d = ocp.dae, ocp.N, ocp.d
    nx, nu = md.nx, md.nu
    tau, Cr = _radau(d)
    x0 = ocp._x0()
    lin = ocp._linearize(x0)
    T0, ref = ocp._start(lin)
    xs, _, _, us = ocp._scales(ref)
    fixed_u = {i: ocp.bounds[n][0] for i, n in enumerate(md.u_names)
               if n in ocp.bounds and ocp.bounds[n][0] == ocp.bounds[n][1]}
    free_u = [i for i in range(nu) if i not in fixed_u]
    # the sparse form in MX: matrix-level derivatives (the dense output rows over all modes would need ~nx
    # forward directions through an SX graph of O(N nx) nodes: 47 of 65 s at N = 100 on the 98-DOF model)
    Sym = ca.MX if sparse else ca.SX
    Uv = Sym.sym("u", len(free_u), N)
    rows_u = [Uv[free_u.index(i), :] * us[i] if i in free_u else ca.DM(np.full((1, N), fixed_u[i])) for i in range(nu)]
    U = ca.vertcat(*rows_u) if nu else Sym(0, N)
    free_T = ocp.T_fixed is None
    Tsc = Sym.sym("T") if free_T else None
    T = T0 * Tsc if free_T else ocp.T_fixed
    h = T / N
    beta = ca.mtimes(ca.DM(md.Bm), U) + ca.repmat(ca.DM(md.fm), 1, N)          # nx x N
    g, lbg, ubg = [], [], []

    def add(expr, lo, hi):
        g.append(ca.vec(expr))
        n_ = expr.numel()
        lbg.append(np.broadcast_to(lo, (n_,)).astype(float))
        ubg.append(np.broadcast_to(hi, (n_,)).astype(float))

    Xvars, X0 = [], []
    if sparse:
        Xc, Xcs, xsc = _sparse_collocation(md, ref, us, h, ref["T"] / N, beta, add)
        Xvars.append(ca.vec(Xcs))
        X0.append((ref["Xc"] / xsc[:, None]).ravel(order="F"))
        Xi = ca.horzcat(Sym.zeros(nx, 1), Xc[:, (d - 1)::d])
    else:
        Xi, Xc = _condensed_states(md, N, d, Cr, h, beta)
    Ucol = ca.horzcat(*[ca.repmat(U[:, k], 1, d) for k in range(N)]) if N else U

    # final conditions (rows over ξ), each scaled by its target or its magnitude along the reference
    term = ocp._terminal_rows(lin)
    if term is not None:
        Ctm, tt = term
        refmag = np.max(np.abs(np.vstack([ref["X"], ref["Xc"].T]) @ Ctm.T), axis=0)
        sc = np.maximum(np.abs(tt), refmag)
        sc = np.where(sc > 0, sc, 1.0)
        add(ca.mtimes(ca.DM(Ctm / sc[:, None]), Xi[:, N]) - ca.DM(tt / sc), 0.0, 0.0)
    # residual vibration: auxiliary variables E = (L ξ_N + l)/limit (|E|² <= 1 then has a unit Hessian; the
    # same quadratic composed with the T-dependent propagation made Ipopt diverge)
    res_expr, Evars, E0 = {}, [], []
    for n, (L, l_) in ocp._residual_rows(lin).items():
        lim = ocp.residual_limits[n]
        e = ca.mtimes(ca.DM(L / lim), Xi[:, N]) + ca.DM((l_ - L @ x0) / lim)
        E = Sym.sym(f"E{len(Evars)}", e.numel())
        Evars.append(E)
        E0.append((L @ ref["X"][-1] + l_ - L @ x0) / lim)
        res_expr[n] = ca.sqrt(ca.sumsqr(e)) * lim
        add(E - e, 0.0, 0.0)
        add(ca.sumsqr(E), -np.inf, 1.0)
    # path bounds: outputs and (original) states at the collocation points, states also at t = 0
    y_names = [n for n in ocp.bounds if ocp._kind(n) == "y"]
    obj_y = [ocp.objective_args["output"]] if ocp.objective_kind in ("tracking", "vibration") else []
    all_y = list(dict.fromkeys(y_names + obj_y))
    Yc, ys = None, {}
    if all_y:
        y0, Cy, Dy = md.rows(all_y)
        Yc = ca.mtimes(ca.DM(Cy), Xc) + ca.mtimes(ca.DM(Dy), Ucol) + ca.repmat(ca.DM(y0), 1, N * d)
        Yref = Cy @ ref["Xc"] + Dy @ np.repeat(ref["U"].T, d, axis=1) + y0[:, None]
        for i, n in enumerate(all_y):
            s = ocp._nominal(n, default=np.nan)
            ys[n] = s if np.isfinite(s) else (float(np.max(np.abs(Yref[i]))) or 1.0)
    lbx = [np.array([1e-6]) if free_T else np.zeros(0)]
    ubx = [np.array([np.inf]) if free_T else np.zeros(0)]
    ulo, uhi = np.full((len(free_u), N), -np.inf), np.full((len(free_u), N), np.inf)
    for n, (lo, hi) in ocp.bounds.items():
        kind = ocp._kind(n)
        if kind == "u":
            i = md.u_names.index(n)
            if i in free_u:
                ulo[free_u.index(i)], uhi[free_u.index(i)] = lo / us[i], hi / us[i]
            continue
        s = ys[n]
        expr = Yc[all_y.index(n), :] / s
        add(expr, lo / s, hi / s)
    lbx.append(ulo.ravel(order="F"))
    ubx.append(uhi.ravel(order="F"))
    wq = np.tile(_radau_weights(tau, d), N)
    kind = ocp.objective_kind
    if kind == "time":
        J = T / T0
    elif kind == "effort":
        w = np.array([ocp.objective_args["weights"].get(n, 1.0) for n in md.u_names])
        J = h * ca.sum2(ca.sum1(ca.diag(w / us**2) @ (U**2)))
    else:
        tc = np.concatenate([(k + tau[1:]) * (ocp.T_fixed / N) for k in range(N)])
        out = ocp.objective_args["output"]
        s = ys[out]
        if kind == "tracking":
            r_t = np.array([ocp.objective_args["reference"](t) for t in tc])
            e = (Yc[all_y.index(out), :] - ca.DM(r_t[None, :])) / s
            J = h * ca.sum2(e**2 * ca.DM(wq[None, :])) + ocp.objective_args["effort_weight"] * h * ca.sumsqr(Uv)
        else:
            mask = (tc >= ocp.T_fixed - ocp.objective_args["T_settle"]).astype(float)
            e = Yc[all_y.index(out), :] / s
            J = h * ca.sum2(e**2 * ca.DM((wq * mask)[None, :]))
    w = ca.vertcat(Tsc, ca.vec(Uv), *Evars, *Xvars) if free_T else ca.vertcat(ca.vec(Uv), *Evars, *Xvars)
    nE = sum(E.numel() for E in Evars)
    nX = sum(v.numel() for v in Xvars)
    lbx.append(np.full(nE + nX, -np.inf))
    ubx.append(np.full(nE + nX, np.inf))
    G = ca.vertcat(*g) if g else Sym(0, 1)
    nlp = {"x": w, "f": J, "g": G}
    ipopt = dict(ocp.ipopt_options, **(solver_options or {}))
    solver = ca.nlpsol("ocp_sparse" if sparse else "ocp_condensed", "ipopt", nlp,
                       {"ipopt": ipopt, "print_time": False})
    w0 = np.concatenate([[ref["T"] / T0] if free_T else [], (ref["U"][:, free_u] / us[free_u]).T.ravel(order="F")]
                        + E0 + X0)
    sol = solver(x0=w0, lbx=np.concatenate(lbx), ubx=np.concatenate(ubx),
                 lbg=np.concatenate(lbg) if lbg else np.zeros(0), ubg=np.concatenate(ubg) if ubg else np.zeros(0))
    stats = solver.stats()
    wv = np.asarray(sol["x"]).ravel()
    ev = ca.Function("ev", [w], [T if free_T else ca.DM(T), U, Xi, Xc]
                     + ([Yc] if Yc is not None else []) + list(res_expr.values()))
    vals = ev(wv)
    if not stats.get("success"):
        vib = ""
        if res_expr:
            parts = [f"'{n}' {float(vals[4 + (Yc is not None) + i]):.3g} (limit {ocp.residual_limits[n]:.3g})"
                     for i, n in enumerate(res_expr)]
            vib = (" Residual-vibration bound at the last iterate: " + ", ".join(parts) + "; a limit below what the "
                   "input grid can reach is infeasible: raise N or the limit, or add time (fixed-T problems).")
        gv = np.asarray(sol["g"]).ravel()
        lo, hi = (np.concatenate(lbg), np.concatenate(ubg)) if lbg else (np.zeros(0), np.zeros(0))
        viol = float(np.max(np.r_[0.0, lo - gv, gv - hi])) if gv.size else 0.0
        raise OcpError(
            f"Ipopt did not converge on '{md.name}' (status: {stats.get('return_status')}, iterations "
            f"{stats.get('iter_count')}, largest scaled constraint violation {viol:.3g}).{vib} Hints: check that "
            "the final state is reachable within the bounds, give a better T_guess or warm start, loosen bounds, "
            "or give scale= for signals of very different magnitudes")
    Tv = float(vals[0])
    Uv_ = np.asarray(vals[1]).reshape(nu, N).T
    Xv = np.asarray(vals[2]).reshape(nx, N + 1).T
    uk = np.vstack([Uv_[:1], Uv_])
    XDv = Xv @ md.Asp.T + uk @ md.Bm.T + md.fm[None, :]
    outputs = {}
    if Yc is not None:
        Ycv = np.asarray(vals[4]).reshape(len(all_y), N * d)
        for i, n in enumerate(all_y):
            outputs[n] = np.r_[ocp._y0(n, Xv[0], Uv_[0]), Ycv[i, (d - 1)::d]]
    active = {}
    for n, (lo, hi) in ocp.bounds.items():
        v = Uv_[:, md.u_names.index(n)] if n in md.u_names else outputs[n]
        active[n] = active_fraction(v, lo, hi)
    off = 4 + (Yc is not None)
    residual = {n: float(vals[off + i]) for i, n in enumerate(res_expr)}
    return OcpResult(T=Tv, t=np.linspace(0, Tv, N + 1), x=Xv, u=Uv_, outputs=outputs, x_names=list(md.x_names),
                     u_names=list(md.u_names), active=active,
                     stats={"return_status": stats.get("return_status"), "iter_count": stats.get("iter_count"),
                            "t_wall_total": stats.get("t_wall_total"), "n_unknowns": int(w.numel()) - nE,
                            "transcription": "sparse" if sparse else "condensed"},
                     dae=md, p=md.p, xd=XDv, z=np.zeros((N + 1, 0)), residual=residual)


def _condensed_states(md, N, d, Cr, h, beta):
    """Exact Radau IIA solution of the block-diagonal model, block by block: (ξ at the grid points,
    ξ at the collocation points) as expressions of the inputs (in ``beta``) and the step ``h``."""
    nx = md.nx
    Xi = ca.SX.zeros(nx, N + 1)
    Xc = ca.SX.zeros(nx, N * d)
    Ct = Cr[1:, 1:].T
    c0 = Cr[0, 1:][:, None]
    for idx, _, _ in md.self_basis["blocks"]:
        m = len(idx)
        Lb = ca.DM(md.Asp[np.ix_(idx, idx)])
        Lh = ca.DM(np.kron(Ct, np.eye(m))) - h * ca.kron(ca.DM.eye(d), Lb)
        Mx = ca.solve(Lh, ca.DM(-np.kron(c0, np.eye(m))))
        Mb = ca.solve(Lh, h * ca.DM(np.kron(np.ones((d, 1)), np.eye(m))))
        xk = ca.DM(np.zeros(m))
        Xi[idx, 0] = xk
        for k in range(N):
            st = ca.mtimes(Mx, xk) + ca.mtimes(Mb, beta[idx, k])
            for j in range(d):
                Xc[idx, k * d + j] = st[j * m:(j + 1) * m]
            xk = st[(d - 1) * m:]
            Xi[idx, k + 1] = xk
    return Xi, Xc


def _sparse_collocation(md, ref, us, h, h0, beta, add):
    """States kept: scaled modal collocation variables ``Ξ_s`` (ξ = s_b Ξ_s, one scale per block: the largest
    |ξ| of the block along the reference motion, floored at 1e-9 of the largest block) and the Radau IIA
    equations ``Σ_r C_rj ξ_kr = h (Λ ξ_kj + β_k)`` as constraints, each row divided by its largest term at
    the reference step ``h0``. Every row has the 1 x 1 / 2 x 2 / rigid block of its mode, the inputs and T:
    O(N nx) non-zeros instead of the O(N² nx) expressions of the condensed form.
    Returns (ξ at the collocation points, the scaled variables, the scales)."""
    from bscomp.optimal.problem import _radau

    nx, N = md.nx, beta.shape[1]
    d = ref["Xc"].shape[1] // max(N, 1)
    _, Cr = _radau(d)
    mag = np.maximum(np.max(np.abs(ref["Xc"]), axis=1), np.max(np.abs(ref["X"]), axis=0))
    xsc = np.ones(nx)
    for idx, _, _ in md.self_basis["blocks"]:
        xsc[idx] = np.max(mag[idx])
    big = float(np.max(xsc)) if nx else 1.0
    xsc = np.maximum(xsc, 1e-9 * big) if big > 0 else np.ones(nx)
    Xcs = ca.MX.sym("xi", nx, N * d)
    Xc = ca.mtimes(ca.diag(ca.DM(xsc)), Xcs)
    Ls = md.Asp * xsc[None, :] / xsc[:, None]
    Ls[np.abs(Ls) < 1e-300] = 0.0
    Uref = ref["U"].T
    bref = md.Bm @ Uref + md.fm[:, None] if N else np.zeros((nx, 0))
    rs = np.maximum.reduce([np.ones(nx), h0 * np.max(np.abs(Ls), axis=1),
                            h0 * np.max(np.abs(bref), axis=1) / xsc if N else np.zeros(nx),
                            h0 * np.max(np.abs(md.Bm) * us[None, :], axis=1) / xsc])
    Lsp = ca.sparsify(ca.DM(Ls))
    Rinv = ca.diag(ca.DM(1.0 / rs))
    Xprev = ca.horzcat(ca.MX.zeros(nx, 1), Xcs[:, (d - 1)::d][:, :N - 1]) if N else ca.MX(nx, 0)
    bs = ca.mtimes(ca.diag(ca.DM(1.0 / xsc)), beta)
    for j in range(1, d + 1):
        lhs = Cr[0, j] * Xprev
        for r in range(1, d + 1):
            lhs = lhs + Cr[r, j] * Xcs[:, (r - 1)::d]
        rhs = h * (ca.mtimes(Lsp, Xcs[:, (j - 1)::d]) + bs)
        add(ca.mtimes(Rinv, lhs - rhs), 0.0, 0.0)
    return Xc, Xcs, xsc
