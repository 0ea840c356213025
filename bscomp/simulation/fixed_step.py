"""Fixed-step L-stable SDIRK integration of the implicit DAE, compiled into CasADi chunks.

Used by :func:`bscomp.simulation.simulate` with ``method="fixed"`` (:func:`simulate_fixed`). The scheme is
Alexander's 3-stage, order 3, stiffly accurate and L-stable singly diagonally implicit Runge–Kutta method
(SDIRK3). On the implicit DAE ``F(x', x, z, u, p) = 0`` stage ``i`` solves

.. math:: F\\Big(K_i,\\; x_n + h \\sum_{j<i} a_{ij} K_j + h\\gamma K_i,\\; Z_i,\\; u_n,\\; p\\Big) = 0

for the stage derivative ``K_i`` and algebraic ``Z_i``; the last stage gives ``x_{n+1}`` and, since
the method is stiffly accurate, consistent ``x'_{n+1} = K_3`` and ``z_{n+1} = Z_3`` (accelerations
are solved for, not differenced). L-stability damps modes far above ``1/h`` at once instead of
letting them ring, which is what a square wave into a lightly damped structure needs.

Every stage has the same Newton matrix ``W = [dF/dx' + h γ dF/dx, dF/dz]``. It is built and inverted
once per step size at the start point; equations whose Jacobian depends on the solution or the inputs
(friction, backlash, ...) are corrected exactly at every iteration by the Woodbury identity
(a small ``r x r`` solve, ``r`` = number of such equations), so Newton is exact Newton at the cost
of one dense product with ``W⁻¹`` per iteration. For an affine DAE one iteration is exact.

Chunks of steps are one CasADi Function each, called through zero-copy buffers, so there is no
per-step Python; sampled controllers split the run into chunks between their sample instants.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from bscomp.simulation.common import Progress, SampledLoop, finish
from bscomp.simulation.native import native_function
from bscomp.simulation.result import SimulationError
from bscomp.simulation.travel import warn_slow_with_moving_nut

__all__ = ["simulate_fixed", "Stepper", "chunk_function", "nonlinear_rows"]

GAMMA = 0.43586652150845899941601945
_B1 = -(6 * GAMMA ** 2 - 16 * GAMMA + 1) / 4
_B2 = (6 * GAMMA ** 2 - 20 * GAMMA + 5) / 4
SDIRK3 = np.array([[GAMMA, 0.0, 0.0], [(1 - GAMMA) / 2, GAMMA, 0.0], [_B1, _B2, GAMMA]])

CHUNK = 250          # output intervals per chunk Function
NEWTON_TOL = 1e-4    # largest accepted last Newton update, relative to 1 + |unknown| (quadratic: error ~ its square)
_SX_MAX = 40         # expand the step to SX (fast scalar virtual machine) up to this many unknowns


def nonlinear_rows(dae):
    """Rows of F whose Jacobian w.r.t. (x', x, z) depends on (x', x, z, u): the ones Newton must refresh."""
    key = "fixed_nonlinear_rows"
    if key not in dae._cache:
        xd, x, z, u, p = dae._mx()
        res = dae.F(xd, x, z, u, p)
        w = ca.vertcat(xd, x, z)
        J = ca.jacobian(res, w)
        rows, _ = J.sparsity().get_triplet()
        if J.nnz():
            dep = ca.which_depends(J.nz[:], ca.vertcat(w, u), 1, True)
            nl = sorted({int(rows[i]) for i, d in enumerate(dep) if d})
        else:
            nl = []
        dae._cache[key] = nl
    return dae._cache[key]


def _step_function(dae, nl, n_iter, substeps, line_search, sym=ca.MX):
    """One output interval: ``substeps`` SDIRK3 steps of size h, each stage solved by ``n_iter`` Newton steps.

    Inputs (x, v, u, p, h, Wi, G, W0r, rscale); outputs (x_next, v_next = [K_3; Z_3], newton measure), where the
    measure is the largest last Newton update relative to ``1 + |v|`` (0 when one iteration is exact).
    ``sym=ca.SX`` builds it as scalar expressions (small models: fast virtual machine, compilable).
    """
    nx, nz, nu = dae.nx, dae.nz, dae.nu
    m, r = nx + nz, len(nl)
    x = sym.sym("x", nx)
    v = sym.sym("v", m)
    u = sym.sym("u", nu)
    p = sym.sym("p", dae.np)
    h = sym.sym("h")
    Wi = sym.sym("Wi", m, m)
    G = sym.sym("G", m, r)
    W0r = sym.sym("W0r", r, m)
    if r:
        vs = sym.sym("vs", m)
        bs = sym.sym("bs", nx)
        Rr = dae.F(vs[:nx], bs + h * GAMMA * vs[:nx], vs[nx:], u, p)[nl]
        jac_r = ca.Function("jac_r", [vs, bs, u, p, h], [ca.jacobian(Rr, vs)])
    # row scaling of the line-search merit: residual / (row norm of W) has the units of the unknowns
    rscale = sym.sym("rscale", m) if r else None
    meas = sym(0)
    xc, vc = x, v
    for _ in range(substeps):
        K = []
        for i in range(3):
            base = xc
            for j in range(i):
                base = base + h * SDIRK3[i, j] * K[j]
            for _ in range(n_iter):
                R = dae.F(vc[:nx], base + h * GAMMA * vc[:nx], vc[nx:], u, p)
                s = ca.mtimes(Wi, R)
                if r:
                    D = jac_r(vc, base, u, p, h) - W0r
                    s = s - ca.mtimes(G, ca.solve(ca.DM.eye(r) + ca.mtimes(D, G), ca.mtimes(D, s)))
                    if line_search:
                        s = _line_search(dae, vc, s, base, u, p, h, rscale)
                vc = vc - s
            if n_iter > 1:
                meas = ca.fmax(meas, ca.mmax(ca.fabs(s) / (1 + ca.fabs(vc))))
            K.append(vc[:nx])
        xc = base + h * GAMMA * vc[:nx]
    if not r:
        rscale = sym.sym("rscale", 0)
    return ca.Function("sdirk3_step", [x, v, u, p, h, Wi, G, W0r, rscale], [xc, vc, meas])


def _line_search(dae, v, s, base, u, p, h, rscale, alphas=(1.0, 0.5, 0.25, 0.125, 0.0625)):
    """The Newton step ``alpha * s`` with the smallest scaled residual among ``alphas`` (tried all at once).

    Saturating laws (regularised friction ``tanh(v / v_reg)``) make a full Newton step from the sliding
    branch overshoot across the steep region; backtracking on the residual keeps the iteration inside it.
    """
    nx = dae.nx
    best_step, best = None, None
    for a in alphas:
        w = v - a * s
        phi = ca.sumsqr(dae.F(w[:nx], base + h * GAMMA * w[:nx], w[nx:], u, p) * rscale)
        if best is None:
            best_step, best = a * s, phi
        else:
            better = phi < best
            best_step = ca.if_else(better, a * s, best_step)
            best = ca.if_else(better, phi, best)
    return best_step


def chunk_function(dae, n, n_iter, substeps, jit=False, line_search=False):
    """``n`` output intervals in one Function ``(x0, v0, U[nu x n], p, h, Wi, G, W0r, rscale) -> (X, V, E)``."""
    nl = nonlinear_rows(dae)
    cache = dae._cache.setdefault("fixed_chunks", {})
    key = (n, n_iter, substeps, jit, line_search)
    if key not in cache:
        skey = ("step", n_iter, substeps, line_search)
        if skey not in cache:
            cache[skey] = _step_function(dae, nl, n_iter, substeps, line_search,
                                         ca.SX if dae.nx + dae.nz <= _SX_MAX else ca.MX)
        step = cache[skey]
        m, r = dae.nx + dae.nz, len(nl)
        x = ca.MX.sym("x", dae.nx)
        v = ca.MX.sym("v", m)
        U = ca.MX.sym("U", dae.nu, n)
        p = ca.MX.sym("p", dae.np)
        h = ca.MX.sym("h")
        Wi = ca.MX.sym("Wi", m, m)
        G = ca.MX.sym("G", m, r)
        W0r = ca.MX.sym("W0r", r, m)
        rs = ca.MX.sym("rscale", m if r else 0)
        xs, vs, es = [], [], []
        xc, vc = x, v
        for k in range(n):
            xc, vc, e = step(xc, vc, U[:, k], p, h, Wi, G, W0r, rs)
            xs.append(xc)
            vs.append(vc)
            es.append(e)
        f = ca.Function("sdirk3_chunk", [x, v, U, p, h, Wi, G, W0r, rs], [ca.horzcat(*xs), ca.horzcat(*vs),
                                                                          ca.horzcat(*es)])
        cache[key] = native_function(f) if jit else f
    return cache[key]


class Stepper:
    """Calls chunk Functions through zero-copy buffers on the caller's arrays."""

    def __init__(self, dae, p, x_lin, xd_lin, z_lin, u_lin, n_iter, substeps, jit=False):
        self.dae, self.p = dae, np.ascontiguousarray(p, float)
        self.nl = nonlinear_rows(dae)
        self.n_iter = 1 if not self.nl else n_iter
        self.substeps = substeps
        self.jit = jit
        self.lin = (xd_lin, x_lin, z_lin, u_lin)
        self.mats = {}
        self.buffers = {}
        self.max_newton = 0.0
        self.retries = 0

    def matrices(self, h):
        """(h, W⁻¹, G, W0r, rscale) for the sub-step ``h`` (Newton matrix at the start point)."""
        key = float(h)
        if key not in self.mats:
            dae = self.dae
            _, Jxd, Jx, Jz, _ = dae.jacobians(*self.lin, self.p)
            W = np.hstack([np.array(ca.densify(Jxd + h * GAMMA * Jx)), np.array(ca.densify(Jz))])
            Wi = np.linalg.inv(W)
            r = len(self.nl)
            G = np.ascontiguousarray(Wi[:, self.nl]) if r else np.zeros((dae.nx + dae.nz, 0))
            W0r = np.ascontiguousarray(W[self.nl, :]) if r else np.zeros((0, dae.nx + dae.nz))
            # CasADi is column-major: pass transposed C arrays
            rscale = 1.0 / np.maximum(np.max(np.abs(W), axis=1), 1e-300) if r else np.zeros(0)
            self.mats[key] = (np.array([h]), np.ascontiguousarray(Wi.T), np.ascontiguousarray(G.T),
                              np.ascontiguousarray(W0r.T), rscale)
        return self.mats[key]

    def run(self, n, h_out, x0, v0, Ut, X, V, E):
        """Advance ``n`` output intervals of length ``h_out``; writes rows of X (n, nx), V (n, m), E (n,).

        A chunk in which Newton has not converged (E > NEWTON_TOL, typically a friction stick/slip switch)
        is redone once with four times the iterations and a backtracking line search; the caller checks E.
        """
        x0, v0 = np.array(x0), np.array(v0)  # the rows may be overwritten by a first attempt
        self._run(n, self.n_iter, False, h_out, x0, v0, Ut, X, V, E)
        if self.nl and E.size and not np.max(E) <= NEWTON_TOL:
            self.retries += 1
            self._run(n, 4 * self.n_iter, True, h_out, x0, v0, Ut, X, V, E)
        if E.size:
            self.max_newton = max(self.max_newton, float(np.max(E)))

    def _run(self, n, n_iter, line_search, h_out, x0, v0, Ut, X, V, E):
        key = (n, n_iter, line_search)
        if key not in self.buffers:
            self.buffers[key] = chunk_function(self.dae, n, n_iter, self.substeps, self.jit, line_search).buffer()
        buf, ev = self.buffers[key]
        args = [np.ascontiguousarray(x0), np.ascontiguousarray(v0), np.ascontiguousarray(Ut), self.p,
                *self.matrices(h_out / self.substeps)]
        for i, a in enumerate(args):
            buf.set_arg(i, memoryview(a.reshape(-1)))
        for i, a in enumerate((X, V, E)):
            buf.set_res(i, memoryview(a.reshape(-1)))
        ev()


