"""Exact zero-order-hold stepping of the model linearized at its start point: ``simulate(method="lti")``.

For a linear time-invariant model driven by held inputs this is exact (the floor for linear structures
driven by sampled inputs, see DESIGN.md, "Known pitfalls"); for nonlinear ones (friction, backlash, a
moving nut) it is wrong: use ``"idas"``, ``"fixed"`` or ``"split"`` there.

With ``A, B`` of the explicit form at the start point (:func:`bscomp.linear.explicit_form`) and the
deviations ``e = x - x_s``, ``du = u - u_0``, the affine model ``x' = x'_0 + A e + B du`` held over a step
``h`` gives

.. math:: e_{k+1} = A_d e_k + B_d\\,du_k + f_d, \\qquad
          \\exp\\left(\\begin{bmatrix} A & B & x'_0 \\\\ 0 & 0 & 0 \\end{bmatrix} h\\right)
          = \\begin{bmatrix} A_d & B_d & f_d \\\\ 0 & I & \\ldots \\end{bmatrix}

(one augmented matrix exponential per distinct step). On a uniform grid without controllers and for models
up to 32 states the recursion is solved for all steps at once in complex Schur coordinates of ``A_d``
(:func:`zoh_schur`); otherwise it is one matrix-vector product per step.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg as sla
from scipy.signal import lfilter

from bscomp.linear.linearization import explicit_form, linearized_parts, warn_linearized
from bscomp.simulation.common import SampledLoop, finish

__all__ = ["simulate_zoh", "zoh_schur"]

SCHUR_MAX = 32  # largest model solved in Schur coordinates (O(n^2 N) element-wise work)


#: largest relative residual of the nonlinear equations along an lti run that still counts as exact (the
#: nonlinearity was not reached: a current limit never hit, a joint never moved)
EXACT_RTOL = 1e-6
#: time points at which the nonlinear residual is evaluated (evenly spread, plus each input's extremes)
CHECK_POINTS = 200


def _check_linearization(dae, parts, t, X, XD, Z, Uh, p, jac) -> float:
    """Warn that the run linearized ``parts`` unless the nonlinear residual ``F(x', x, z, u)`` along it stays at
    round-off: ``|F_i| <= EXACT_RTOL sum_j |dF_i/dv_j| |v_j|`` at :data:`CHECK_POINTS` time points (each input's
    extremes among them), e.g. a current limit never reached or a friction element that never moved. The
    warning says when the run first left the tangent and in which equation. Returns the largest ratio
    ``|F_i| / sum_j |dF_i/dv_j| |v_j|`` (``0.0`` for a linear model), recorded as ``stats["linearization_error"]``."""
    if not parts:
        return 0.0
    nt = len(t)
    k = np.unique(np.r_[np.linspace(0, nt - 1, min(nt, CHECK_POINTS)).round().astype(int),
                        np.argmax(Uh, axis=0), np.argmin(Uh, axis=0)])
    key = ("lti_check", k.size)
    Fm = dae._cache.get(key)
    if Fm is None:
        Fm = dae._cache[key] = dae.F.map(k.size)
    R = np.abs(np.asarray(Fm(XD[k].T, X[k].T, Z[k].T, Uh[k].T, np.tile(np.asarray(p, float)[:, None], k.size))))
    Jxd, Jx, Jz, Ju = jac
    # the scale of each equation: its tangent's terms summed in magnitude, sum_j |J_ij| |v_j| (round-off of F is
    # a small multiple of it; a saturated limiter's row keeps the size of its output there)
    scale = sum(abs(J) @ np.abs(V[k]).T for J, V in ((Jxd, XD), (Jx, X), (Jz, Z), (Ju, Uh)) if J.shape[1])
    scale = np.asarray(scale) if np.ndim(scale) else np.zeros_like(R)
    top = float(scale.max(initial=0.0))
    rel = np.where(scale > 1e-12 * top, R / np.maximum(scale, 1e-300), 0.0)
    worst = float(rel.max(initial=0.0))
    if worst > EXACT_RTOL:
        col = int(np.argmax((rel > EXACT_RTOL).any(axis=0)))          # the first sampled time off the tangent
        row = int(np.argmax(rel[:, col]))
        origin = dae.eq_origin[row] if row < len(dae.eq_origin) else f"row {row}"
        warn_linearized(parts, "simulate(method='lti')", "use method='idas', 'fixed', 'split' or 'modal'",
                        stacklevel=5, measured=f"this run leaves it by t = {t[k[col]]:.4g} s, first in '{origin}'")
    return worst


def simulate_zoh(problem, options=None):
    """``simulate(method="lti")``: exact ZOH stepping of the model linearized at the start point.

    Parameters
    ----------
    problem : SimulationProblem
    options : SimulationOptions, optional
        Not used (the method has no settings).

    Returns
    -------
    SimulationResult
        ``stats``: ``discretisations`` (distinct step lengths).
    """
    dae, t, U, p, xs = problem.dae, problem.t, problem.U, problem.p, problem.x0
    parts = linearized_parts(dae, p)
    t_wall = time.perf_counter()
    nx, nu, nt = dae.nx, dae.nu, len(t)
    u0 = U[:, 0]
    xd0, z0 = dae.initialize(xs, u0, p, store=False)
    _, Jxd, Jx, Jz, Ju = dae.jacobians_at(xd0, xs, z0, u0, p)
    A, B, Zx, Zu = explicit_form(dae, Jxd, Jx, Jz, Ju)
    disc = _Discretisation(A, B, xd0)  # per call: it depends on this call's linearization point
    h_all = np.diff(t)
    Uh = np.empty((nt, nu))
    Uh[0] = u0
    uniform = bool(np.all(np.abs(h_all - h_all[0]) <= 1e-9 * h_all[0]))
    if not problem.controllers and uniform and 0 < nx <= SCHUR_MAX:
        Uh[1:] = U.T
        Ad, Bd, fd = disc(h_all[0])
        dX = zoh_schur(Ad, Bd, fd, U.T - u0)
        X = xs + dX
    else:
        keys = np.round(h_all, 15)
        uniq, which = np.unique(keys, return_inverse=True)
        discs = [disc(h) for h in uniq]
        if not problem.controllers:
            Uh[1:] = U.T
            X = xs + _recursion(discs, which, U.T - u0)
        else:
            X = _closed_loop(problem, discs, which, (A, B, Zx, Zu, xd0, z0), Uh)
        dX = X - xs
    dU = Uh - u0
    XD = xd0 + dX @ A.T + dU @ B.T
    Z = z0 + dX @ Zx.T + dU @ Zu.T
    worst = _check_linearization(dae, parts, t, X, XD, Z, Uh, p, (Jxd, Jx, Jz, Ju))
    return finish(problem, X, XD, Z, Uh, {"method": "lti", "discretisations": len(disc.cache),
                                          "linearization_error": worst}, t_wall)


class _Discretisation:
    """``(A_d, B_d, f_d)`` of the affine model for a step ``h`` (cached per step length)."""

    def __init__(self, A, B, xd0):
        self.A, self.B, self.xd0, self.cache = A, B, xd0, {}

    def __call__(self, h):
        key = round(h, 15)
        if key not in self.cache:
            nx, nu = self.B.shape
            n = nx + nu + 1
            Maug = np.zeros((n, n))
            Maug[:nx, :nx] = self.A * h
            Maug[:nx, nx:nx + nu] = self.B * h
            Maug[:nx, -1] = self.xd0 * h
            E = sla.expm(Maug)
            self.cache[key] = (E[:nx, :nx], E[:nx, nx:nx + nu], E[:nx, -1])
        return self.cache[key]


def _recursion(discs, which, dU):
    """``e_0 = 0, e_1 .. e_N`` of ``e_{k+1} = A_d e_k + B_d du_k + f_d`` (step ``k`` uses ``discs[which[k]]``)."""
    N, nx = dU.shape[0], discs[0][0].shape[0]
    G = np.empty((N, nx))
    for j, (_, Bd, fd) in enumerate(discs):
        sel = which == j
        G[sel] = dU[sel] @ Bd.T + fd
    Ads = [d[0] for d in discs]
    E = np.zeros((N + 1, nx))
    e = np.zeros(nx)
    for k in range(N):
        e = Ads[which[k]] @ e + G[k]
        E[k + 1] = e
    return E


def _closed_loop(problem, discs, which, lin, Uh):
    """States with sampled controllers in the loop (one step at a time); writes the applied inputs into
    ``Uh`` rows 1..N."""
    dae, t, U, p, xs = problem.dae, problem.t, problem.U, problem.p, problem.x0
    A, B, Zx, Zu, xd0, z0 = lin
    u0 = U[:, 0]
    loop = SampledLoop(dae, problem.controllers, t[0])
    X = np.empty((len(t), dae.nx))
    X[0] = xs
    e = np.zeros(dae.nx)
    for k in range(len(t) - 1):
        u_k = U[:, k].copy()

        def y_of(uk, k=k, e=e):
            du = uk - u0
            return loop.measure(xd0 + A @ e + B @ du, X[k], z0 + Zx @ e + Zu @ du, uk, p)

        loop.sample(t[k], u_k, y_of)
        Ad, Bd, fd = discs[which[k]]
        e = Ad @ e + Bd @ (u_k - u0) + fd
        X[k + 1] = xs + e
        Uh[k + 1] = u_k
    return X


def zoh_schur(Ad, Bd, fd, dU):
    """All ``e_k`` (k = 0..N, e_0 = 0) of ``e_{k+1} = Ad e_k + Bd du_k + fd`` (rows of dU: du_k), no step loop.

    With ``Ad = Q T Q^H`` (complex Schur, unitary Q) the coordinates ``eta = Q^H e`` obey an upper
    triangular recursion (after balancing), solved from the last component up, each one a first-order filter
    (:func:`scipy.signal.lfilter`) driven by the input and the components already known. Only
    element-wise vector operations are used (no threaded BLAS on long arrays, which stalls on a busy
    machine); the work is O(n^2 N), meant for small models.
    """
    # balancing first (a diagonal similarity) puts states of very different size (µm, rad/s) on one
    # scale; without it the unitary transform spreads round-off of the large ones onto the small ones
    Ab, (scale, _) = sla.matrix_balance(Ad, permute=False, separate=True)
    T, Q = sla.schur(Ab, output="complex")
    n, N = Ad.shape[0], dU.shape[0]
    Bm = Q.conj().T @ (Bd / scale[:, None])
    fm = Q.conj().T @ (fd / scale)
    eta = np.zeros((n, N + 1), complex)  # row i: eta_i at k = 0..N, eta_0 = 0
    for i in range(n - 1, -1, -1):
        drive = np.full(N, fm[i], complex)
        for j in range(dU.shape[1]):
            if Bm[i, j] != 0:
                drive += Bm[i, j] * dU[:, j]
        for j in range(i + 1, n):
            if T[i, j] != 0:
                drive += T[i, j] * eta[j, :-1]
        eta[i, 1:] = lfilter([1.0], [1.0, -T[i, i]], drive)
    e = np.zeros((n, N + 1))
    for i in range(n):
        for j in range(n):
            e[i] += (Q[i, j] * eta[j]).real
        e[i] *= scale[i]
    return np.ascontiguousarray(e.T)
