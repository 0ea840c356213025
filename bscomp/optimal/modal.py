"""Modal transcription of an :class:`~bscomp.optimal.Ocp` on a linear model (``coordinates="modal"``).

The problem is restated on :class:`~bscomp.optimal.coordinates.ModalDae`, the model in its real modal
coordinates ``ξ`` (``x = x0 + P ξ``, ``ξ' = Λ ξ + P⁻¹ (x'0 + B u)``, ``Λ`` block diagonal with every
damping inside the blocks): final values and rest become rows of ``P``, bounds and outputs keep the
model's names, and the solution is mapped back to the model's states (:func:`solve_modal`). The same
Radau IIA equations as :mod:`bscomp.optimal.collocation` are then either

* solved exactly, block by block, so that only the inputs and T are unknowns (*condensed*,
  :func:`condensed_states`; O(N² nx) expressions, small dense KKT systems), or
* kept as sparse constraints on scaled modal collocation states (*sparse*, :func:`sparse_collocation`;
  O(N nx) non-zeros, for large models),

``coordinates="modal"`` choosing condensed up to :data:`SPARSE_MODAL_NX` states.
"""

from __future__ import annotations

from functools import partial

import casadi as ca
import numpy as np

from bscomp.kernel.signal_meta import unit_of
from bscomp.optimal.collocation import objective, output_at, radau
from bscomp.optimal.guess import initial_guess
from bscomp.optimal.infeasibility import Ledger, describe
from bscomp.optimal.result import OcpError, OcpResult, active_fraction, convergence_error

__all__ = ["SPARSE_MODAL_NX", "solve_modal", "solve_condensed", "condensed_states", "sparse_collocation"]

# coordinates="modal" keeps the modal states as collocation variables (sparse) above this many states and
# eliminates them (condensed: inputs and T the only unknowns, O(N² nx) expressions) up to it
SPARSE_MODAL_NX = 40


def solve_modal(ocp, solver_options: dict | None = None) -> OcpResult:
    """Solve ``ocp`` in the real modal coordinates of its (linear) model and map the result back.

    The problem is restated on :meth:`Ocp.modal_dae` (final values and rest become rows of ``P``; a warm
    start is mapped to modal states), transcribed by :func:`solve_condensed` (condensed or sparse, see
    :data:`SPARSE_MODAL_NX` and ``Ocp(coordinates=...)``), and its states, derivatives and algebraic
    variables are mapped back to the model's. Rate limits are refused (physical coordinates only).
    """
    if ocp.rate_limits:
        raise OcpError(f"bound_rate ({sorted(ocp.rate_limits)}) is transcribed in physical coordinates only: "
                       "use Ocp(..., coordinates='physical') or drop the rate limit")
    dae, x0 = ocp.dae, ocp.start_state()
    md = ocp.modal_dae()
    rows, tgt, names = [], [], []
    for i, v in ocp.final_targets():
        rows.append(md.P[i])
        tgt.append(v - x0[i])
        names.append(dae.x_names[i])
    terminal = (np.array(rows).reshape(len(rows), md.nx), np.array(tgt, float))
    warm = None
    if ocp.warm is not None:
        w = ocp.warm
        xi = md.from_physical(w.x) if w.x.shape[1] == dae.nx else w.x
        warm = OcpResult(T=w.T, t=w.t, x=xi, u=w.u, outputs={}, x_names=md.x_names, u_names=w.u_names, active={})
    sparse = ocp.coordinates == "modal-sparse" or (ocp.coordinates == "modal" and md.nx > SPARSE_MODAL_NX)
    r = solve_condensed(ocp.restated(md, terminal, warm, names), solver_options, sparse=sparse)
    X = md.to_physical(r.x)
    XD = r.xd @ md.P.T
    uk = np.vstack([r.u[:1], r.u])
    Z = (md.lin["z0"][None, :] + (X - x0[None, :]) @ md.lin["Zx"].T + uk @ md.lin["Zu"].T) if dae.nz \
        else np.zeros((len(r.t), 0))
    stats = dict(r.stats, coordinates="modal", modal_info=dict(md.info))
    return OcpResult(T=r.T, t=r.t, x=X, u=r.u, outputs=r.outputs, x_names=list(dae.x_names),
                     u_names=list(dae.u_names), active=r.active, stats=stats, dae=dae, p=ocp.p, xd=XD, z=Z,
                     residual=r.residual)


