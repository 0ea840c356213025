"""The splitting of a Dae for ``simulate(method="split")`` (:mod:`bscomp.simulation.split`, whose module
docstring has the equations): the nonlinear variables and rows (:func:`nonlinear_structure`), the model at
one start point with its regimes (:class:`SplitModel`, cached by :func:`split_model`) and one regime's
linear part with its discretisations and modal basis (:class:`Regime`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.linear.linearization import explicit_form
from bscomp.memo import kept
from bscomp.simulation.split_kernels import REGIME_RTOL, Kernels, Numeric, rigid_block

__all__ = ["SplitModel", "Regime", "split_model", "nonlinear_structure", "step_key", "FINE"]

FAR = 1.0e6          # distance [SI units] of the far points that define the outer-branch slopes
REGIME_ATOL = 1e-3   # a tangent entry also belongs to a regime within this fraction of the steepest slope seen ...
REGIME_COUPLING = 1e-3  # ... or when the slope difference times dw/dg over one step is below this
MAX_REGIMES = 32     # beyond this, the nearest cached regime is reused
FINE = 16            # sub-steps per step while a regime change is being resolved
_COND_MAX = 1.0e9    # largest eigenvector condition number (1-norm, LAPACK estimate) accepted for modal coordinates


def nonlinear_structure(dae):
    """``(N, rows)``: indices into ``[x', x, z, u]`` entering ``F`` nonlinearly, and the rows containing them so."""
    key = "split_structure"
    if key not in dae._cache:
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        N = [i for i, d in enumerate(ca.which_depends(dae.F_sx, v, 2, False)) if d] if dae.F_sx.numel() else []
        rows = [i for i, d in enumerate(ca.which_depends(dae.F_sx, v[N], 2, True)) if d] if N else []
        dae._cache[key] = (N, rows)
    return dae._cache[key]



def step_key(h):
    """Cache key of a step length (robust to the last bits of ``h / 2^j``)."""
    return float(f"{float(h):.12e}")



def split_model(dae, p, xs, xd0, z0, u0, newton_iter, substeps, h):
    """The :class:`SplitModel` for this start point and step, cached on ``dae._cache`` (its regimes, their
    discretisations and modal bases are reused by a later run from the same start; a few kept)."""
    parts = [np.asarray(a, float).tobytes() for a in (p, xs, xd0, z0, u0)]
    key = ("split_model", *parts, int(newton_iter), int(substeps), step_key(h))
    m = kept(dae._cache.setdefault("split_models", {}), key,
             lambda: SplitModel(dae, p, xs, xd0, z0, u0, newton_iter, substeps, h), 4)
    m.reset()
    return m



class SplitModel:
    """The splitting of one Dae at one start point: the nonlinear map and the regimes (one linear part per
    tangent of the nonlinear laws, with its discretisations); the step Functions are shared (:class:`Kernels`)."""

    def __init__(self, dae, p, xs, xd0, z0, u0, newton_iter, substeps, h):
        self.dae, self.p = dae, np.asarray(p, float)
        nx, nz = dae.nx, dae.nz
        self.N, self.rows = nonlinear_structure(dae)
        nv = 2 * nx + nz
        self.Nw = [i for i in self.N if i < nv]          # unknowns of the Newton solve
        self.Nu = [i - nv for i in self.N if i >= nv]    # nonlinear inputs (known per step)
        names = [f"der({n})" for n in dae.x_names] + list(dae.x_names) + list(dae.z_names)
        self.names = [names[i] for i in self.Nw]
        self.n_iter, self.substeps = int(newton_iter), int(substeps)
        self.h_coarse, self.h_fine = step_key(h / self.substeps), step_key(h / (self.substeps * FINE))
        self.v0 = np.concatenate([xd0, xs, z0, u0])
        self.xs, self.u0 = np.asarray(xs, float), np.asarray(u0, float)
        self.xd0, self.z0 = np.asarray(xd0, float), np.asarray(z0, float)
        F0, Jxd, Jx, Jz, Ju = dae.jacobians_at(xd0, xs, z0, u0, p)
        self.F0 = F0.reshape(-1, 1)
        self.J = sp.hstack([Jxd, Jx, Jz, Ju]).tolil()
        self.regimes, self.pool, self.retries, self.max_residual = [], {}, 0, 0.0
        r = len(self.rows)
        self.iw = [self.N.index(i) for i in self.Nw]            # columns of the Newton unknowns in the block
        if not r:
            self.J0 = np.zeros((0, len(self.N)))
            self.kern = Kernels(dae, self.N, self.rows, self.n_iter, self.substeps * FINE,
                                 np.concatenate([self.p, self.v0]))
            self.mp = np.zeros(0)
            self.base = self.regime(self.J0)
            return
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        Fr = dae.F_sx[self.rows]
        Fr_fun = ca.Function("split_fr", [v, dae.ps], [Fr])
        self.Fr0 = np.array(ca.densify(Fr_fun(self.v0, p))).ravel()
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
        # (w_N, u_N) -> tangent of F_r, the other variables at the start point
        w, uN = ca.SX.sym("w", len(self.Nw)), ca.SX.sym("uN", len(self.Nu))
        vv = ca.SX(ca.DM(self.v0))
        for a, i in enumerate(self.Nw):
            vv[i] = w[a]
        for a, i in enumerate(self.Nu):
            vv[nv + i] = uN[a]
        Frw = Fr_fun(vv, ca.DM(self.p))
        Jw = ca.densify(ca.jacobian(Frw, ca.vertcat(w, uN)))
        self.tangent = Numeric(ca.Function("split_tangent", [w, uN], [Jw]))
        # a slope error dJ costs ~ dJ H / 2 relative per step (H = dw/dg over a step): the floor of the regime
        # test is also REGIME_COUPLING / |H|, H of the softest branches (largest response)
        cand = np.stack([self.J0] + self.Jfar)
        Jsoft = np.take_along_axis(cand, np.argmin(np.abs(cand), axis=0)[None], axis=0)[0]
        H = Regime(self, Jsoft, -1).discretise(self.h_coarse)["H"]
        Hw = np.zeros_like(self.J0)
        Hw[:, self.iw] = np.abs(H.T)
        with np.errstate(divide="ignore"):
            self.atol = np.minimum(self.atol, np.where(Hw > 0, REGIME_COUPLING / Hw, np.inf))
        self.kern = Kernels(dae, self.N, self.rows, self.n_iter, self.substeps * FINE, np.concatenate(
            [self.p, self.v0, self.Fr0, self.atol[:, self.iw].reshape(-1, order="F")]))
        self.mp = np.zeros(0)
        self.base = self.regime_of(self.v0[self.Nw], self.u0[self.Nu])

    def reset(self):
        """Start a run: no regime active but the base one; cached regimes are re-activated when the run's
        tangent asks for exactly their slopes (so a second run repeats the first one exactly)."""
        self.retries, self.max_residual = 0, 0.0
        self.regimes = []
        self.activate(self.base)

    def activate(self, R):
        if R not in self.regimes:
            R.index = len(self.regimes)
            self.regimes.append(R)
        return R

    # ---- regimes --------------------------------------------------------------------------------
    def mismatches(self, Jnow):
        """For every active regime (one entry each), the largest entry of ``|Jnow - Jreg| / (rtol max(|Jnow|,
        |Jreg|) + atol)``: > 1 = another regime."""
        if not self.regimes:
            return np.zeros(0)
        Jr = np.stack([R.Jblk for R in self.regimes])
        den = REGIME_RTOL * np.maximum(np.abs(Jnow), np.abs(Jr)) + self.atol
        return np.max(np.abs(Jnow - Jr) / den, axis=(1, 2), initial=0.0)

    def regime_of(self, w, uN):
        """The active regime whose slopes match the tangent at ``(w, u_N)``, or a new one for that tangent
        (entries near an outer-branch slope snapped to it)."""
        if not self.rows:
            return self.base
        Jnow = self.tangent(w, uN)[0]
        if not np.all(np.isfinite(Jnow)):
            return self.regimes[-1] if self.regimes else self.regime(self.J0)
        mis = self.mismatches(Jnow)
        if mis.size and min(mis) <= 1.0:
            return self.regimes[int(np.argmin(mis))]
        if len(self.regimes) >= MAX_REGIMES:
            return self.regimes[int(np.argmin(mis))]
        Jr = Jnow.copy()
        for Jf in self.Jfar:
            near = np.abs(Jr - Jf) <= self.atol
            Jr[near] = Jf[near]
        return self.regime(Jr)

    def regime(self, Jblk):
        key = np.asarray(Jblk, float).tobytes()
        if key not in self.pool:
            self.pool[key] = Regime(self, Jblk, -1)
        return self.activate(self.pool[key])

    def g_base(self, W, UN):
        """``g`` of the base regime at many points (rows: time points)."""
        if not self.rows:
            return np.zeros((W.shape[0], 0))
        if "g_base" not in self.kern.funs:
            w, uN = ca.SX.sym("w", len(self.Nw)), ca.SX.sym("uN", len(self.Nu))
            g = self.kern.g_fun(w, uN, ca.DM(self.base.Jblk), ca.DM(self.mp))[0]
            self.kern.funs["g_base"] = ca.Function("split_g_base", [w, uN], [g])
        f = self.kern.funs["g_base"]
        return np.array(f(W.T, UN.T)).T.reshape(W.shape[0], -1)

    def fine(self, R, hs, n_iter):
        """One dense sub-step of ``R``: ``(δx, w, du, u_N) -> [δx+, w+, res, mismatch]`` (``g`` of the start from
        ``w``): the linear part in numpy, the implicit equation in one CasADi call through buffers."""
        d = R.discretise(hs)
        nN = len(self.Nw)
        Ad, Bd, Ed, fd, Cn, Dn, wc = d["Ad"], d["Bd"], d["Ed"], d["fd"], R.Cn, R.Dn, R.wc
        if not R.E.shape[1]:
            def call(x, w, du, uN):
                return [Ad @ x + Bd @ du + fd, w.copy(), np.zeros(nN), np.zeros(1)]
            return call
        f, (buf, ev) = self.kern.newton_single(n_iter)
        Hf = np.asfortranarray(d["H"])

        def call(x, w, du, uN):
            pred = Ad @ x + Bd @ du + fd
            ins = [np.ascontiguousarray(w, float), wc + Cn @ pred + Dn @ du, np.ascontiguousarray(uN, float), Hf,
                   R.Jblk_f, self.mp]
            outs = [np.zeros(Ed.shape[1]), np.zeros(nN), np.zeros(nN), np.zeros(1)]
            for i, a in enumerate(ins):
                buf.set_arg(i, memoryview(a.reshape(-1, order="F")))
            for i, a in enumerate(outs):
                buf.set_res(i, memoryview(a))
            ev()
            return [pred + Ed @ outs[0], outs[2], outs[1], outs[3]]

        return call



class Regime:
    """One linear part: the Jacobian at the start point with the block (nonlinear rows, nonlinear variables)
    replaced by the regime's slopes ``Jblk``; ``g = F_r(w) - F_r0 - Jblk (w - w0)``."""

    def __init__(self, m, Jblk, index):
        dae = m.dae
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        self.m, self.Jblk, self.index = m, np.asarray(Jblk, float), index
        self.Jblk_f = np.asfortranarray(self.Jblk)
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
        self.aug, self.disc, self.params, self.markovs = {}, {}, {}, {}

    def g_of(self, w, uN):
        if not self.m.rows:
            return np.zeros(0)
        return self.m.kern.g_only(w, uN, self.Jblk, self.m.mp)[0].ravel()

    # ---- linear part ----------------------------------------------------------------------------
    def _modal(self):
        """Real modal basis ``V`` of ``A`` (ordered: the complex pairs as adjacent (real part, imaginary part),
        then the real modes) or None if ``A`` is not safely diagonalisable."""
        n = self.A.shape[0]
        self.V, self.dense, self.cond, self.modal_done = None, True, np.nan, True
        if n == 0:
            return
        lam, W = sla.eig(self.A)
        real = np.abs(lam.imag) <= 1e-12 * np.maximum(np.abs(lam), 1.0)
        up = ~real & (lam.imag > 0)
        if np.count_nonzero(up) != np.count_nonzero(~real & (lam.imag < 0)):
            return
        Wp = W[:, up]
        ri = np.flatnonzero(real)
        ri = ri[np.argsort(-np.abs(lam[ri]), kind="stable")]     # the slowest (rigid-body) modes last
        V = np.hstack([np.stack([Wp.real, Wp.imag], axis=2).reshape(n, -1), W[:, ri].real])
        V /= np.linalg.norm(V, axis=0)
        with np.errstate(divide="ignore"):
            lu = sla.lu_factor(V, check_finite=False)
            rcond, info = sla.lapack.dgecon(lu[0], np.linalg.norm(V, 1), norm="1")
        cond = 1.0 / rcond if info == 0 and rcond > 0 else np.inf
        if not np.isfinite(cond) or cond > _COND_MAX:
            return
        self.V, self.cond, self.dense = V, cond, False
        self.n_real, self.n_pair = int(np.count_nonzero(real)), int(np.count_nonzero(up))
        self.V_lu = lu

    def _expm(self, h):
        """``expm`` of the augmented matrix ``[A B E c; 0] h`` (cached); at ``2^j`` times the fine sub-step, by
        squaring the one at half the step (one ``expm`` per regime for its fine and chunk steps)."""
        key = step_key(h)
        if key in self.aug:
            return self.aug[key]
        ratio = key / self.m.h_fine
        j = int(round(np.log2(ratio))) if ratio > 1.5 else 0
        if j >= 1 and abs(ratio - 2.0 ** j) <= 1e-9 * ratio:
            Eh = self._expm(0.5 * key)
            self.aug[key] = Eh @ Eh
            return self.aug[key]
        nx, nu, r = self.A.shape[0], self.B.shape[1], self.E.shape[1]
        m = nx + nu + r + 1
        Maug = np.zeros((m, m))
        Maug[:nx, :nx] = self.A * h
        Maug[:nx, nx:nx + nu] = self.B * h
        Maug[:nx, nx + nu:nx + nu + r] = self.E * h
        Maug[:nx, -1] = self.c * h
        self.aug[key] = sla.expm(Maug)
        return self.aug[key]

    def discretise(self, h, modal=False):
        """Step matrices for the sub-step ``h`` (cached); with ``modal``, also in modal coordinates."""
        key = step_key(h)
        if modal and not self.modal_done:
            self._modal()
        if key in self.disc and (not modal or self.V is None or "d1" in self.disc[key]):
            return self.disc[key]
        if key in self.disc:
            d = self.disc[key]
            self._modal_matrices(d)
            return d
        nx, nu, r = self.A.shape[0], self.B.shape[1], self.E.shape[1]
        Ex = self._expm(h)
        Ad, Bd, Ed, fd = Ex[:nx, :nx], Ex[:nx, nx:nx + nu], Ex[:nx, nx + nu:nx + nu + r], Ex[:nx, -1]
        H = self.Cn @ Ed + self.Dg
        d = {"H": H, "Ad": np.ascontiguousarray(Ad), "Bd": Bd, "Ed": Ed, "fd": fd}
        if modal and self.V is not None:
            self._modal_matrices(d)
        self.disc[key] = d
        return d

    def _modal_matrices(self, d):
        Ad, Bd, Ed, fd = d["Ad"], d["Bd"], d["Ed"], d["fd"]
        nx = Ad.shape[0]
        V, lu = self.V, self.V_lu
        Am = sla.lu_solve(lu, Ad @ V)
        perm = np.array([i ^ 1 if (i ^ 1) < nx else i for i in range(nx)])
        diag = np.diag(Am).copy()
        off = Am[np.arange(nx), perm].copy()
        off[2 * self.n_pair:] = 0.0
        rest = Am.copy()
        rest[np.arange(nx), np.arange(nx)] = 0.0
        rest[np.arange(2 * self.n_pair), perm[:2 * self.n_pair]] = 0.0
        # the last columns (the slowest modes, where a rigid-body coordinate drifts without bound) are kept
        # whole: a coupling of 1e-8 there, multiplied by the drift, is not round-off (docs/nonlinear.md)
        kb = rigid_block(nx)
        Rc = rest[:, nx - kb:].copy()
        rest[:, nx - kb:] = 0.0
        # the rest of Am is round-off of the similarity transform, unless A was (nearly) defective
        if np.max(np.abs(rest)) > 1e-8 * max(np.max(np.abs(Am)), 1.0):
            self.dense = True  # (nearly) defective A: this regime steps in dense coordinates
        d.update(d1=diag, d2=off, Rc=Rc, Bm=sla.lu_solve(lu, Bd), Em=sla.lu_solve(lu, Ed), fm=sla.lu_solve(lu, fd),
                 Cm=self.Cn @ V)

    def step_params(self, h):
        """The regime inputs of the chunk Function for the sub-step ``h``: ``(matrices (Fortran order), dense)``."""
        key = step_key(h)
        if key not in self.params:
            d = self.discretise(h, modal=True)
            dense = self.dense
            src = dict(d, Jblk=self.Jblk, Cn=self.Cn, Dn=self.Dn, wc=self.wc)
            if dense:
                src.update(Bm=d["Bd"], Em=d["Ed"], fm=d["fd"], Cm=self.Cn)
            mats = [np.asfortranarray(np.asarray(src[name], float).reshape(shape, order="F"))
                    for name, shape in self.m.kern.layout(dense)]
            self.params[key] = (mats, dense)
        return self.params[key]

    def markov(self, h):
        """For the fine batch at sub-step ``h``: ``(Mx, Mb, Mf, T)`` with ``C0 = wc + Dn du + reshape(Mx x0 + Mb du
        + Mf)`` and ``T = [C_N A_d^k E_d]_(k=1..K-1)`` (column-major for the Function)."""
        key = step_key(h)
        if key not in self.markovs:
            d = self.discretise(h)
            K, nN = self.m.kern.K, len(self.m.Nw)
            Ad = d["Ad"]
            Pk = self.Cn.copy()
            S = np.zeros_like(Pk)
            Mx, Ms, Ts = [], [], []
            for k in range(K):
                S = S + Pk           # C_N sum_{i<=k} A_d^i
                Pk = Pk @ Ad         # C_N A_d^(k+1)
                Mx.append(Pk)
                Ms.append(S)
                if k < K - 1:
                    Ts.append(Pk @ d["Ed"])
            Ms = np.vstack(Ms)
            T = np.hstack(Ts) if Ts else np.zeros((nN, 0))
            self.markovs[key] = (np.vstack(Mx), Ms @ d["Bd"], Ms @ d["fd"], np.asfortranarray(T))
        return self.markovs[key]

    def to_coords(self, dx, dense):
        return dx if dense else sla.lu_solve(self.V_lu, dx)

    def from_coords(self, X, dense):
        return X if dense else X @ self.V.T
