"""Partitioned exponential integration of the implicit DAE: exact zero-order hold for the linear part, an
implicit step for the few nonlinear force laws (friction, backlash). Used by
:func:`bscomp.simulate.simulate` with ``method="split"``.

Splitting
---------
The variables ``v = (x', x, z, u)`` that enter ``F`` nonlinearly (``casadi.which_depends`` of order 2)
are the *nonlinear variables* ``w_N``; the rows containing them nonlinearly are the *nonlinear rows*
``r``. Every other partial derivative of ``F`` is constant, so with a reference Jacobian ``J_ref``

.. math:: F(v) = F(v_0) + J_{ref}\\,(v - v_0) + P\\,g(w_N, u_N),

exactly, where ``P`` places ``g`` (one value per nonlinear row) into its rows and
``g = F_r(v) - F_r(v_0) - J_{ref,r}(v - v_0)`` depends on ``w_N`` (and nonlinear inputs ``u_N``) only.
``J_ref`` is the Jacobian at the start point except on the block (nonlinear rows, nonlinear variables),
where it holds the slopes of a *regime*: the tangent of the laws at a state of that regime (friction:
sticking ``F_c / v_reg``, sliding ``B``, the smooth transition in a ladder of slopes; backlash: gap ``0``,
contact ``c``), entries close to an outer-branch slope (the Jacobian at two far points ``w_N0 ± 1e6 σ``)
snapped to it. Within a regime ``g`` is then (nearly) constant -- ``±F_c`` while sliding, ``∓c b/2`` in
contact, ``0`` in the gap -- which the zero-order hold below represents exactly. A state belongs to a cached
regime when every entry of its tangent is within ``REGIME_RTOL`` (relative) of the regime's slope, or
within a floor: the smaller of ``REGIME_ATOL`` x the steepest slope seen and ``REGIME_COUPLING / |H|``
(``H`` = response of ``w_N`` to ``g`` over one step of the softest branches: a slope error ``dJ`` costs
about ``dJ H / 2`` per step). Every regime has its own linear part, discretisation and step Functions
(cached; a handful on the test bed).

Solving the index-1 linear part for ``(x', z)`` (as :func:`bscomp.linear.explicit_form`) gives

.. math:: \\dot x = c + A\\,\\delta x + B\\,\\delta u + E\\,g, \\qquad
          w_N = w_{N0} + C_N\\,\\delta x + D_N\\,\\delta u + D_g\\,g .

Step
----
``u`` and ``g`` are held over a step of length ``h`` (``g`` at its end value: implicit), and the linear
part is integrated exactly (augmented matrix exponential, as ``method="lti"``):

.. math:: \\delta x_{k+1} = A_d\\,\\delta x_k + B_d\\,\\delta u_k + f_d + E_d\\,g_{k+1}, \\qquad
          g_{k+1} = g\\big(w_{N,k+1}\\big),\\quad
          w_{N,k+1} = \\underbrace{w_{N0} + C_N(A_d \\delta x_k + B_d \\delta u_k + f_d) + D_N \\delta u_k}_{c_k}
                      + \\underbrace{(C_N E_d + D_g)}_{H}\\,g_{k+1}

so each step is a Newton solve of ``w - c_k - H g(w) = 0`` in the few nonlinear unknowns (backtracking
line search on the residual scaled to force units), then one state update. The scheme is exact for the
linear structure (any step, any stiffness), first order in the nonlinear force (exact while ``g`` is
constant: sliding, contact), and for passive laws unconditionally stable (implicit Euler on ``g``).

Regime changes: a chunk of steps runs in one regime; the first step whose end state lies in another
regime (or whose Newton failed) ends it. That step and the following ones are taken one at a time in
``FINE x substeps`` dense sub-steps (linear part in numpy, Newton in one CasADi call), each redone with the
tangent of its end state's regime when that differs (if Newton fails: in the regime of its last iterate
or start, then as two half sub-steps), until ``SETTLE`` steps pass without a change.

The state is carried in real modal coordinates of ``A`` (``δx = V ξ``; complex pairs as 2x2 rotation
blocks), so a step is a few vector operations of length ``n`` and products with the thin matrices
``V^{-1}B_d``, ``V^{-1}E_d``, ``C_N V``; if ``A`` is not safely diagonalisable (a Jordan block, e.g. an
undamped rigid-body mode), a dense ``A_d`` is used instead (per regime; the basis is computed only for
regimes that run chunks). Chunks of steps are one CasADi Function
(``mapaccum``), called through zero-copy buffers: no per-step Python inside a regime.
"""

from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .simulate import SimulationError, SimulationResult, _evaluate_outputs, _sample_controllers

