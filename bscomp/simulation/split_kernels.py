"""The step Functions of ``simulate(method="split")`` (:mod:`bscomp.simulation.split`): the implicit equation
``w - c - H g(w) = 0`` of one step in the few nonlinear unknowns (undamped and damped Newton), the step of
the linear part in modal or dense coordinates, chunks of 4, 16, 64 or 256 steps and the fine batches, all
CasADi Functions with the regime's matrices as inputs (one set per start point, shared by all regimes).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from bscomp.simulation.native import native_function

__all__ = ["Kernels", "Numeric", "NEWTON_TOL", "REGIME_RTOL"]

NEWTON_TOL = 1e-6    # accepted final residual, as a force relative to 1 + max |g| (the nonlinear forces)
REGIME_RTOL = 0.5    # a tangent entry belongs to a regime if within this relative distance of its slope ...
_ALPHAS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125)
_ROUNDOFF = 64 * np.finfo(float).eps  # relative round-off allowed in the positions of the implicit equation
RIGID_BLOCK = 2      # modal step: the last (slowest) modal coordinates whose columns of V^-1 A_d V are kept whole


def rigid_block(nx) -> int:
    """Width of the modal step's column block of the slowest modes (:data:`RIGID_BLOCK`, at most ``nx``)."""
    return min(RIGID_BLOCK, nx)


class Numeric:
    """A CasADi Function called on numpy arrays through a zero-copy buffer (no DM conversion): returns its
    outputs as dense arrays of their shapes (the Function's outputs must be dense)."""

    def __init__(self, f):
        self.f, (self.buf, self.ev) = f, f.buffer()
        self.shapes = [f.size_out(i) for i in range(f.n_out())]

    def __call__(self, *args):
        ins = [np.asfortranarray(a, float).reshape(-1, order="F") for a in args]  # alive until ev()
        outs = [np.empty(s[0] * s[1]) for s in self.shapes]
        for i, a in enumerate(ins):
            self.buf.set_arg(i, memoryview(a))
        for i, a in enumerate(outs):
            self.buf.set_res(i, memoryview(a))
        self.ev()
        return [a.reshape(s, order="F") for a, s in zip(outs, self.shapes)]