def solve_condensed(ocp, solver_options=None, sparse=False) -> OcpResult:
    """Transcribe and solve ``ocp`` (an :class:`~bscomp.optimal.Ocp` whose model is a first-order
    :class:`~bscomp.optimal.coordinates.ModalDae`) with the states eliminated.

    The Radau IIA collocation equations of a block-diagonal linear model are solved exactly, block by block:
    on interval k the stage values of block ``b`` are ``Ξ_k = Mx(h) ξ_k + Mb(h) β_k`` with
    ``(Cᵀ ⊗ I - h I ⊗ Λ_b) Ξ = h 1 ⊗ β - c0 ⊗ ξ_k`` (``β_k = P⁻¹(B u_k + x'0)``) and ``ξ_{k+1}`` the last stage;
    ``Mx``, ``Mb`` are 3m x m symbolic functions of the step h = T/N, built once per block. The unknowns are
    the free inputs and T only: the same collocation solution as the full transcription, but the NLP has
    ``N nu + 1`` variables, so the KKT systems are small and dense instead of large with long fill-in chains.
    ``sparse=True``: the states are kept instead (:func:`sparse_collocation`, built in MX), the rest of the
    problem (final rows, residual limit, path bounds, objective) is the same.
    Returns an :class:`~bscomp.optimal.OcpResult` in modal coordinates.
    """
    return _ModalNlp(ocp, sparse).solve(solver_options)