CHUNK = 256          # most output intervals per chunk Function (lengths are powers of two, inputs padded)
NEWTON_TOL = 1e-6    # accepted final residual, as a force relative to 1 + max |g| (the nonlinear forces)
FAR = 1.0e6          # distance [SI units] of the far points that define the outer-branch slopes
REGIME_RTOL = 0.5    # a tangent entry belongs to a regime if within this relative distance of its slope ...
REGIME_ATOL = 1e-3   # ... or within this fraction of the steepest slope seen for that entry
REGIME_COUPLING = 1e-3  # ... or when the slope difference times dw/dg over one step is below this
MAX_REGIMES = 32     # beyond this, the nearest cached regime is reused
FINE = 16            # sub-steps per step while a regime change is being resolved
SETTLE = 2           # steps without a regime change before chunks are used again
_ALPHAS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125)
_ROUNDOFF = 64 * np.finfo(float).eps  # relative round-off allowed in the positions of the implicit equation
_COND_MAX = 1.0e8    # largest eigenvector condition number accepted for modal coordinates


def nonlinear_structure(dae):
    """``(N, rows)``: indices into ``[x', x, z, u]`` entering ``F`` nonlinearly, and the rows containing them so."""
    key = "split_structure"
    if key not in dae._cache:
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        N = [i for i, d in enumerate(ca.which_depends(dae.F_sx, v, 2, False)) if d] if dae.F_sx.numel() else []
        rows = [i for i, d in enumerate(ca.which_depends(dae.F_sx, v[N], 2, True)) if d] if N else []
        dae._cache[key] = (N, rows)
    return dae._cache[key]


class SplitModel:
    """The splitting of one Dae at one start point: the nonlinear map, the regimes (one linear part per
    tangent of the nonlinear laws) and their step Functions."""

    def __init__(self, dae, p, xs, xd0, z0, u0, newton_iter, substeps, h):
        from .dae import _sp

        self.dae, self.p = dae, np.asarray(p, float)
        nx, nz = dae.nx, dae.nz
        self.N, self.rows = nonlinear_structure(dae)
        nv = 2 * nx + nz
        self.Nw = [i for i in self.N if i < nv]          # unknowns of the Newton solve
        self.Nu = [i - nv for i in self.N if i >= nv]    # nonlinear inputs (known per step)
        names = [f"der({n})" for n in dae.x_names] + list(dae.x_names) + list(dae.z_names)
        self.names = [names[i] for i in self.Nw]
        self.n_iter, self.substeps = int(newton_iter), int(substeps)
        self.v0 = np.concatenate([xd0, xs, z0, u0])
        self.xs, self.u0 = np.asarray(xs, float), np.asarray(u0, float)
        self.xd0, self.z0 = np.asarray(xd0, float), np.asarray(z0, float)
        F0, Jxd, Jx, Jz, Ju = dae.jacobians(xd0, xs, z0, u0, p)
        self.F0 = np.asarray(F0, float).reshape(-1, 1)
        self.J = sp.hstack([_sp(Jxd), _sp(Jx), _sp(Jz), _sp(Ju)]).tolil()
        self.regimes, self.retries, self.max_residual = [], 0, 0.0
        self.regime_steps = 0
        r, nN = len(self.rows), len(self.Nw)
        self.iw = [self.N.index(i) for i in self.Nw]            # columns of the Newton unknowns in the block
        if not r:
            self.J0 = np.zeros((0, len(self.N)))
            self.base = self.regime(self.J0)
            return
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        Fr = dae.F_sx[self.rows]
        self.Fr0 = np.array(ca.densify(ca.Function("split_fr", [v, dae.ps], [Fr])(self.v0, p))).ravel()
        jr = ca.Function("split_jr", [v, dae.ps], [ca.jacobian(Fr, v[self.N])])
        self.J0 = np.array(ca.densify(jr(self.v0, p)))
        # the outer-branch slopes (far points) are the candidates an entry snaps to (viscous B, contact c);
        # the steepest slope seen at a few probes sets the absolute floor of the regime test
        sigma = (1.0 + np.mod(np.arange(len(self.N)) * 0.6180339887, 1.0)) * np.where(
            np.arange(len(self.N)) % 2, -1.0, 1.0)
        probes = []
        for dist in (FAR, 1.0, 1e-3, 1e-6):
            for sgn in (1.0, -1.0):
                vf = self.v0.copy()
                vf[self.N] += sgn * dist * sigma
                probes.append(np.array(ca.densify(jr(vf, p))))
        self.Jfar = [J for J in probes[:2] if np.all(np.isfinite(J))]
        allJ = np.stack([self.J0] + [J for J in probes if np.all(np.isfinite(J))])
        self.scale = np.max(np.abs(allJ), axis=0)
        self.atol = REGIME_ATOL * self.scale + 1e-300
        # (w_N, u_N) -> F_r and its tangent, the other variables at the start point
        w = ca.SX.sym("w", nN)
        uN = ca.SX.sym("uN", len(self.Nu))
        vv = ca.SX(ca.DM(self.v0))
        nv_ = len(self.v0) - dae.nu
        for a, i in enumerate(self.Nw):
            vv[i] = w[a]
        for a, i in enumerate(self.Nu):
            vv[nv_ + i] = uN[a]
        Frw = ca.Function("split_frw", [v, dae.ps], [Fr])(vv, ca.DM(self.p))
        self.w_sym, self.uN_sym, self.Fr_w = w, uN, Frw
        self.tangent = ca.Function("split_tangent", [w, uN], [ca.jacobian(Frw, ca.vertcat(w, uN))])
        # a slope error dJ costs ~ dJ H / 2 relative per step (H = dw/dg over a step): the floor of the regime
        # test is also REGIME_COUPLING / |H|, H of the softest branches (largest response)
        cand = np.stack([self.J0] + self.Jfar)
        Jsoft = np.take_along_axis(cand, np.argmin(np.abs(cand), axis=0)[None], axis=0)[0]
        H = _Regime(self, Jsoft, -1).discretise(h / self.substeps)["H"]
        Hw = np.zeros_like(self.J0)
        Hw[:, self.iw] = np.abs(H.T)
        with np.errstate(divide="ignore"):
            self.atol = np.minimum(self.atol, np.where(Hw > 0, REGIME_COUPLING / Hw, np.inf))
        self.base = self.regime_of(self.v0[self.Nw], self.u0[self.Nu])

    # ---- regimes --------------------------------------------------------------------------------
    def mismatch(self, Jnow, Jreg):
        """Largest entry of ``|Jnow - Jreg| / (rtol max(|Jnow|, |Jreg|) + atol)``: > 1 = another regime."""
        return float(np.max(np.abs(Jnow - Jreg) / (REGIME_RTOL * np.maximum(np.abs(Jnow), np.abs(Jreg))
                                                     + self.atol), initial=0.0))

    def regime_of(self, w, uN):
        """The cached regime whose slopes match the tangent at ``(w, u_N)``, or a new one for that tangent
        (entries near an outer-branch slope snapped to it)."""
        if not self.rows:
            return self.base
        Jnow = np.array(ca.densify(self.tangent(w, uN)))
        if not np.all(np.isfinite(Jnow)):
            return self.regimes[-1] if self.regimes else self.regime(self.J0)
        mis = [self.mismatch(Jnow, R.Jblk) for R in self.regimes]
        if mis and min(mis) <= 1.0:
            return self.regimes[int(np.argmin(mis))]
        if len(self.regimes) >= MAX_REGIMES:
            return self.regimes[int(np.argmin(mis))]
        Jr = Jnow.copy()
        for Jf in self.Jfar:
            near = np.abs(Jr - Jf) <= self.atol
            Jr[near] = Jf[near]
        return self.regime(Jr)

    def regime(self, Jblk):
        R = _Regime(self, Jblk, len(self.regimes))
        self.regimes.append(R)
        return R

    def g_base(self, W, UN):
        """``g`` of the base regime at many points (rows: time points)."""
        if not self.rows:
            return np.zeros((W.shape[0], 0))
        f = self.base.g_fun.map(W.shape[0])
        return np.array(f(W.T, UN.T)[0]).T.reshape(W.shape[0], -1)