class Kernels:
    """The step Functions of one start point (parameters, ``v0``, ``F_r(v0)`` and the regime tolerances folded
    in as constants; cached with the :class:`SplitModel` on ``dae._cache``), with everything that depends on
    the regime as inputs: its slopes, discretised matrices and ``H``. A new regime costs only its matrices."""

    def __init__(self, dae, N, rows, n_iter, K, mp_value):
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        self.nv = 2 * nx + nz
        self.N, self.rows, self.n_iter, self.K = list(N), list(rows), int(n_iter), int(K)
        self.Nw = [i for i in N if i < self.nv]
        self.Nu = [i - self.nv for i in N if i >= self.nv]
        self.iw = [self.N.index(i) for i in self.Nw]
        self.nx, self.nu, self.r, self.nN, self.nuN = nx, nu, len(rows), len(self.Nw), len(self.Nu)
        self.np_, self.nvall = dae.np, self.nv + nu
        self.nmp = self.np_ + self.nvall + self.r + self.r * self.nN
        self.funs = {}
        r, nN, nuN = self.r, self.nN, self.nuN
        self.w, self.uN = ca.SX.sym("w", nN), ca.SX.sym("uN", nuN)
        self.Jblk = ca.SX.sym("Jblk", r, len(self.N))
        self.H = ca.SX.sym("H", nN, r)
        self.mp = ca.SX.sym("mp", self.nmp)
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        self.Fr_fun = ca.Function("split_fr", [v, dae.ps], [dae.F_sx[self.rows]])
        g, G, mis = self._g_expr(self.w, self.uN, self.Jblk, self.mp)
        # specialised to this start point and parameters (folded into constants): mp is an empty input from here
        g, G, mis = ca.substitute([g, G, mis], [self.mp], [ca.DM(np.asarray(mp_value, float))])
        self.nmp, self.mp = 0, ca.SX.sym("mp", 0)
        self.g_fun = ca.Function("split_g", [self.w, self.uN, self.Jblk, self.mp], [g, G, mis])
        self.g_only = Numeric(ca.Function("split_g_only", [self.w, self.uN, self.Jblk, self.mp], [ca.densify(g)]))
        if nN:
            c = ca.SX.sym("c", nN)
            args = [self.w, c, self.uN, self.H, self.Jblk, self.mp]
            self.it_fun = ca.Function("split_newton_iteration", args, list(self._iteration(*args)))
            self.full_fun = ca.Function("split_newton_full", args, [self._full_iteration(*args)])
            self.gend_fun = ca.Function("split_g_end", args, list(self._g_end(*args)))

    # ---- symbolic pieces --------------------------------------------------------------------------
    def _unpack_mp(self, mp):
        a = np.cumsum([0, self.np_, self.nvall, self.r, self.r * self.nN])
        return mp[a[0]:a[1]], mp[a[1]:a[2]], mp[a[2]:a[3]], ca.reshape(mp[a[3]:a[4]], self.r, self.nN)

    def _g(self, w, uN, Jblk, mp):
        return self.g_fun(w, uN, Jblk, mp)

    def _g_expr(self, w, uN, Jblk, mp):
        """``g = F_r(v) - F_r(v0) - Jblk (v_N - v0_N)`` with ``v`` = ``v0`` but ``w``, ``u_N``; its Jacobian
        ``G`` in ``w`` and the regime mismatch of the tangent ``G + Jblk_w``."""
        p, v0, Fr0, atol = self._unpack_mp(mp)
        el = [v0[i] for i in range(self.nvall)]
        for a, i in enumerate(self.Nw):
            el[i] = w[a]
        for a, i in enumerate(self.Nu):
            el[self.nv + i] = uN[a]
        v = ca.vertcat(*el)
        vN, v0N = ca.vertcat(w, uN), v0[self.N]
        g = self.Fr_fun(v, p) - Fr0 - ca.mtimes(Jblk, vN - v0N)
        if not self.nN:
            return g, ca.SX(self.r, 0), ca.SX(0)
        G = ca.jacobian(g, w)
        Jw = Jblk[:, self.iw]
        mis = ca.mmax(ca.fabs(G) / (REGIME_RTOL * ca.fmax(ca.fabs(G + Jw), ca.fabs(Jw)) + atol))
        return g, G, mis

    def _scales(self, w, c, H):
        sig = ca.sum2(ca.fabs(H))
        isig = 1.0 / ca.fmax(sig, 1e-12 * ca.fmax(ca.mmax(sig), 1e-300))
        return isig

    def _relative(self, Rv, wv, gv, c, H, isig):
        # force residual relative to 1 + max |g|, less the round-off of the positions (at short steps H is
        # tiny and 1 ulp of a position is a large force)
        ulp = _ROUNDOFF * (ca.fabs(wv) + ca.fabs(c) + ca.fabs(ca.mtimes(H, gv))) * isig
        return ca.fmax(ca.fabs(Rv) - ulp, 0) / (1 + ca.mmax(ca.fabs(gv)))

    def _iteration(self, w, c, uN, H, Jblk, mp):
        """One damped Newton iteration for ``w - c - H g(w) = 0``: ``(w+, res)``; ``res`` per unknown in force
        units (divided by the size of H's row), relative to ``1 + max |g|``."""
        isig = self._scales(w, c, H)

        def scaled_residual(wv):
            gv, G, _ = self._g(wv, uN, Jblk, mp)
            return gv, G, (wv - c - ca.mtimes(H, gv)) * isig

        gv, G, R = scaled_residual(w)
        s = ca.solve(ca.SX.eye(self.nN) - ca.mtimes(H, G), R / isig)
        # backtracking: the step length (of _ALPHAS) with the smallest residual, all tried at once
        best_w = best = best_R = best_g = None
        for a in _ALPHAS:
            wa = w - a * s
            ga, _, Ra = scaled_residual(wa)
            phi = ca.sumsqr(Ra)
            if best is None:
                best_w, best, best_R, best_g = wa, phi, Ra, ga
            else:
                better = phi < best
                best_w, best = ca.if_else(better, wa, best_w), ca.if_else(better, phi, best)
                best_R, best_g = ca.if_else(better, Ra, best_R), ca.if_else(better, ga, best_g)
        return best_w, self._relative(best_R, best_w, best_g, c, H, isig)

    def _full_iteration(self, w, c, uN, H, Jblk, mp):
        """One undamped Newton iteration for ``w - c - H g(w) = 0`` (the laws evaluated once): ``w+``. Used in
        chunks and fine batches; a step it does not converge is redone with the damped :meth:`_iteration`."""
        gv, G, _ = self._g(w, uN, Jblk, mp)
        Rw = w - c - ca.mtimes(H, gv)
        # (I - H G)^-1 = I + H (I - G H)^-1 G: a solve in the r nonlinear rows instead of the nN unknowns
        return w - Rw - ca.mtimes(H, ca.solve(ca.SX.eye(self.r) - ca.mtimes(G, H), ca.mtimes(G, Rw)))

    def _g_end(self, w, c, uN, H, Jblk, mp):
        """``(g, res, w, mismatch)`` at the Newton iterate ``w``."""
        isig = self._scales(w, c, H)
        gv, _, mis = self._g(w, uN, Jblk, mp)
        return gv, self._relative((w - c - ca.mtimes(H, gv)) * isig, w, gv, c, H, isig), w, mis

    def _newton_sx(self, c, g_prev, uN, H, Jblk, mp):
        """SX: ``n_iter`` undamped Newton iterations from the predictor ``c + H g_prev``, then ``(g, res, w,
        mismatch)`` (an unconverged step is redone by the caller with the damped iteration)."""
        if not self.nN:
            g, _, mis = self._g(ca.SX(0, 1), uN, Jblk, mp)
            return g, ca.SX(0, 1), ca.SX(0, 1), mis
        w = c + ca.mtimes(H, g_prev)
        for _ in range(self.n_iter):
            w = self.full_fun(w, c, uN, H, Jblk, mp)
        return self.gend_fun(w, c, uN, H, Jblk, mp)

    # ---- Functions ----------------------------------------------------------------------------------
    def layout(self, dense):
        """Names and shapes of the regime inputs of the step Function (packed column-major in one vector)."""
        nx, nu, r, nN = self.nx, self.nu, self.r, self.nN
        lin = [("Ad", (nx, nx))] if dense else [("d1", (nx, 1)), ("d2", (nx, 1)), ("Rc", (nx, rigid_block(nx)))]
        return lin + [("Bm", (nx, nu)), ("Em", (nx, r)), ("fm", (nx, 1)), ("Cm", (nN, nx)), ("Dn", (nN, nu)),
                      ("wc", (nN, 1)), ("H", (nN, r)), ("Jblk", (r, len(self.N)))]

    def core(self):
        """SX ``(c, g_prev, u_N, H, Jblk, mp) -> (g, res, w, mismatch)``: the implicit equation of one sub-step."""
        if "core" not in self.funs:
            c, g = ca.SX.sym("c", self.nN), ca.SX.sym("g", self.r)
            ins = [c, g, self.uN, self.H, self.Jblk, self.mp]
            self.funs["core"] = ca.Function("split_core", ins, list(self._newton_sx(*ins)))
        return self.funs["core"]

    def step(self, nsub, dense):
        """``nsub`` sub-steps: ``(x, g, du, u_N, *regime matrices (layout), mp) -> (x+, g+, res, w+, mismatch)``,
        ``x`` in modal coordinates (or ``δx`` if ``dense``); ``res`` and ``mismatch`` are maxima over the
        sub-steps. The linear part is MX (vector operations), the implicit equation one SX call."""
        key = ("step", nsub, dense)
        if key in self.funs:
            return self.funs[key]
        nx, nu, r, nN = self.nx, self.nu, self.r, self.nN
        lay = self.layout(dense)
        q = {name: ca.MX.sym(name, m, n) for name, (m, n) in lay}
        x, g, du, uN, mp = ca.MX.sym("x", nx), ca.MX.sym("g", r), ca.MX.sym("du", nu), ca.MX.sym("uN", self.nuN), \
            ca.MX.sym("mp", self.nmp)
        perm = [i ^ 1 if (i ^ 1) < nx else i for i in range(nx)]
        core = self.core() if r else None
        xc, gc, res, w, mis = x, g, ca.MX.zeros(nN), ca.MX.zeros(nN), ca.MX.zeros(1)
        for _ in range(nsub):
            if dense:
                lin = ca.mtimes(q["Ad"], xc)
            else:                       # modal: the diagonal, the pairs, the slowest modes' columns whole
                lin = q["d1"] * xc + q["d2"] * xc[perm] + ca.mtimes(q["Rc"], xc[nx - rigid_block(nx):])
            pred = lin + ca.mtimes(q["Bm"], du) + q["fm"]
            if r:
                c = q["wc"] + ca.mtimes(q["Cm"], pred) + ca.mtimes(q["Dn"], du)
                gc, rs, w, ms = core(c, gc, uN, q["H"], q["Jblk"], mp)
                res, mis = ca.fmax(res, rs), ca.fmax(mis, ms)
                xc = pred + ca.mtimes(q["Em"], gc)
            else:
                xc = pred
        f = ca.Function("split_step", [x, g, du, uN] + [q[name] for name, _ in lay] + [mp], [xc, gc, res, w, mis])
        self.funs[key] = f
        return f

    def chunk(self, n, nsub, dense, jit=False):
        """``n`` steps in one Function ``(xi0, g0, dU[nu x n], U_N[nuN x n], *regime matrices, mp) -> (Xi, G, Res,
        W, Mis)`` with a zero-copy buffer (``jit``: compiled). ``n`` is a power of 4: four calls of the chunk of
        ``n / 4`` (:meth:`_unrolled`), so building all lengths takes a few symbolic calls."""
        key = ("chunk", n, nsub, dense, jit)
        if key in self.funs:
            return self.funs[key]
        f = self._unrolled(n, nsub, dense)
        if jit:
            f = native_function(f)
        self.funs[key] = (f, f.buffer())
        return self.funs[key]

    def _unrolled(self, n, nsub, dense):
        """The MX Function of ``n`` consecutive steps (``n`` = 1 or a power of 4): :meth:`step`, or four calls
        of the one of ``n / 4`` steps chained through ``(x, g)``, outputs concatenated in time."""
        key = ("unrolled", n, nsub, dense)
        if key in self.funs:
            return self.funs[key]
        if n == 1:
            inner, m = self.step(nsub, dense), 1
        else:
            inner, m = self._unrolled(n // 4, nsub, dense), n // 4
        x0, g0 = ca.MX.sym("x", self.nx), ca.MX.sym("g", self.r)
        dU, UN = ca.MX.sym("dU", self.nu, n), ca.MX.sym("UN", self.nuN, n)
        mats = [ca.MX.sym(name, a, b) for name, (a, b) in self.layout(dense)]
        mp = ca.MX.sym("mp", self.nmp)
        parts = n // m
        dUs = ca.horzsplit(dU, m) if self.nu else [ca.MX(0, m)] * parts
        UNs = ca.horzsplit(UN, m) if self.nuN else [ca.MX(0, m)] * parts
        outs = [[] for _ in range(5)]
        x, g = x0, g0
        for i in range(parts):
            o = inner(x, g, dUs[i], UNs[i], *mats, mp)
            x, g = o[0][:, -1], o[1][:, -1]
            for lst, v in zip(outs, o):
                lst.append(v)
        f = ca.Function(f"split_chunk{n}", [x0, g0, dU, UN] + mats + [mp], [ca.horzcat(*o) for o in outs])
        self.funs[key] = f
        return f

    def batch_size(self, n):
        """The length of the fine batch used for ``n`` remaining sub-steps: the smallest power of two (or
        ``K``) that covers them."""
        return min(self.K, 1 << max(int(n) - 1, 0).bit_length())

    def fine_batch(self, K):
        """``K`` dense sub-steps of one regime in the nonlinear unknowns only: ``(C0[nN x K], T[nN x r(K-1)],
        w0, u_N, H, Jblk, mp) -> (W, G, Res, Mis)`` (``K`` columns). The linear part enters through
        ``C0`` (the predictor of ``w`` from the start state, inputs and ``f_d``) and the impulse responses
        ``T_k = C_N A_d^k E_d``: ``c_j = C0_j + sum_i T_(j+1-i) g_i``. Built for the lengths of
        :meth:`batch_size` (a batch computes only the sub-steps that remain in the step)."""
        key = ("fine_batch", K)
        if key in self.funs:
            return self.funs[key]
        r, nN = self.r, self.nN
        C0, T = ca.SX.sym("C0", nN, K), ca.SX.sym("T", nN, r * max(K - 1, 0))
        w0, uN, H, Jblk, mp = ca.SX.sym("w0", nN), self.uN, self.H, self.Jblk, self.mp
        g_prev = self._g(w0, uN, Jblk, mp)[0]
        Gs, outs = [], [[] for _ in range(4)]
        for j in range(K):
            c = C0[:, j]
            if j:  # sum_(i=1..j) T_(j+1-i) g_i: T_1 ... T_j against g_j ... g_1
                c = c + ca.mtimes(T[:, :r * j], ca.vertcat(*Gs[::-1]))
            g_prev, res, w, mis = self._newton_sx(c, g_prev, uN, H, Jblk, mp)
            Gs.append(g_prev)
            for lst, v in zip(outs, (w, g_prev, res, mis)):
                lst.append(v)
        f = ca.Function("split_fine_batch", [C0, T, w0, uN, H, Jblk, mp], [ca.horzcat(*o) for o in outs])
        self.funs[key] = (f, f.buffer())
        return self.funs[key]

    def newton_single(self, n_iter):
        """MX ``(w_start, c, u_N, H, Jblk, mp) -> (g, res, w, mismatch)`` of one implicit sub-step from the
        predictor ``c + H g(w_start)``: ``n_iter`` iterations always, then up to ``4 n_iter`` more, each
        evaluated only while not converged; with a zero-copy buffer."""
        key = ("newton", n_iter)
        if key in self.funs:
            return self.funs[key]
        nN, r = self.nN, self.r
        wp, c, uN = ca.MX.sym("wp", nN), ca.MX.sym("c", nN), ca.MX.sym("uN", self.nuN)
        H, Jblk, mp = ca.MX.sym("H", nN, r), ca.MX.sym("Jblk", r, len(self.N)), ca.MX.sym("mp", self.nmp)
        g0 = self.g_fun(wp, uN, Jblk, mp)[0]
        w = c + ca.mtimes(H, g0)
        _, res, _, _ = self.gend_fun(w, c, uN, H, Jblk, mp)
        ws, rs, cs, us = (ca.MX.sym(n, *x.shape) for n, x in (("w", w), ("res", res), ("c", c), ("uN", uN)))
        Hs, Js, ms = ca.MX.sym("H", nN, r), ca.MX.sym("Jblk", r, len(self.N)), ca.MX.sym("mp", self.nmp)
        skip = ca.Function("split_skip", [ws, rs, cs, us, Hs, Js, ms], [ws, rs])
        iterate = ca.Function("split_iterate", [ws, rs, cs, us, Hs, Js, ms], list(self.it_fun(ws, cs, us, Hs, Js, ms)))
        guarded = ca.Function.conditional("split_guarded", [skip], iterate)
        for i in range(5 * n_iter):
            if i < n_iter:
                w, res = self.it_fun(w, c, uN, H, Jblk, mp)
            else:
                w, res = guarded(ca.mmax(res) > NEWTON_TOL, w, res, c, uN, H, Jblk, mp)
        f = ca.Function("split_newton", [wp, c, uN, H, Jblk, mp], list(self.gend_fun(w, c, uN, H, Jblk, mp)))
        self.funs[key] = (f, f.buffer())
        return self.funs[key]