class _ModalNlp:
    """The NLP of :func:`solve_condensed` (``casadi.nlpsol``), built step by step: unknowns (T, free inputs),
    modal states (eliminated or kept), final rows, residual-vibration limits, output bounds, objective."""

    def __init__(self, ocp, sparse):
        md, N = ocp.dae, ocp.N
        self.ocp, self.md, self.N, self.d, self.sparse = ocp, md, N, ocp.d, sparse
        self.guess = g = initial_guess(ocp)
        self.x0, self.lin, self.T0, self.ref, self.xs, self.us = g.x0, g.lin, g.T0, g.ref, g.xs, g.us
        self.fixed_u = fixed_u = ocp.fixed_inputs()
        self.free_u = free_u = [i for i in range(md.nu) if i not in fixed_u]
        # the sparse form in MX: matrix-level derivatives (the dense output rows over all modes would need ~nx
        # forward directions through an SX graph of O(N nx) nodes: 47 of 65 s at N = 100 on the 98-DOF model)
        self.Sym = Sym = ca.MX if sparse else ca.SX
        us = self.us
        self.Uv = Uv = Sym.sym("u", len(free_u), N)
        rows_u = [Uv[free_u.index(i), :] * us[i] if i in free_u else ca.DM(np.full((1, N), fixed_u[i]))
                  for i in range(md.nu)]
        self.U = ca.vertcat(*rows_u) if md.nu else Sym(0, N)
        self.Us = ca.vertcat(*[Uv[free_u.index(i), :] if i in free_u else ca.DM(np.full((1, N), fixed_u[i] / us[i]))
                               for i in range(md.nu)]) if md.nu else Sym(0, N)
        self.free_T = ocp.T_fixed is None
        self.Tsc = Sym.sym("T") if self.free_T else None
        self.T = self.T0 * self.Tsc if self.free_T else ocp.T_fixed
        self.h = self.T / N
        self.beta = ca.mtimes(ca.DM(md.Bm), self.U) + ca.repmat(ca.DM(md.fm), 1, N)          # nx x N
        self.g, self.lbg, self.ubg = [], [], []
        self.Xvars, self.X0, self.Evars, self.E0 = [], [], [], []
        self.ledger = Ledger()

    def add(self, expr, lo, hi, label="constraint", names="", tfrac=1.0, scale=1.0, bound=None):
        """Constraint ``lo <= expr <= hi`` (element-wise, bounds broadcast), recorded in the ledger with what it
        is (``label``, ``names`` and times ``tfrac`` per row, ``scale`` back to physical units; ``bound``: the
        physical ``(lo, hi)`` of a bound)."""
        self.g.append(ca.vec(expr))
        n_ = expr.numel()
        self.lbg.append(np.broadcast_to(lo, (n_,)).astype(float))
        self.ubg.append(np.broadcast_to(hi, (n_,)).astype(float))
        blo, bhi = bound if bound is not None else (None, None)
        self.ledger.add(n_, label, names, tfrac, scale, blo, bhi)

    def _states(self):
        """ξ at the grid points (``Xi``) and at the collocation points (``Xc``): eliminated or kept."""
        md, N, d, ref = self.md, self.N, self.d, self.ref
        if self.sparse:
            Xc, Xcs, xsc = sparse_collocation(md, ref, self.us, self.h, ref["T"] / N, self.beta, self.add)
            self.Xvars.append(ca.vec(Xcs))
            self.X0.append((ref["Xc"] / xsc[:, None]).ravel(order="F"))
            self.Xi = ca.horzcat(self.Sym.zeros(md.nx, 1), Xc[:, (d - 1)::d])
            self.Xc = Xc
        else:
            self.Xi, self.Xc = condensed_states(md, N, d, radau(d).C, self.h, self.beta)
        self.Ucol = ca.horzcat(*[ca.repmat(self.U[:, k], 1, d) for k in range(N)]) if N else self.U

    def _final(self):
        """Final rows over ξ, each scaled by its target or its magnitude along the reference; residual
        vibration through auxiliary variables ``E = (L ξ_N + l)/limit`` (``|E|² <= 1`` then has a unit
        Hessian; the same quadratic composed with the T-dependent propagation made Ipopt diverge)."""
        ocp, ref, Xi, N, x0 = self.ocp, self.ref, self.Xi, self.N, self.x0
        term = ocp.terminal_rows(self.lin)
        if term is not None:
            Ctm, tt = term
            refmag = np.max(np.abs(np.vstack([ref["X"], ref["Xc"].T]) @ Ctm.T), axis=0)
            sc = np.maximum(np.abs(tt), refmag)
            sc = np.where(sc > 0, sc, 1.0)
            self.add(ca.mtimes(ca.DM(Ctm / sc[:, None]), Xi[:, N]) - ca.DM(tt / sc), 0.0, 0.0, "final value",
                     ocp.terminal_names(len(tt)), 1.0, sc)
        self.res_expr = {}
        for n, (L, l_) in ocp.residual_rows(self.lin).items():
            lim = ocp.residual_limits[n]
            e = ca.mtimes(ca.DM(L / lim), Xi[:, N]) + ca.DM((l_ - L @ x0) / lim)
            E = self.Sym.sym(f"E{len(self.Evars)}", e.numel())
            self.Evars.append(E)
            self.E0.append((L @ ref["X"][-1] + l_ - L @ x0) / lim)
            self.res_expr[n] = ca.sqrt(ca.sumsqr(e)) * lim
            self.add(E - e, 0.0, 0.0, "residual-vibration bound (in units of the limit)", n)
            self.add(ca.sumsqr(E), -np.inf, 1.0, "residual-vibration limit (in units of the limit, squared)", n)

    def _bounds(self):
        """Outputs (and original states) at the collocation points with their nominals; output bounds as
        constraints, input bounds as variable bounds (returned: lbx, ubx of T and the inputs)."""
        ocp, md, N, d, ref = self.ocp, self.md, self.N, self.d, self.ref
        y_names = [n for n in ocp.bounds if ocp.kind(n) == "y"]
        self.obj_y = [ocp.objective_args["output"]] if ocp.objective_kind in ("tracking", "vibration") else []
        self.all_y = all_y = list(dict.fromkeys(y_names + self.obj_y))
        self.Yc, self.ys = None, {}
        if all_y:
            y0, Cy, Dy = md.rows(all_y)
            self.Yc = ca.mtimes(ca.DM(Cy), self.Xc) + ca.mtimes(ca.DM(Dy), self.Ucol) + ca.repmat(ca.DM(y0), 1, N * d)
            Yref = Cy @ ref["Xc"] + Dy @ np.repeat(ref["U"].T, d, axis=1) + y0[:, None]
            for i, n in enumerate(all_y):
                s = ocp.nominal(n, default=np.nan)
                self.ys[n] = s if np.isfinite(s) else (float(np.max(np.abs(Yref[i]))) or 1.0)
        lbx = [np.array([1e-6]) if self.free_T else np.zeros(0)]
        ubx = [np.array([np.inf]) if self.free_T else np.zeros(0)]
        free_u = self.free_u
        ulo, uhi = np.full((len(free_u), N), -np.inf), np.full((len(free_u), N), np.inf)
        for n, (lo, hi) in ocp.bounds.items():
            if ocp.kind(n) == "u":
                i = md.u_names.index(n)
                if i in free_u:
                    ulo[free_u.index(i)], uhi[free_u.index(i)] = lo / self.us[i], hi / self.us[i]
                continue
            s = self.ys[n]
            self.add(self.Yc[all_y.index(n), :] / s, lo / s, hi / s, "bound", n, radau(d).stage_times(N), s, (lo, hi))
        lbx.append(ulo.ravel(order="F"))
        ubx.append(uhi.ravel(order="F"))
        if self.free_T:
            self.ledger.add(1, "horizon", "T", 1.0, self.T0, lo=1e-6 * self.T0, space="x", start=0)
        nf = len(free_u)
        if nf:
            sc = np.tile([self.us[i] for i in free_u], N)
            self.ledger.add(nf * N, "bound", [md.u_names[i] for i in free_u] * N, np.repeat(np.arange(N) / N, nf),
                            sc, lo=ulo.ravel(order="F") * sc, hi=uhi.ravel(order="F") * sc, space="x",
                            start=int(self.free_T))
        return lbx, ubx

    def solve(self, solver_options) -> OcpResult:
        ocp, ref = self.ocp, self.ref
        self._states()
        self._final()
        lbx, ubx = self._bounds()
        y = self.Yc[self.all_y.index(self.obj_y[0]), :] if self.obj_y else None
        J = objective(ocp, radau(self.d), self.T, self.T0, self.h, self.Us, y,
                      self.ys[self.obj_y[0]] if self.obj_y else 1.0)
        w = ca.vertcat(*([self.Tsc] if self.free_T else []), ca.vec(self.Uv), *self.Evars, *self.Xvars)
        nE = sum(E.numel() for E in self.Evars)
        nX = sum(v.numel() for v in self.Xvars)
        lbx.append(np.full(nE + nX, -np.inf))
        ubx.append(np.full(nE + nX, np.inf))
        G = ca.vertcat(*self.g) if self.g else self.Sym(0, 1)
        ipopt = dict(ocp.ipopt_options, **(solver_options or {}))
        try:
            solver = ca.nlpsol("ocp_sparse" if self.sparse else "ocp_condensed", "ipopt", {"x": w, "f": J, "g": G},
                               {"ipopt": ipopt, "print_time": False})
        except RuntimeError as exc:     # Ipopt refused an option (Ocp.solve checks them first)
            raise OcpError(f"Ipopt did not run on '{ocp.dae.name}': {str(exc).strip().splitlines()[-1]}") from exc
        w0 = np.concatenate([[ref["T"] / self.T0] if self.free_T else [],
                             (ref["U"][:, self.free_u] / self.us[self.free_u]).T.ravel(order="F")] + self.E0 + self.X0)
        lbg = np.concatenate(self.lbg) if self.lbg else np.zeros(0)
        ubg = np.concatenate(self.ubg) if self.ubg else np.zeros(0)
        sol = solver(x0=w0, lbx=np.concatenate(lbx), ubx=np.concatenate(ubx), lbg=lbg, ubg=ubg)
        stats = solver.stats()
        ev = ca.Function("ev", [w], [self.T if self.free_T else ca.DM(self.T), self.U, self.Xi, self.Xc]
                         + ([self.Yc] if self.Yc is not None else []) + list(self.res_expr.values()))
        vals = ev(np.asarray(sol["x"]).ravel())
        off = 4 + (self.Yc is not None)
        residual = {n: float(vals[off + i]) for i, n in enumerate(self.res_expr)}
        if not stats.get("success"):
            gv = np.asarray(sol["g"]).ravel()
            viol = float(np.max(np.r_[0.0, lbg - gv, gv - ubg])) if gv.size else 0.0
            where, info = describe(self.ledger, float(vals[0]), gv, lbg, ubg, np.asarray(sol["x"]).ravel(),
                                   np.concatenate(lbx), np.concatenate(ubx), units=partial(unit_of, self.md))
            raise convergence_error(self.md.name, stats, viol, residual, ocp.residual_limits, where, info,
                                    units=partial(unit_of, self.md))
        return self._result(vals, stats, residual, int(w.numel()) - nE)

    def _result(self, vals, stats, residual, n_unknowns) -> OcpResult:
        """The solution in modal coordinates at the grid points, bounded outputs and active fractions."""
        ocp, md, N, d = self.ocp, self.md, self.N, self.d
        Tv = float(vals[0])
        Uv = np.asarray(vals[1]).reshape(md.nu, N).T
        Xv = np.asarray(vals[2]).reshape(md.nx, N + 1).T
        uk = np.vstack([Uv[:1], Uv])
        XDv = Xv @ md.Asp.T + uk @ md.Bm.T + md.fm[None, :]
        outputs = {}
        if self.Yc is not None:
            Ycv = np.asarray(vals[4]).reshape(len(self.all_y), N * d)
            for i, n in enumerate(self.all_y):
                outputs[n] = np.r_[output_at(md, md.p, n, Xv[0], Uv[0]), Ycv[i, (d - 1)::d]]
        active = {}
        for n, (lo, hi) in ocp.bounds.items():
            v = Uv[:, md.u_names.index(n)] if n in md.u_names else outputs[n]
            active[n] = active_fraction(v, lo, hi)
        return OcpResult(T=Tv, t=np.linspace(0, Tv, N + 1), x=Xv, u=Uv, outputs=outputs, x_names=list(md.x_names),
                         u_names=list(md.u_names), active=active,
                         stats={"return_status": stats.get("return_status"), "iter_count": stats.get("iter_count"),
                                "t_wall_total": stats.get("t_wall_total"), "n_unknowns": n_unknowns,
                                "transcription": "sparse" if self.sparse else "condensed"},
                         dae=md, p=md.p, xd=XDv, z=np.zeros((N + 1, 0)), residual=residual)


