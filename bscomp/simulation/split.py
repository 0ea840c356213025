"""Partitioned exponential integration of the implicit DAE: exact zero-order hold for the linear part, an
implicit step for the few nonlinear force laws (friction, backlash). Used by
:func:`bscomp.simulation.simulate` with ``method="split"``.

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
about ``dJ H / 2`` per step). Every regime has its own linear part and discretisation (cached; a handful
on the test bed); the step Functions are shared by all regimes, which enter as inputs (:class:`_Kernels`).

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

so each step is a Newton solve of ``w - c_k - H g(w) = 0`` in the few nonlinear unknowns, then one state
update. In chunks and fine batches the Newton is undamped (the laws evaluated once per iteration, the linear
solve in the ``r`` nonlinear rows: ``(I - H G)^-1 = I + H (I - G H)^-1 G``); a step it leaves unconverged is
redone with the damped iteration (backtracking line search on the residual scaled to force units). The
scheme is exact for the linear structure (any step, any stiffness), first order in the nonlinear force
(exact while ``g`` is constant: sliding, contact), and for passive laws unconditionally stable (implicit
Euler on ``g``).

Regime changes: a chunk of steps runs in one regime; the first step whose end state lies in another
regime (or whose Newton failed) ends it (a step that only needs more Newton iterations is redone alone with
up to ``5 n_iter`` and the chunks go on). That step and the following ones are taken one at a time in
``FINE x substeps`` dense sub-steps, each redone with the tangent of its end state's regime when that
differs (if Newton fails: in the regime of its last iterate or start, then as two half sub-steps), until
``SETTLE`` steps pass without a change. The sub-steps that stay in the regime are computed in one call in
the nonlinear unknowns only (:meth:`_Kernels.fine_batch`: the linear part enters through
``C_N A_d^k x_0`` and the impulse responses ``C_N A_d^k E_d``, the state is updated afterwards in numpy);
the first sub-step that leaves it is redone one at a time as above.

The state is carried in real modal coordinates of ``A`` (``δx = V ξ``; complex pairs as adjacent 2x2
rotation blocks), so a step is a few vector operations of length ``n`` and products with the thin
matrices ``V^{-1}B_d``, ``V^{-1}E_d``, ``C_N V``; if ``A`` is not safely diagonalisable (a Jordan block,
e.g. an undamped rigid-body mode), a dense ``A_d`` is used instead (per regime; the basis is computed only
for regimes that run chunks; its condition is the LAPACK 1-norm estimate). Chunks of 4, 16, 64 or 256 steps
are one CasADi Function each (four calls of the next shorter one, down to one step Function with the
regime's matrices as inputs; built once), called through zero-copy buffers: no per-step Python inside a
regime. Fine batches are built for 1, 2, 4, 8 and 16 sub-steps and sized to the sub-steps that remain.
One ``expm`` per regime (at the fine sub-step; the chunk step by squaring). Set-up cost: the Functions,
the regimes' ``expm`` / ``eig`` and their matrices are cached on ``dae._cache`` per start point, step and
``newton_iter`` (:func:`split_model`); a repeated run re-activates the cached regimes in the order it asks
for them and so repeats the first run exactly.
"""

from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.simulation.dispatch import (
    SimulationError,
    SimulationResult,
    _evaluate_outputs,
    _held_inputs,
    _progress_bar,
    _sample_controllers,
)

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


class _Numeric:
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


def _key(h):
    """Cache key of a step length (robust to the last bits of ``h / 2^j``)."""
    return float(f"{float(h):.12e}")


def split_model(dae, p, xs, xd0, z0, u0, newton_iter, substeps, h):
    """The :class:`SplitModel` for this start point and step, cached on ``dae._cache`` (its regimes, their
    discretisations and modal bases are reused by a later run from the same start; a few kept)."""
    parts = [np.asarray(a, float).tobytes() for a in (p, xs, xd0, z0, u0)]
    key = ("split_model", *parts, int(newton_iter), int(substeps), _key(h))
    models = dae._cache.setdefault("split_models", {})
    if key not in models:
        if len(models) >= 4:
            models.pop(next(iter(models)))
        models[key] = SplitModel(dae, p, xs, xd0, z0, u0, newton_iter, substeps, h)
    m = models[key]
    m.reset()
    return m