def simulate_fixed(problem, options):
    """``simulate(method="fixed")``: fixed-step SDIRK3 on the nonlinear DAE, ``substeps`` steps per output
    interval, chunks of up to ``CHUNK`` intervals per call (cut at sampled-controller instants).

    Parameters
    ----------
    problem : SimulationProblem
    options : SimulationOptions
        ``substeps``, ``newton_iter`` (per stage, when the model has nonlinear equations), ``jit``.

    Returns
    -------
    SimulationResult
        ``stats``: ``scheme``, ``step``, ``chunk_calls``, ``newton_iterations``, ``nonlinear_equations``,
        ``newton_max_update``, ``newton_retries``, ``jit``.
    """
    substeps, newton_iter = options.fixed_steps()
    warn_slow_with_moving_nut(problem.dae, "fixed", stacklevel=4)
    jit = bool(options.jit)
    dae, t, U, p, xs = problem.dae, problem.t, problem.U, problem.p, problem.x0
    t_wall = time.perf_counter()
    nx, nz, nu, nt = dae.nx, dae.nz, dae.nu, len(t)
    xd0, z0 = dae.initialize(xs, U[:, 0], p, store=False)
    X = np.empty((nt, nx))
    V = np.empty((nt, nx + nz))  # [x', z]
    E = np.zeros(nt)
    Uh = np.empty((nt, nu))
    X[0], V[0], Uh[0] = xs, np.concatenate([xd0, z0]), U[:, 0]
    Ut = np.ascontiguousarray(U.T)
    stepper = Stepper(dae, p, xs, xd0, z0, U[:, 0], newton_iter, substeps, jit)
    h_all = np.diff(t)
    loop = SampledLoop(dae, problem.controllers, t[0])
    progress = Progress(dae.name, t, problem.progress)
    n_calls, k = 0, 0
    while k < nt - 1:
        h = h_all[k]
        if loop:
            loop.sample(t[k], Ut[k].copy(), lambda uk, k=k: loop.measure(V[k, :nx], X[k], V[k, nx:], uk, p))
        t_next = loop.next_time
        n = 1
        while (k + n < nt - 1 and n < CHUNK and abs(h_all[k + n] - h) < 1e-9 * h
               and t[k + n] + 1e-12 < t_next):
            n += 1
        Uc = loop.hold(Ut[k:k + n])
        stepper.run(n, h, X[k], V[k], Uc, X[k + 1:k + 1 + n], V[k + 1:k + 1 + n], E[k + 1:k + 1 + n])
        Uh[k + 1:k + 1 + n] = Uc
        n_calls += 1
        if not (np.isfinite(X[k + n]).all() and np.max(E[k + 1:k + 1 + n]) <= NEWTON_TOL):  # NaN propagates
            _failure(dae, t, X, E, k, n, substeps, stepper)
        k += n
        progress.update(n_calls, k)
    stats = {"method": "fixed", "scheme": "SDIRK3 (L-stable, order 3)", "step": float(np.min(h_all)) / substeps,
             "chunk_calls": n_calls, "newton_iterations": stepper.n_iter, "nonlinear_equations": len(stepper.nl),
             "newton_max_update": stepper.max_newton, "newton_retries": stepper.retries, "jit": jit}
    return finish(problem, X, V[:, :nx], V[:, nx:], Uh, stats, t_wall)


def _failure(dae, t, X, E, k, n, substeps, stepper):
    """Raise SimulationError for the first failed interval of the chunk ``k .. k + n``."""
    tol = NEWTON_TOL
    bad = ~np.isfinite(X[k + 1:k + 1 + n]).all(axis=0)
    Ec = E[k + 1:k + 1 + n]
    j = k + 1 + int(np.argmax(~np.isfinite(X[k + 1:k + 1 + n]).all(axis=1) | ~(Ec <= tol)))
    what = (f"state '{dae.x_names[int(np.argmax(bad))]}' became non-finite" if bad.any() else
            f"Newton did not converge (last update {E[j]:.2g} of the unknowns' size)")
    raise SimulationError(
        f"fixed-step SDIRK3 on '{dae.name}': {what} between t = {t[j - 1]:.6g} s and t = {t[j]:.6g} s. "
        f"Hints: more substeps (now {substeps}) or newton_iter (now {stepper.n_iter}, retried with "
        f"{4 * stepper.n_iter} and a line search); a stiff contact or a "
        "switching element may need method='idas'")