def condensed_states(md, N, d, C, h, beta):
    """Exact Radau IIA solution of the block-diagonal model, block by block: (ξ at the grid points, ξ at the
    collocation points) as expressions of the inputs (in ``beta``) and the step ``h``.

    ``C`` is the (d+1) x d derivative matrix of :func:`bscomp.optimal.collocation.radau`.
    """
    nx = md.nx
    Xi = ca.SX.zeros(nx, N + 1)
    Xc = ca.SX.zeros(nx, N * d)
    Ct = C[1:, :].T
    c0 = C[0, :][:, None]
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


def sparse_collocation(md, ref, us, h, h0, beta, add):
    """States kept: scaled modal collocation variables ``Ξ_s`` (ξ = s_b Ξ_s, one scale per block: the largest
    |ξ| of the block along the reference motion, floored at 1e-9 of the largest block) and the Radau IIA
    equations ``Σ_r C_rj ξ_kr = h (Λ ξ_kj + β_k)`` as constraints, each row divided by its largest term at
    the reference step ``h0``. Every row has the 1 x 1 / 2 x 2 / rigid block of its mode, the inputs and T:
    O(N nx) non-zeros instead of the O(N² nx) expressions of the condensed form.
    Returns (ξ at the collocation points, the scaled variables, the scales)."""
    nx, N = md.nx, beta.shape[1]
    d = ref["Xc"].shape[1] // max(N, 1)
    C = radau(d).C
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
        lhs = C[0, j - 1] * Xprev
        for r in range(1, d + 1):
            lhs = lhs + C[r, j - 1] * Xcs[:, (r - 1)::d]
        rhs = h * (ca.mtimes(Lsp, Xcs[:, (j - 1)::d]) + bs)
        add(ca.mtimes(Rinv, lhs - rhs), 0.0, 0.0, "modal collocation equation", list(md.x_names) * N,
            np.repeat((np.arange(N) + radau(d).tau[j]) / max(N, 1), nx), np.tile(rs * xsc, N))
    return Xc, Xcs, xsc