class _Regime:
    """One linear part: the Jacobian at the start point with the block (nonlinear rows, nonlinear variables)
    replaced by the regime's slopes ``Jblk``; ``g = F_r(w) - F_r0 - Jblk (w - w0)``."""

    def __init__(self, m, Jblk, index):
        from .linear import explicit_form

        dae = m.dae
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        self.m, self.Jblk, self.index = m, np.asarray(Jblk, float), index
        r, nN = len(m.rows), len(m.Nw)
        J = m.J.copy()
        for a, i in enumerate(m.rows):
            for b, j in enumerate(m.N):
                J[i, j] = J[i, j] - m.J0[a, b] + self.Jblk[a, b]
        J = J.tocsc()
        cols = np.cumsum([0, nx, nx, nz, nu])
        Jxd_r, Jx_r, Jz_r, Ju_r = (J[:, cols[i]:cols[i + 1]] for i in range(4))
        P = sp.csc_matrix((np.ones(r), (m.rows, np.arange(r))), shape=(J.shape[0], r))
        A, BEc, Zx, ZuZgc = explicit_form(dae, Jxd_r, Jx_r, Jz_r, sp.hstack([Ju_r, P, sp.csc_matrix(m.F0)]).tocsc())
        self.A = A
        self.B, self.E = BEc[:, :nu], BEc[:, nu:nu + r]
        self.c = m.xd0 + BEc[:, -1]  # x' at dx = 0, du = 0, g = 0
        self.Zx, self.Zu, self.Zg = Zx, ZuZgc[:, :nu], ZuZgc[:, nu:nu + r]
        self.zc = m.z0 + ZuZgc[:, -1]
        Cn, Dn, Dg, wc = np.zeros((nN, nx)), np.zeros((nN, nu)), np.zeros((nN, r)), np.zeros(nN)
        for a, i in enumerate(m.Nw):
            if i < nx:
                Cn[a], Dn[a], Dg[a], wc[a] = self.A[i], self.B[i], self.E[i], self.c[i]
            elif i < 2 * nx:
                Cn[a, i - nx], wc[a] = 1.0, m.xs[i - nx]
            else:
                j = i - 2 * nx
                Cn[a], Dn[a], Dg[a], wc[a] = self.Zx[j], self.Zu[j], self.Zg[j], self.zc[j]
        self.Cn, self.Dn, self.Dg, self.wc = Cn, Dn, Dg, wc
        self.V, self.dense, self.cond, self.modal_done = None, True, np.nan, False  # modal basis: when chunks need it
        self.disc, self.funs, self.newtons = {}, {}, {}
        if r:
            w, uN = m.w_sym, m.uN_sym
            g = m.Fr_w - ca.DM(m.Fr0) - ca.mtimes(ca.DM(self.Jblk), ca.vertcat(w, uN) - ca.DM(m.v0[m.N]))
            G = ca.jacobian(g, w)
            Jw = ca.DM(self.Jblk[:, m.iw])
            Jnow = G + Jw
            atol = ca.DM(m.atol[:, m.iw])
            mis = ca.mmax(ca.fabs(G) / (REGIME_RTOL * ca.fmax(ca.fabs(Jnow), ca.fabs(Jw)) + atol))
            self.g_fun = ca.Function("split_g", [w, uN], [g, G, mis])
        else:
            self.g_fun = None

    def g_of(self, w, uN):
        return np.array(self.g_fun(w, uN)[0]).ravel() if self.g_fun is not None else np.zeros(0)

    # ---- linear part ----------------------------------------------------------------------------
    def _modal(self):
        """Real modal basis ``V`` of ``A`` (ordered: real modes, then real parts, then imaginary parts of the
        complex pairs) or None if ``A`` is not safely diagonalisable."""
        n = self.A.shape[0]
        self.V, self.dense, self.cond, self.modal_done = None, True, np.nan, True
        if n == 0:
            return
        lam, W = sla.eig(self.A)
        real = np.abs(lam.imag) <= 1e-12 * np.maximum(np.abs(lam), 1.0)
        up = ~real & (lam.imag > 0)
        if np.count_nonzero(up) != np.count_nonzero(~real & (lam.imag < 0)):
            return
        V = np.hstack([W[:, real].real, W[:, up].real, W[:, up].imag])
        V /= np.linalg.norm(V, axis=0)
        try:
            cond = np.linalg.cond(V)
        except np.linalg.LinAlgError:
            return
        if not np.isfinite(cond) or cond > _COND_MAX:
            return
        self.V, self.cond, self.dense = V, cond, False
        self.n_real, self.n_pair = int(np.count_nonzero(real)), int(np.count_nonzero(up))
        self.V_lu = sla.lu_factor(V)

    def discretise(self, h, modal=False):
        """Step matrices for the sub-step ``h`` (cached); with ``modal``, also in modal coordinates."""
        key = float(h)
        if modal and not self.modal_done:
            self._modal()
        if key in self.disc and (not modal or self.V is None or "d1" in self.disc[key]):
            return self.disc[key]
        if key in self.disc:
            d = self.disc[key]
            self._modal_matrices(d)
            return d
        nx, nu, r = self.A.shape[0], self.B.shape[1], self.E.shape[1]
        m = nx + nu + r + 1
        Maug = np.zeros((m, m))
        Maug[:nx, :nx] = self.A * h
        Maug[:nx, nx:nx + nu] = self.B * h
        Maug[:nx, nx + nu:nx + nu + r] = self.E * h
        Maug[:nx, -1] = self.c * h
        Ex = sla.expm(Maug)
        Ad, Bd, Ed, fd = Ex[:nx, :nx], Ex[:nx, nx:nx + nu], Ex[:nx, nx + nu:nx + nu + r], Ex[:nx, -1]
        H = self.Cn @ Ed + self.Dg
        d = {"H": H, "Ad": Ad, "Bd": Bd, "Ed": Ed, "fd": fd}
        if modal and self.V is not None:
            self._modal_matrices(d)
        self.disc[key] = d
        return d

    def _modal_matrices(self, d):
        Ad, Bd, Ed, fd = d["Ad"], d["Bd"], d["Ed"], d["fd"]
        nx = Ad.shape[0]
        V, lu = self.V, self.V_lu
        Am = sla.lu_solve(lu, Ad @ V)
        nr, npair = self.n_real, self.n_pair
        diag = np.diag(Am).copy()
        perm = np.r_[np.arange(nr), nr + npair + np.arange(npair), nr + np.arange(npair)]
        off = Am[np.arange(nx), perm].copy()
        off[:nr] = 0.0
        # the rest of Am is round-off of the similarity transform, unless A was (nearly) defective
        rest = Am.copy()
        rest[np.arange(nx), np.arange(nx)] = 0.0
        rest[np.arange(nx), perm] = 0.0
        if np.max(np.abs(rest)) > 1e-8 * max(np.max(np.abs(Am)), 1.0):
            self.dense = True  # (nearly) defective A: this regime steps in dense coordinates
        d.update(d1=diag, d2=off, perm=perm, Bm=sla.lu_solve(lu, Bd), Em=sla.lu_solve(lu, Ed),
                 fm=sla.lu_solve(lu, fd), Cm=self.Cn @ V)

    def to_coords(self, dx, dense):
        return dx if dense else sla.lu_solve(self.V_lu, dx)

    def from_coords(self, X, dense):
        return X if dense else X @ self.V.T

    # ---- nonlinear part -------------------------------------------------------------------------
    def newton_functions(self, H):
        """SX Functions for ``w - c - H g(w) = 0``: one damped Newton iteration ``(w, c, u_N) -> (w+, res)``
        and ``(w, c, u_N) -> (g, res, w, mismatch)``; ``res`` is the residual per unknown in force units
        (divided by the size of H's row), relative to ``1 + max |g|``."""
        key = H.tobytes()
        if key in self.newtons:
            return self.newtons[key]
        nN, r = H.shape
        w = ca.SX.sym("w", nN)
        c = ca.SX.sym("c", nN)
        uN = ca.SX.sym("uN", len(self.m.Nu))
        Hs = ca.DM(H)
        sig = np.sum(np.abs(H), axis=1)
        isig = ca.DM(1.0 / np.maximum(sig, 1e-12 * max(np.max(sig, initial=0.0), 1e-300)))

        def scaled_residual(wv):
            gv, G, mis = self.g_fun(wv, uN)
            return gv, G, mis, (wv - c - ca.mtimes(Hs, gv)) * isig

        def relative(Rv, wv, gv):
            # force residual relative to 1 + max |g|, less the round-off of the positions (at short steps H is
            # tiny and 1 ulp of a position is a large force)
            ulp = _ROUNDOFF * (ca.fabs(wv) + ca.fabs(c) + ca.fabs(ca.mtimes(Hs, gv))) * isig
            return ca.fmax(ca.fabs(Rv) - ulp, 0) / (1 + ca.mmax(ca.fabs(gv)))

        gv, G, mis, R = scaled_residual(w)
        s = ca.solve(ca.DM.eye(nN) - ca.mtimes(Hs, G), R / isig)
        # backtracking: the step length (of _ALPHAS) with the smallest residual, all tried at once
        best_w, best, best_g = None, None, None
        for a in _ALPHAS:
            wa = w - a * s
            ga, _, _, Ra = scaled_residual(wa)
            phi = ca.sumsqr(Ra)
            if best is None:
                best_w, best, best_R, best_g = wa, phi, Ra, ga
            else:
                better = phi < best
                best_w, best = ca.if_else(better, wa, best_w), ca.if_else(better, phi, best)
                best_R, best_g = ca.if_else(better, Ra, best_R), ca.if_else(better, ga, best_g)
        rel = relative(best_R, best_w, best_g)
        it = ca.Function("split_newton_iteration", [w, c, uN], [best_w, rel])
        g_end = ca.Function("split_g_end", [w, c, uN], [gv, relative(R, w, gv), w, mis])
        self.newtons[key] = (it, g_end)
        return it, g_end

    def newton(self, H, n_iter, c, g_prev, uN):
        """MX: ``(g, res, w, mismatch)`` of the implicit step from the predictor ``c + H g_prev``: ``n_iter``
        iterations always, then up to ``4 n_iter`` more, each evaluated only while not converged."""
        if not len(self.m.Nw):
            g, _, mis = self.g_fun(ca.MX(0, 1), uN)
            return g, ca.MX(0, 1), ca.MX(0, 1), mis
        it, g_end = self.newton_functions(H)
        w = c + ca.mtimes(ca.DM(H), g_prev)
        _, res, _, _ = g_end(w, c, uN)
        # a switch between "skip" (case 0) and "iterate" (default): only the taken branch is evaluated
        ws, rs, cs, us = (ca.MX.sym(n, *x.shape) for n, x in (("w", w), ("res", res), ("c", c), ("uN", uN)))
        skip = ca.Function("split_skip", [ws, rs, cs, us], [ws, rs])
        iterate = ca.Function("split_iterate", [ws, rs, cs, us], list(it(ws, cs, us)))
        guarded = ca.Function.conditional("split_guarded", [skip], iterate)
        for i in range(5 * n_iter):
            if i < n_iter:
                w, res = it(w, c, uN)
            else:
                w, res = guarded(ca.mmax(res) > NEWTON_TOL, w, res, c, uN)
        return g_end(w, c, uN)

    def step_function(self, hs, nsub, n_iter, dense):
        """``nsub`` sub-steps of ``hs``: ``(x, g, du, u_N) -> (x+, g+, res, w+, mismatch)`` with ``x`` the
        modal coordinates (or ``δx`` if ``dense``); ``res`` and ``mismatch`` are maxima over the sub-steps."""
        key = ("step", float(hs), nsub, n_iter, dense)
        if key in self.funs:
            return self.funs[key]
        d = self.discretise(hs, modal=not dense)
        dense = dense or self.dense
        m = self.m
        nx, nu, r = self.A.shape[0], self.B.shape[1], self.E.shape[1]
        nN = len(m.Nw)
        xi = ca.MX.sym("xi", nx)
        g = ca.MX.sym("g", r)
        du = ca.MX.sym("du", nu)
        uN = ca.MX.sym("uN", len(m.Nu))
        if dense:
            Ad, Bd, Ed, fd = (ca.DM(d[k]) for k in ("Ad", "Bd", "Ed", "fd"))
            Cm = ca.DM(self.Cn)

            def lin(x):
                return ca.mtimes(Ad, x)
        else:
            d1, d2, perm = ca.DM(d["d1"]), ca.DM(d["d2"]), [int(i) for i in d["perm"]]
            Bd, Ed, fd, Cm = (ca.DM(d[k]) for k in ("Bm", "Em", "fm", "Cm"))

            def lin(x):
                return d1 * x + d2 * x[perm]
        Dn, wc = ca.DM(self.Dn), ca.DM(self.wc)
        xc, gc, res, w, mis = xi, g, ca.MX.zeros(nN), ca.MX.zeros(nN), ca.MX.zeros(1)
        for _ in range(nsub):
            pred = lin(xc) + ca.mtimes(Bd, du) + fd
            if r:
                c = wc + ca.mtimes(Cm, pred) + ca.mtimes(Dn, du)
                gc, rs, w, ms = self.newton(d["H"], n_iter, c, gc, uN)
                res, mis = ca.fmax(res, rs), ca.fmax(mis, ms)
                xc = pred + ca.mtimes(Ed, gc)
            else:
                xc = pred
        f = ca.Function("split_step", [xi, g, du, uN], [xc, gc, res, w, mis])
        self.funs[key] = f
        return f

    def fine(self, hs, n_iter):
        """One dense sub-step ``(δx, w, du, u_N) -> [δx+, w+, res, mismatch]`` (``g`` of the start from ``w``):
        the linear part in numpy, the implicit equation in one CasADi call through preallocated buffers."""
        key = ("fine", float(hs), n_iter)
        if key in self.funs:
            return self.funs[key]
        d = self.discretise(hs)
        nN, nuN = len(self.m.Nw), len(self.m.Nu)
        Ad, Bd, Ed, fd, Cn, Dn, wc = d["Ad"], d["Bd"], d["Ed"], d["fd"], self.Cn, self.Dn, self.wc
        if not self.E.shape[1]:
            def call(x, w, du, uN):
                return [Ad @ x + Bd @ du + fd, w.copy(), np.zeros(nN), np.zeros(1)]
            self.funs[key] = call
            return call
        wp, c, uNs = ca.MX.sym("w", nN), ca.MX.sym("c", nN), ca.MX.sym("uN", nuN)
        g0 = self.g_fun(wp, uNs)[0]
        g, res, w, mis = self.newton(d["H"], n_iter, c, g0, uNs)
        f = ca.Function("split_fine_newton", [wp, c, uNs], [g, res, w, mis])
        buf, ev = f.buffer()
        ins = [np.zeros(k) for k in (nN, nN, nuN)]
        outs = [np.zeros(k) for k in (Ed.shape[1], nN, nN, 1)]
        for i, a in enumerate(ins):
            buf.set_arg(i, memoryview(a))
        for i, a in enumerate(outs):
            buf.set_res(i, memoryview(a))

        def call(x, w, du, uN):
            pred = Ad @ x + Bd @ du + fd
            ins[0][:], ins[1][:], ins[2][:] = w, wc + Cn @ pred + Dn @ du, uN
            ev()
            return [pred + Ed @ outs[0], outs[2].copy(), outs[1].copy(), outs[3].copy()]

        call._keep = (f, buf)
        self.funs[key] = call
        return call

    def chunk(self, h_out, n, n_iter, jit=False):
        """``n`` output intervals in one Function ``(xi0, g0, dU[nu x n], U_N[nuN x n]) -> (Xi, G, Res, W, Mis)``
        (with a zero-copy buffer)."""
        self.discretise(h_out / self.m.substeps, modal=True)  # decides modal or dense coordinates
        dense = self.dense
        key = ("chunk", float(h_out), n, n_iter, dense)
        if key in self.funs:
            return self.funs[key]
        step = self.step_function(h_out / self.m.substeps, self.m.substeps, n_iter, dense)
        f = step.mapaccum("split_chunk", n, 2)
        if jit:
            from ._fixed_step import compiled

            f = compiled(f)
        self.funs[key] = (f, f.buffer(), dense)
        return self.funs[key]


