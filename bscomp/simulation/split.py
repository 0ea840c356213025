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
on the test bed); the step Functions are shared by all regimes, which enter as inputs
(:class:`~.split_kernels.Kernels`).

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
the nonlinear unknowns only (:meth:`~.split_kernels.Kernels.fine_batch`: the linear part enters through
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
``newton_iter`` (:func:`~.split_regime.split_model`); a repeated run re-activates the cached regimes in the
order it asks for them and so repeats the first run exactly.

Modules
-------
This module is the driver (:func:`simulate_split`: chunks, fine steps, regime changes);
:mod:`bscomp.simulation.split_regime` holds the splitting and the regimes' linear parts,
:mod:`bscomp.simulation.split_kernels` the CasADi step Functions.
"""

from __future__ import annotations

import time

import numpy as np

from bscomp.simulation.common import Progress, SampledLoop, finish
from bscomp.simulation.result import SimulationError
from bscomp.simulation.split_kernels import NEWTON_TOL, REGIME_RTOL, Kernels
from bscomp.simulation.split_regime import FINE, Regime, SplitModel, nonlinear_structure, split_model
from bscomp.simulation.travel import warn_slow_with_moving_nut

__all__ = ["simulate_split", "SplitModel", "Regime", "Kernels", "split_model", "nonlinear_structure", "NEWTON_TOL",
           "REGIME_RTOL", "FINE", "CHUNK", "SETTLE"]

CHUNK = 256          # most output intervals per chunk Function (lengths are powers of two, inputs padded)
SETTLE = 2           # steps without a regime change before chunks are used again


def simulate_split(problem, options):
    """``simulate(method="split")``: the driver of the partitioned exponential integrator (module docstring).

    Inside a regime, chunks of up to ``CHUNK`` steps run in one Function call. A step whose end state has
    another tangent (or whose Newton did not converge) ends the chunk; that step and the next ones are then
    taken one at a time in ``FINE x substeps`` sub-steps, each sub-step redone with the tangent of its end
    state's regime when that differs, until ``SETTLE`` steps pass without a regime change.

    Parameters
    ----------
    problem : SimulationProblem
    options : SimulationOptions
        ``substeps``, ``newton_iter``, ``jit``.

    Returns
    -------
    SimulationResult
        ``stats``: ``regimes``, ``regime_changes``, ``regime_per_step``, ``fine_steps``, ``coordinates``,
        ``nonlinear_variables``, the Newton counters.
    """
    substeps, newton_iter = options.fixed_steps()
    warn_slow_with_moving_nut(problem.dae, "split", stacklevel=4)
    return _SplitRun(problem, substeps, newton_iter, bool(options.jit)).run()


class _SplitRun:
    """One run of the split method: the state histories, the current regime and the stepping policy."""

    def __init__(self, problem, substeps, newton_iter, jit):
        self.problem, self.substeps, self.jit = problem, substeps, jit
        dae, t, U, p, xs = problem.dae, problem.t, problem.U, problem.p, problem.x0
        self.t_wall = time.perf_counter()
        self.dae, self.t, self.p, self.xs = dae, t, p, xs
        nx, nu, nt = dae.nx, dae.nu, len(t)
        self.u0 = u0 = U[:, 0]
        xd0, z0 = dae.initialize(xs, u0, p, store=False)
        self.h_all = np.diff(t)
        self.m = m = split_model(dae, p, xs, xd0, z0, u0, newton_iter, substeps, self.h_all[0])
        self.r, self.nN = len(m.rows), len(m.Nw)
        self.dX = np.zeros((nt, nx))
        self.W = np.zeros((nt, self.nN))
        self.W[0] = m.v0[m.Nw]
        self.Res = np.zeros((nt, self.nN))
        self.Reg = np.zeros(nt, int)
        self.Uh = np.empty((nt, nu))
        self.Uh[0] = u0
        self.Ut = np.ascontiguousarray(U.T)
        self.loop = SampledLoop(dae, problem.controllers, t[0])
        self.n_iter, self.K = m.n_iter, substeps * FINE
        self.n_calls = self.n_fine = self.n_changes = 0
        self.R, self.fine_left, self.grow = m.base, 0, (CHUNK if not self.r else 4)

    # ---- the main loop ------------------------------------------------------------------------
    def run(self):
        t, m, nt, h_keys = self.t, self.m, len(self.t), []
        progress = Progress(self.dae.name, t, self.problem.progress)
        k = 0
        while k < nt - 1:
            h = self.h_all[k]
            if self.loop:
                self.loop.sample(t[k], self.Ut[k].copy(), lambda uk, k=k: self.measure(k, uk))
            t_next = self.loop.next_time
            hk = next((hh for hh in h_keys if abs(hh - h) <= 1e-9 * h), None)
            if hk is None:
                h_keys.append(h)
                hk = h
            n = 1
            if self.fine_left <= 0:
                while (k + n < nt - 1 and n < min(CHUNK, self.grow) and abs(self.h_all[k + n] - h) < 1e-9 * h
                       and t[k + n] + 1e-12 < t_next):
                    n += 1
            Uc = self.loop.hold(self.Ut[k:k + n])
            self.n_calls += 1
            k = self.fine_step(k, hk, Uc[0]) if self.fine_left > 0 else self.chunk(k, n, hk, Uc)
            if self.nN:
                m.max_residual = max(m.max_residual, float(np.max(self.Res[:k + 1][-max(n, 1):])))
            progress.update(self.n_calls, k)
        return self.result()

    def measure(self, k, uk):
        """The controllers' measured outputs at grid point ``k`` (``x'``, ``z`` of the base regime's linear part)."""
        m, base = self.m, self.m.base
        du = uk - self.u0
        g = base.g_of(self.W[k], uk[m.Nu]) if self.r else np.zeros(0)
        xd = base.c + base.A @ self.dX[k] + base.B @ du + base.E @ g
        z = base.zc + base.Zx @ self.dX[k] + base.Zu @ du + base.Zg @ g
        return self.loop.measure(xd, self.xs + self.dX[k], z, uk, self.p)

    def result(self):
        m, base, dX, Uh = self.m, self.m.base, self.dX, self.Uh
        X = self.xs + dX
        dU = Uh - self.u0
        G = m.g_base(self.W, Uh[:, m.Nu])
        XD = base.c + dX @ base.A.T + dU @ base.B.T + G @ base.E.T
        Z = base.zc + dX @ base.Zx.T + dU @ base.Zu.T + G @ base.Zg.T
        coords = ", ".join(("dense" if R_.dense else f"modal (eigenvector condition {R_.cond:.2g})") if R_.modal_done
                           else "fine steps only" for R_ in m.regimes)
        stats = {"method": "split",
                 "scheme": "exponential (exact ZOH) linear part re-linearized per regime of the nonlinear laws, "
                           "implicit held nonlinear correction (order 1)",
                 "step": float(np.min(self.h_all)) / self.substeps, "substeps": self.substeps,
                 "chunk_calls": self.n_calls, "fine_steps": self.n_fine, "regime_changes": self.n_changes,
                 "regimes": len(m.regimes), "regime_per_step": self.Reg, "coordinates": coords,
                 "nonlinear_variables": list(m.names), "nonlinear_rows": self.r,
                 "newton_iterations": self.n_iter, "newton_retries": m.retries,
                 "newton_max_residual": m.max_residual, "jit": self.jit}
        return finish(self.problem, X, XD, Z, Uh, stats, self.t_wall)

    # ---- chunks inside one regime -----------------------------------------------------------------
    def chunk(self, k, n, hk, Uc):
        """Up to ``n`` steps from ``k`` in the current regime in one call, cut at the first step that leaves it
        (a step that only needs more Newton iterations is redone alone); returns the new ``k``."""
        m, R, nx, r, nN = self.m, self.R, self.dae.nx, self.r, self.nN
        L = min(CHUNK, 4 ** max(1, -(-(n - 1).bit_length() // 2)))  # lengths 4, 16, 64, 256 (inputs padded)
        pad = np.r_[np.arange(n), np.full(L - n, n - 1)]
        dU = np.ascontiguousarray(Uc[pad] - self.u0)
        UN = np.ascontiguousarray(Uc[pad][:, m.Nu])
        Xo, Go, Ro, Wo, Mo = np.empty((L, nx)), np.empty((L, r)), np.empty((L, nN)), np.empty((L, nN)), \
            np.empty((L, 1))
        mats, cdense = R.step_params(hk / self.substeps)
        _, (buf, ev) = m.kern.chunk(L, self.substeps, cdense, self.jit)
        g0 = R.g_of(self.W[k], Uc[0][m.Nu])
        # (the arrays must stay alive until ev())
        args = (np.ascontiguousarray(R.to_coords(self.dX[k], cdense)), np.ascontiguousarray(g0), dU, UN, *mats, m.mp)
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
            self.dX[k + 1:k + 1 + j] = R.from_coords(Xo[:j], cdense)
            self.W[k + 1:k + 1 + j], self.Res[k + 1:k + 1 + j], self.Reg[k + 1:k + 1 + j] = Wo[:j], Ro[:j], R.index
            self.Uh[k + 1:k + 1 + j] = Uc[:j]
        retried = j < n and nN and finite[j] and unconverged[j] and Mo[j, 0] <= 1.0 and \
            self.retry_step(R, k + j, hk, Uc[j])  # Newton needed more than n_iter iterations: with up to 5 n_iter
        if not retried and j < n:
            self.fine_left = SETTLE
        else:
            self.grow = 4 * self.grow
        return k + j + retried

    def retry_step(self, R, j, hk, uj):
        """Step ``j -> j + 1`` in ``R`` with the Newton iterations continued while unconverged (numpy linear
        part); stored and True if it converged and stayed in ``R``."""
        m, nN = self.m, self.nN
        du, uN = uj - self.u0, uj[m.Nu]
        x, w = self.dX[j].copy(), self.W[j].copy()
        call = m.fine(R, hk / self.substeps, self.n_iter)
        res_max, mis = np.zeros(nN), 0.0
        for _ in range(self.substeps):
            x, w, res, ms = call(x, w, du, uN)
            res_max, mis = np.maximum(res_max, res), max(mis, float(ms[0]))
        if not (np.isfinite(x).all() and np.max(res_max) <= NEWTON_TOL and mis <= 1.0):
            return False
        self.dX[j + 1], self.W[j + 1], self.Res[j + 1], self.Reg[j + 1], self.Uh[j + 1] = x, w, res_max, R.index, uj
        return True

    # ---- fine steps while a regime change is resolved -------------------------------------------------
    def fine_step(self, k, hk, u):
        """Step ``k -> k + 1`` in ``FINE x substeps`` sub-steps, each in the regime of its end state (the ones
        that stay in the regime in one batch); returns ``k + 1``."""
        m, nN, K = self.m, self.nN, self.K
        du, uN = u - self.u0, u[m.Nu]
        hs = hk / (self.substeps * FINE)
        x, w = self.dX[k].copy(), self.W[k].copy()
        res_max = np.zeros(nN)
        changes0 = self.n_changes
        j = 0
        while j < K:
            if nN:  # the sub-steps that stay in R, in one call; the first that leaves it one at a time
                b, x, w, res = self.batch(self.R, x, w, hs, du, uN, K - j)
                res_max = np.maximum(res_max, res)
                j += b
                if j == K:
                    break
            x, w, res, self.R = self.advance(self.R, x, w, hs, du, uN, 0, k)
            res_max = np.maximum(res_max, res)
            j += 1
        changed = self.n_changes > changes0
        self.dX[k + 1], self.W[k + 1], self.Res[k + 1], self.Reg[k + 1] = x, w, res_max, self.R.index
        self.Uh[k + 1] = u
        self.n_fine += 1
        self.fine_left = SETTLE if changed else self.fine_left - 1
        self.grow = 4
        return k + 1

    def batch(self, R, x, w, hs, du, uN, n):
        """Up to ``n`` dense sub-steps of ``R`` from ``(x, w)`` in one call (:meth:`Kernels.fine_batch`), cut
        before the first that leaves ``R`` or whose Newton did not converge: ``(count, x, w, res)``."""
        m, r, nN = self.m, self.r, self.nN
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

    def advance(self, R, x, w, hs, du, uN, depth, k):
        """A sub-step from ``(x, w)`` in regime ``R``, redone in the regime of its end state if that differs;
        if Newton fails, in the start state's regime, then as two half sub-steps (at most 3 levels)."""
        m = self.m
        out, ok = self.sub(R, x, w, hs, du, uN)
        if ok and out[3][0] > 1.0:
            R2 = m.regime_of(out[1], uN)
            if R2 is not R:
                self.n_changes += 1
                out2, ok2 = self.sub(R2, x, w, hs, du, uN)
                if ok2:
                    out, R = out2, R2
                    if out[3][0] > 1.0:
                        R = m.regime_of(out[1], uN)
        for w_try in ((out[1], w) if not ok else ()):  # the regime of the last iterate, then of the start
            R2 = m.regime_of(w_try, uN) if np.isfinite(w_try).all() else R
            if R2 is not R:
                out2, ok2 = self.sub(R2, x, w, hs, du, uN)
                if ok2:
                    out, R, ok = out2, R2, True
                    self.n_changes += 1
                    break
        if not ok:
            if depth < 3:
                x1, w1, r1, R = self.advance(R, x, w, hs / 2, du, uN, depth + 1, k)
                x2, w2, r2, R = self.advance(R, x1, w1, hs / 2, du, uN, depth + 1, k)
                return x2, w2, np.maximum(r1, r2), R
            self.fail(k + 1, self.newton_message(out[2]) if np.isfinite(out[0]).all() else
                      "the state became non-finite")
        return out[0], out[1], out[2], R

    def sub(self, Rg, x, w, hs, du, uN):
        """One dense sub-step in regime ``Rg`` (retried with 4x the Newton iterations): ``(out, ok)``."""
        for its in (self.n_iter, 4 * self.n_iter):
            out = self.m.fine(Rg, hs, its)(x, w, du, uN)
            ok = np.isfinite(out[0]).all() and (not self.nN or np.max(out[2]) <= NEWTON_TOL)
            if ok:
                break
            self.m.retries += 1
        return out, ok

    # ---- failure ----------------------------------------------------------------------------------
    def newton_message(self, res):
        var = self.m.names[int(np.nanargmax(np.where(np.isfinite(res), res, np.inf)))]
        return f"Newton did not converge for the nonlinear variable '{var}' (scaled residual " \
               f"{np.nanmax(res):.2g} > {NEWTON_TOL:g})"

    def fail(self, j, what):
        t = self.t
        raise SimulationError(
            f"split step on '{self.dae.name}': {what} between t = {t[j - 1]:.6g} s and t = {t[j]:.6g} s. Hints: "
            f"more substeps (now {self.substeps}) or newton_iter (now {self.n_iter}, retried with {4 * self.n_iter}); "
            "a law much stiffer than the step resolves (friction v_reg, contact stiffness) may need method='idas'")