class SplitModel:
    """The splitting of one Dae at one start point: the nonlinear map and the regimes (one linear part per
    tangent of the nonlinear laws, with its discretisations); the step Functions are shared (:class:`_Kernels`)."""

    def __init__(self, dae, p, xs, xd0, z0, u0, newton_iter, substeps, h):
        from bscomp.kernel.dae import _sp

        self.dae, self.p = dae, np.asarray(p, float)
        nx, nz = dae.nx, dae.nz
        self.N, self.rows = nonlinear_structure(dae)
        nv = 2 * nx + nz
        self.Nw = [i for i in self.N if i < nv]          # unknowns of the Newton solve
        self.Nu = [i - nv for i in self.N if i >= nv]    # nonlinear inputs (known per step)
        names = [f"der({n})" for n in dae.x_names] + list(dae.x_names) + list(dae.z_names)
        self.names = [names[i] for i in self.Nw]
        self.n_iter, self.substeps = int(newton_iter), int(substeps)
        self.h_coarse, self.h_fine = _key(h / self.substeps), _key(h / (self.substeps * FINE))
        self.v0 = np.concatenate([xd0, xs, z0, u0])
        self.xs, self.u0 = np.asarray(xs, float), np.asarray(u0, float)
        self.xd0, self.z0 = np.asarray(xd0, float), np.asarray(z0, float)
        F0, Jxd, Jx, Jz, Ju = dae.jacobians(xd0, xs, z0, u0, p)
        self.F0 = np.asarray(F0, float).reshape(-1, 1)
        self.J = sp.hstack([_sp(Jxd), _sp(Jx), _sp(Jz), _sp(Ju)]).tolil()
        self.regimes, self.pool, self.retries, self.max_residual = [], {}, 0, 0.0
        r = len(self.rows)
        self.iw = [self.N.index(i) for i in self.Nw]            # columns of the Newton unknowns in the block
        if not r:
            self.J0 = np.zeros((0, len(self.N)))
            self.kern = _Kernels(dae, self.N, self.rows, self.n_iter, self.substeps * FINE,
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
        self.tangent = _Numeric(ca.Function("split_tangent", [w, uN], [Jw]))
        # a slope error dJ costs ~ dJ H / 2 relative per step (H = dw/dg over a step): the floor of the regime
        # test is also REGIME_COUPLING / |H|, H of the softest branches (largest response)
        cand = np.stack([self.J0] + self.Jfar)
        Jsoft = np.take_along_axis(cand, np.argmin(np.abs(cand), axis=0)[None], axis=0)[0]
        H = _Regime(self, Jsoft, -1).discretise(self.h_coarse)["H"]
        Hw = np.zeros_like(self.J0)
        Hw[:, self.iw] = np.abs(H.T)
        with np.errstate(divide="ignore"):
            self.atol = np.minimum(self.atol, np.where(Hw > 0, REGIME_COUPLING / Hw, np.inf))
        self.kern = _Kernels(dae, self.N, self.rows, self.n_iter, self.substeps * FINE, np.concatenate(
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
            self.pool[key] = _Regime(self, Jblk, -1)
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


class _Kernels:
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
        self.g_only = _Numeric(ca.Function("split_g_only", [self.w, self.uN, self.Jblk, self.mp], [ca.densify(g)]))
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
        lin = [("Ad", (nx, nx))] if dense else [("d1", (nx, 1)), ("d2", (nx, 1))]
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
            lin = ca.mtimes(q["Ad"], xc) if dense else q["d1"] * xc + q["d2"] * xc[perm]
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
            from bscomp.simulation.fixed_step import compiled

            f = compiled(f)
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


class _Regime:
    """One linear part: the Jacobian at the start point with the block (nonlinear rows, nonlinear variables)
    replaced by the regime's slopes ``Jblk``; ``g = F_r(w) - F_r0 - Jblk (w - w0)``."""

    def __init__(self, m, Jblk, index):
        from bscomp.linear.linearize import explicit_form

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
        V = np.hstack([np.stack([Wp.real, Wp.imag], axis=2).reshape(n, -1), W[:, real].real])
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
        key = _key(h)
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
        key = _key(h)
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
        # the rest of Am is round-off of the similarity transform, unless A was (nearly) defective
        rest = Am.copy()
        rest[np.arange(nx), np.arange(nx)] = 0.0
        rest[np.arange(2 * self.n_pair), perm[:2 * self.n_pair]] = 0.0
        if np.max(np.abs(rest)) > 1e-8 * max(np.max(np.abs(Am)), 1.0):
            self.dense = True  # (nearly) defective A: this regime steps in dense coordinates
        d.update(d1=diag, d2=off, Bm=sla.lu_solve(lu, Bd), Em=sla.lu_solve(lu, Ed), fm=sla.lu_solve(lu, fd),
                 Cm=self.Cn @ V)

    def step_params(self, h):
        """The regime inputs of the chunk Function for the sub-step ``h``: ``(matrices (Fortran order), dense)``."""
        key = _key(h)
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
        key = _key(h)
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


def simulate_split(dae, t, U, xs, p, outputs, controllers, substeps, newton_iter, progress, jit):
    """Driver of ``simulate(method="split")`` (arguments as :func:`bscomp.simulation.dispatch._simulate_fixed`).

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
    m = split_model(dae, p, xs, xd0, z0, u0, newton_iter, substeps, h_all[0])
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
            out = m.fine(Rg, hs, its)(x, w, du, uN)
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

    K = substeps * FINE

    def batch(R, x, w, hs, du, uN, n):
        """Up to ``n`` dense sub-steps of ``R`` from ``(x, w)`` in one call (:meth:`_Kernels.fine_batch`), cut
        before the first that leaves ``R`` or whose Newton did not converge: ``(count, x, w, res)``."""
        Mx, Mb, Mf, T = R.markov(hs)
        d = R.discretise(hs)
        Kb = m.kern.batch_size(n)
        Mx, Mb, Mf, T = Mx[:Kb * nN], Mb[:Kb * nN], Mf[:Kb * nN], T[:, :r * (Kb - 1)]
        C0 = np.asfortranarray(((Mx @ x + Mb @ du + Mf).reshape(Kb, nN) + (R.wc + R.Dn @ du)).T)
        f, (buf, ev) = m.kern.fine_batch(Kb)
        Wb, Gb, Rb, Mb_ = np.empty((Kb, nN)), np.empty((Kb, r)), np.empty((Kb, nN)), np.empty((Kb, 1))
        ins = (C0, np.asfortranarray(T), np.ascontiguousarray(w, float), np.ascontiguousarray(uN, float),
               np.asfortranarray(d["H"]), R.Jblk_f, m.mp)
        for i, a in enumerate(ins):
            buf.set_arg(i, memoryview(a.reshape(-1, order="F")))
        for i, a in enumerate((Wb, Gb, Rb, Mb_)):
            buf.set_res(i, memoryview(a.reshape(-1)))
        ev()
        bad = ~(np.isfinite(Wb[:n]).all(axis=1) & np.isfinite(Gb[:n]).all(axis=1)
                & (np.max(Rb[:n], axis=1) <= NEWTON_TOL) & (Mb_[:n, 0] <= 1.0))
        b = int(np.argmax(bad)) if bad.any() else n
        if not b:
            return 0, x, w, np.zeros(nN)
        q = d["Bd"] @ du + d["fd"]
        Ad, Ed = d["Ad"], d["Ed"]
        for i in range(b):
            x = Ad @ x + q + Ed @ Gb[i]
        return b, x, Wb[b - 1].copy(), np.max(Rb[:b], axis=0)

    def retry_step(R, j, hk, uj):
        """Step ``j -> j + 1`` in ``R`` with the Newton iterations continued while unconverged (numpy linear
        part); stored and True if it converged and stayed in ``R``."""
        du, uN = uj - u0, uj[m.Nu]
        x, w = dX[j].copy(), W[j].copy()
        call = m.fine(R, hk / substeps, n_iter)
        res_max, mis = np.zeros(nN), 0.0
        for _ in range(substeps):
            x, w, res, ms = call(x, w, du, uN)
            res_max, mis = np.maximum(res_max, res), max(mis, float(ms[0]))
        if not (np.isfinite(x).all() and np.max(res_max) <= NEWTON_TOL and mis <= 1.0):
            return False
        dX[j + 1], W[j + 1], Res[j + 1], Reg[j + 1], Uh[j + 1] = x, w, res_max, R.index, uj
        return True

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
        Uc = _held_inputs(dae, Ut[k:k + n], controllers, ctrl_u)
        n_calls += 1
        if fine_left > 0:
            # ---- one step in FINE x substeps sub-steps, each in the regime of its end state ----
            du, uN = Uc[0] - u0, Uc[0][m.Nu]
            hs = hk / (substeps * FINE)
            x, w = dX[k].copy(), W[k].copy()
            res_max = np.zeros(nN)
            changes0 = n_changes
            j = 0
            while j < K:
                if nN:  # the sub-steps that stay in R, in one call; the first that leaves it one at a time
                    b, x, w, res = batch(R, x, w, hs, du, uN, K - j)
                    res_max = np.maximum(res_max, res)
                    j += b
                    if j == K:
                        break
                x, w, res, R = advance(R, x, w, hs, du, uN, 0, k)
                res_max = np.maximum(res_max, res)
                j += 1
            changed = n_changes > changes0
            dX[k + 1], W[k + 1], Res[k + 1], Reg[k + 1] = x, w, res_max, R.index
            Uh[k + 1] = Uc[0]
            n_fine += 1
            fine_left = SETTLE if changed else fine_left - 1
            grow = 4
            k += 1
        else:
            # ---- a chunk of up to n steps in regime R, cut at the first step that leaves it ----
            L = min(CHUNK, 4 ** max(1, -(-(n - 1).bit_length() // 2)))  # lengths 4, 16, 64, 256 (inputs padded)
            pad = np.r_[np.arange(n), np.full(L - n, n - 1)]
            dU = np.ascontiguousarray(Uc[pad] - u0)
            UN = np.ascontiguousarray(Uc[pad][:, m.Nu])
            Xo, Go, Ro, Wo, Mo = np.empty((L, nx)), np.empty((L, r)), np.empty((L, nN)), np.empty((L, nN)), \
                np.empty((L, 1))
            mats, cdense = R.step_params(hk / substeps)
            _, (buf, ev) = m.kern.chunk(L, substeps, cdense, jit)
            g0 = R.g_of(W[k], Uc[0][m.Nu])
            # (the arrays must stay alive until ev())
            args = (np.ascontiguousarray(R.to_coords(dX[k], cdense)), np.ascontiguousarray(g0), dU, UN, *mats, m.mp)
            for i, a in enumerate(args):
                buf.set_arg(i, memoryview(a.reshape(-1, order="A")))
            for i, a in enumerate((Xo, Go, Ro, Wo, Mo)):
                buf.set_res(i, memoryview(a.reshape(-1)))
            ev()
            finite = np.isfinite(Xo[:n]).all(axis=1)
            bad = ~finite
            if nN:
                unconverged = ~(np.max(Ro[:n], axis=1) <= NEWTON_TOL)
                bad |= unconverged | (Mo[:n, 0] > 1.0)
            j = int(np.argmax(bad)) if bad.any() else n
            if j:
                dX[k + 1:k + 1 + j] = R.from_coords(Xo[:j], cdense)
                W[k + 1:k + 1 + j], Res[k + 1:k + 1 + j], Reg[k + 1:k + 1 + j] = Wo[:j], Ro[:j], R.index
                Uh[k + 1:k + 1 + j] = Uc[:j]
            retried = j < n and nN and finite[j] and unconverged[j] and Mo[j, 0] <= 1.0 and \
                retry_step(R, k + j, hk, Uc[j])  # Newton needed more than n_iter iterations: with up to 5 n_iter
            k += j + retried
            if not retried and j < n:
                fine_left = SETTLE
            else:
                grow = 4 * grow
        if nN:
            m.max_residual = max(m.max_residual, float(np.max(Res[:k + 1][-max(n, 1):])))
        if progress and (n_calls % 20 == 0 or k == nt - 1):
            _progress_bar(dae.name, k / (nt - 1), t[k])
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