def simulate_split(dae, t, U, xs, p, outputs, controllers, substeps, newton_iter, progress, jit):
    """Driver of ``simulate(method="split")`` (arguments as :func:`bscomp.simulate._simulate_fixed`).

    Inside a regime, chunks of up to ``CHUNK`` steps run in one Function call. A step whose end state has
    another tangent (or whose Newton did not converge) ends the chunk; that step and the next ones are then
    taken one at a time in ``FINE x substeps`` sub-steps, each sub-step redone with the tangent of its end
    state's regime when that differs, until ``SETTLE`` steps pass without a regime change."""
    if outputs:
        dae.output_function(outputs)  # unknown output names fail before integrating
    t_wall = time.perf_counter()
    nx, nu, nt = dae.nx, dae.nu, len(t)
    u0 = U[:, 0]
    xd0, z0 = dae.initialize(xs, u0, p, store=False)
    h_all = np.diff(t)
    m = SplitModel(dae, p, xs, xd0, z0, u0, newton_iter, substeps, h_all[0])
    r, nN = len(m.rows), len(m.Nw)
    dX = np.zeros((nt, nx))
    W = np.zeros((nt, nN))
    W[0] = m.v0[m.Nw]
    Res = np.zeros((nt, nN))
    Reg = np.zeros(nt, int)
    Uh = np.empty((nt, nu))
    Uh[0] = u0
    Ut = np.ascontiguousarray(U.T)
    mfun = dae.output_function([mm for c in controllers for mm in c.measure]) if controllers else None
    ctrl_next = [t[0] for _ in controllers]
    ctrl_u = [None for _ in controllers]
    if progress is None:
        progress = nt > 200 and sys.stderr.isatty()
    n_calls, n_fine, n_changes, k = 0, 0, 0, 0
    n_iter = m.n_iter
    h_keys = []
    R = m.base
    fine_left = 0
    grow = CHUNK if not r else 4
    base = m.base

    def fail(j, what):
        raise SimulationError(
            f"split step on '{dae.name}': {what} between t = {t[j - 1]:.6g} s and t = {t[j]:.6g} s. Hints: more "
            f"substeps (now {substeps}) or newton_iter (now {n_iter}, retried with {4 * n_iter}); a law much "
            "stiffer than the step resolves (friction v_reg, contact stiffness) may need method='idas'")

    def newton_message(res):
        var = m.names[int(np.nanargmax(np.where(np.isfinite(res), res, np.inf)))]
        return f"Newton did not converge for the nonlinear variable '{var}' (scaled residual " \
               f"{np.nanmax(res):.2g} > {NEWTON_TOL:g})"

    def sub(Rg, x, w, hs, du, uN):
        """One dense sub-step in regime ``Rg`` (retried with 4x the Newton iterations)."""
        for its in (n_iter, 4 * n_iter):
            out = Rg.fine(hs, its)(x, w, du, uN)
            ok = np.isfinite(out[0]).all() and (not nN or np.max(out[2]) <= NEWTON_TOL)
            if ok:
                break
            m.retries += 1
        return out, ok

    def advance(R, x, w, hs, du, uN, depth, k):
        """A sub-step from ``(x, w)`` in regime ``R``, redone in the regime of its end state if that differs;
        if Newton fails, in the start state's regime, then as two half sub-steps (at most 3 levels)."""
        nonlocal n_changes
        out, ok = sub(R, x, w, hs, du, uN)
        if ok and out[3][0] > 1.0:
            R2 = m.regime_of(out[1], uN)
            if R2 is not R:
                n_changes += 1
                out2, ok2 = sub(R2, x, w, hs, du, uN)
                if ok2:
                    out, R = out2, R2
                    if out[3][0] > 1.0:
                        R = m.regime_of(out[1], uN)
        for w_try in ((out[1], w) if not ok else ()):  # the regime of the last iterate, then of the start
            R2 = m.regime_of(w_try, uN) if np.isfinite(w_try).all() else R
            if R2 is not R:
                out2, ok2 = sub(R2, x, w, hs, du, uN)
                if ok2:
                    out, R, ok = out2, R2, True
                    n_changes += 1
                    break
        if not ok:
            if depth < 3:
                x1, w1, r1, R = advance(R, x, w, hs / 2, du, uN, depth + 1, k)
                x2, w2, r2, R = advance(R, x1, w1, hs / 2, du, uN, depth + 1, k)
                return x2, w2, np.maximum(r1, r2), R
            fail(k + 1, newton_message(out[2]) if np.isfinite(out[0]).all() else "the state became non-finite")
        return out[0], out[1], out[2], R

    while k < nt - 1:
        h = h_all[k]
        if controllers:
            u_k = Ut[k].copy()

            def y_of(uk, k=k):
                du = uk - u0
                g = base.g_of(W[k], uk[m.Nu]) if r else np.zeros(0)
                xd = base.c + base.A @ dX[k] + base.B @ du + base.E @ g
                z = base.zc + base.Zx @ dX[k] + base.Zu @ du + base.Zg @ g
                return np.asarray(mfun(xd, xs + dX[k], z, uk, p)).ravel()

            _sample_controllers(dae, controllers, t[k], u_k, ctrl_next, ctrl_u, y_of)
            t_next = min(ctrl_next)
        else:
            t_next = np.inf
        hk = next((hh for hh in h_keys if abs(hh - h) <= 1e-9 * h), None)
        if hk is None:
            h_keys.append(h)
            hk = h
        if fine_left > 0:
            n = 1
        else:
            n = 1
            while (k + n < nt - 1 and n < min(CHUNK, grow) and abs(h_all[k + n] - h) < 1e-9 * h
                   and t[k + n] + 1e-12 < t_next):
                n += 1
        Uc = Ut[k:k + n]
        if controllers:
            Uc = Uc.copy()
            for c, val in zip(controllers, ctrl_u):
                if val is not None:
                    for a, v in zip(c.actuate, val):
                        Uc[:, dae.u_names.index(a)] = v
        n_calls += 1
        if fine_left > 0:
            # ---- one step in FINE x substeps sub-steps, each in the regime of its end state ----
            du, uN = Uc[0] - u0, Uc[0][m.Nu]
            hs = hk / (substeps * FINE)
            x, w = dX[k].copy(), W[k].copy()
            res_max = np.zeros(nN)
            changes0 = n_changes
            for _ in range(substeps * FINE):
                x, w, res, R = advance(R, x, w, hs, du, uN, 0, k)
                res_max = np.maximum(res_max, res)
            changed = n_changes > changes0
            dX[k + 1], W[k + 1], Res[k + 1], Reg[k + 1] = x, w, res_max, R.index
            Uh[k + 1] = Uc[0]
            n_fine += 1
            fine_left = SETTLE if changed else fine_left - 1
            grow = 4
            k += 1
        else:
            # ---- a chunk of up to n steps in regime R, cut at the first step that leaves it ----
            L = min(CHUNK, 1 << (n - 1).bit_length())  # a few Function lengths, padded by repeating the last input
            pad = np.r_[np.arange(n), np.full(L - n, n - 1)]
            dU = np.ascontiguousarray(Uc[pad] - u0)
            UN = np.ascontiguousarray(Uc[pad][:, m.Nu])
            Xo, Go, Ro, Wo, Mo = np.empty((L, nx)), np.empty((L, r)), np.empty((L, nN)), np.empty((L, nN)), \
                np.empty((L, 1))
            _, (buf, ev), cdense = R.chunk(hk, L, n_iter, jit)
            g0 = R.g_of(W[k], Uc[0][m.Nu])
            # (the arrays must stay alive until ev())
            args = (np.ascontiguousarray(R.to_coords(dX[k], cdense)), np.ascontiguousarray(g0), dU, UN)
            for i, a in enumerate(args):
                buf.set_arg(i, memoryview(a.reshape(-1)))
            for i, a in enumerate((Xo, Go, Ro, Wo, Mo)):
                buf.set_res(i, memoryview(a.reshape(-1)))
            ev()
            bad = ~np.isfinite(Xo[:n]).all(axis=1)
            if nN:
                bad |= ~(np.max(Ro[:n], axis=1) <= NEWTON_TOL) | (Mo[:n, 0] > 1.0)
            j = int(np.argmax(bad)) if bad.any() else n
            if j:
                dX[k + 1:k + 1 + j] = R.from_coords(Xo[:j], cdense)
                W[k + 1:k + 1 + j], Res[k + 1:k + 1 + j], Reg[k + 1:k + 1 + j] = Wo[:j], Ro[:j], R.index
                Uh[k + 1:k + 1 + j] = Uc[:j]
            if j < n:
                fine_left = SETTLE
            else:
                grow = 2 * grow
            k += j
        if nN:
            m.max_residual = max(m.max_residual, float(np.max(Res[:k + 1][-max(n, 1):])))
        if progress and (n_calls % 20 == 0 or k == nt - 1):
            frac = k / (nt - 1)
            sys.stderr.write(f"\r  simulating '{dae.name}' [{'#' * int(30 * frac):<30}] {100 * frac:5.1f}%  "
                             f"t = {t[k]:.4g} s")
            if k == nt - 1:
                sys.stderr.write("\n")
    X = xs + dX
    dU = Uh - u0
    G = m.g_base(W, Uh[:, m.Nu])
    XD = base.c + dX @ base.A.T + dU @ base.B.T + G @ base.E.T
    Z = base.zc + dX @ base.Zx.T + dU @ base.Zu.T + G @ base.Zg.T
    out = _evaluate_outputs(dae, outputs, XD, X, Z, Uh, p)
    wall = time.perf_counter() - t_wall
    coords = ", ".join(("dense" if R_.dense else f"modal (eigenvector condition {R_.cond:.2g})") if R_.modal_done
                       else "fine steps only" for R_ in m.regimes)
    return SimulationResult(
        t=t, x=X, xd=XD, z=Z, u=Uh, x_names=list(dae.x_names), z_names=list(dae.z_names), u_names=list(dae.u_names),
        outputs=out,
        stats={"wall_s": wall, "method": "split",
               "scheme": "exponential (exact ZOH) linear part re-linearized per regime of the nonlinear laws, "
                         "implicit held nonlinear correction (order 1)",
               "step": float(np.min(h_all)) / substeps, "substeps": substeps, "chunk_calls": n_calls,
               "fine_steps": n_fine, "regime_changes": n_changes, "regimes": len(m.regimes),
               "regime_per_step": Reg, "coordinates": coords,
               "nonlinear_variables": list(m.names), "nonlinear_rows": r,
               "newton_iterations": n_iter, "newton_retries": m.retries,
               "newton_max_residual": m.max_residual, "jit": jit,
               "real_time_factor": (t[-1] - t[0]) / wall if wall > 0 else np.inf})
