"""Direct collocation (Radau IIA) of an :class:`~bscomp.optimal.Ocp` in the model's own coordinates.

The implicit DAE ``F(x', x, z, u, p) = 0`` is collocated on N intervals of length ``h = T/N`` with the
Radau IIA points ``τ_1..τ_d`` of degree ``d`` (``τ_d = 1``): the state polynomial through ``x_k`` and the
stage values ``x_k1..x_kd`` gives

.. math:: h\\, x'(t_k + τ_j h) = \\sum_{r=0}^{d} C_{rj}\\, x_{kr}, \\qquad x_{k+1} = x_{kd},

and the residual ``F`` is imposed at every collocation point, with ``x'`` and ``z`` there as unknowns
(inputs piecewise constant: what a sampled drive applies). ``C`` and the quadrature weights ``B`` of the
integral objectives come from CasADi (``collocation_points``, ``collocation_coeff``): :func:`radau`.

Every unknown is scaled by a nominal magnitude (:class:`bscomp.optimal.guess.Guess`) and every residual
row by its largest scaled term, so µm and kN live in one problem; the reference motion of
:mod:`bscomp.optimal.guess` is the cold-start guess. The Dae is not touched: the transcription is
chosen apart from the model.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache, partial

import casadi as ca
import numpy as np

from bscomp.kernel.signal_meta import unit_of
from bscomp.optimal.checks import reference_values
from bscomp.optimal.infeasibility import Ledger, describe
from bscomp.optimal.result import OcpError, OcpResult, active_fraction, convergence_error

__all__ = ["RadauScheme", "radau", "objective", "output_at", "solve_physical"]


@dataclass(frozen=True)
class RadauScheme:
    """Radau IIA collocation of degree ``d`` on the unit interval.

    Attributes
    ----------
    d : int
    tau : ndarray (d+1,)
        0 and the collocation points ``τ_1..τ_d`` (``τ_d = 1``).
    C : ndarray (d+1, d)
        Derivative weights: ``x'(τ_j) = Σ_r C[r, j-1] x(τ_r)`` for the polynomial through ``x(τ_0..τ_d)``.
    D : ndarray (d+1,)
        End-value weights, ``x(1) = Σ_r D[r] x(τ_r)`` (Radau: the last stage).
    B : ndarray (d,)
        Quadrature weights, ``∫_0^1 f ≈ Σ_j B[j-1] f(τ_j)``: CasADi's integrals of the Lagrange basis of
        ``τ_1..τ_d`` over the points ``0, τ_1..τ_d``, the Radau quadrature (exact to degree 2d - 2) for
        d >= 2; at d = 1 the basis of ``τ_0`` keeps half the interval and ``B = [1/2]``.
    """

    d: int
    tau: np.ndarray
    C: np.ndarray
    D: np.ndarray
    B: np.ndarray

    def stage_times(self, N: int, T: float | None = None) -> np.ndarray:
        """Collocation times of N equal intervals of ``[0, T]`` (default: normalised, ``T = 1``), N d values
        interval by interval."""
        if T is None:
            return np.concatenate([(k + self.tau[1:]) / N for k in range(N)])
        return np.concatenate([(k + self.tau[1:]) * (T / N) for k in range(N)])


@lru_cache(maxsize=None)
def radau(d: int) -> RadauScheme:
    """The Radau IIA scheme of degree ``d`` from ``casadi.collocation_points`` / ``collocation_coeff``."""
    pts = ca.collocation_points(int(d), "radau")
    C, D, B = (np.asarray(ca.DM(m), float) for m in ca.collocation_coeff(pts))
    arrays = np.append(0.0, pts), C.reshape(d + 1, d), D.ravel(), B.ravel()
    for a in arrays:
        a.setflags(write=False)
    return RadauScheme(int(d), *arrays)


def output_at(dae, p, name, x, u) -> float:
    """An observable at a state and input, with ``(x', z)`` made consistent there."""
    xd, z = dae.initialize(x, u, p, store=False)
    return float(dae.output_function([name])(xd, x, z, u, p))


def objective(ocp, scheme: RadauScheme, T, T0, h, Us, y=None, y_scale=1.0):
    """The objective of ``ocp`` on the grid: ``T/T0`` (minimum time), ``∫ Σ w_i u_i² dt`` (effort, inputs in
    units of their nominals), ``∫ ((y - r(t))/s)² dt`` (+ effort weight × ``∫ Σ u_i²``) (tracking) or
    ``∫ (y/s)² dt`` over the last ``T_settle`` (residual vibration), the integrals by Radau quadrature.

    ``Us`` are the scaled inputs (nu x N), ``y`` the objective's output at the collocation points
    (1 x N d, unscaled) and ``y_scale`` its nominal ``s``.
    """
    N = Us.shape[1]
    kind, args = ocp.objective_kind, ocp.objective_args
    if kind == "time":
        return T / T0
    if kind == "effort":
        w = np.array([args["weights"].get(n, 1.0) for n in ocp.dae.u_names])
        return h * ca.sum2(ca.sum1(ca.diag(w) @ (Us**2)))
    wq = np.tile(scheme.B, N)
    tc = scheme.stage_times(N, ocp.T_fixed)
    if kind == "tracking":
        ref_t = reference_values(args["reference"], args["output"], tc)
        e = (y - ca.DM(ref_t[None, :])) / y_scale
        return h * ca.sum2(e**2 * ca.DM(wq[None, :])) + args["effort_weight"] * h * ca.sumsqr(Us)
    mask = (tc >= ocp.T_fixed - args["T_settle"]).astype(float)
    e = y / y_scale
    return h * ca.sum2(e**2 * ca.DM((wq * mask)[None, :]))


def solve_physical(ocp, guess, solver_options: dict | None = None) -> OcpResult:
    """Transcribe ``ocp`` by direct collocation in the model's coordinates and solve it with Ipopt.

    Parameters
    ----------
    ocp : Ocp
        The problem statement.
    guess : bscomp.optimal.guess.Guess
        Start state, linearization, horizon guess, reference motion and nominals
        (:func:`bscomp.optimal.guess.initial_guess`).
    solver_options : dict, optional
        Ipopt options over ``ocp.ipopt_options``.

    Raises :class:`~bscomp.optimal.OcpError` if Ipopt does not converge.
    """
    return _Transcription(ocp, guess).solve(solver_options)


class _Transcription:
    """The collocation NLP of one :class:`~bscomp.optimal.Ocp` (CasADi ``Opti``), built step by step:
    unknowns, collocation and residual equations, boundary conditions, residual-vibration limits, path
    bounds, rate limits, objective, guess; then solved and read back into an :class:`OcpResult`."""

    def __init__(self, ocp, guess):
        self.ocp, self.dae, self.guess = ocp, ocp.dae, guess
        self.N, self.d = ocp.N, ocp.d
        self.scheme = radau(ocp.d)
        self.x0, self.lin, self.T0, self.ref = guess.x0, guess.lin, guess.T0, guess.ref
        self.xs, self.ws, self.zs, self.us = guess.xs, guess.ws, guess.zs, guess.us
        self.opti = ca.Opti()
        self.ledger = Ledger()
        self.tk = np.arange(self.N) / self.N                 # interval starts, fractions of T
        self.tc = self.scheme.stage_times(self.N)            # collocation points, fractions of T

    def _subject_to(self, constraint, label, names, tfrac, scale=1.0, lo=None, hi=None, rate=False):
        """``opti.subject_to`` with the rows recorded in the ledger (what they are, names, times, scales)."""
        start = self.opti.ng
        self.opti.subject_to(constraint)
        self.ledger.add(self.opti.ng - start, label, names, tfrac, scale, lo, hi, start=start, rate=rate)

    def solve(self, solver_options) -> OcpResult:
        ocp, opti = self.ocp, self.opti
        self._unknowns()
        self._collocation()
        self._boundary()
        self._outputs()
        self._path_bounds()
        rate_expr = self._rate_limits()
        y = self.Yc[self.all_y.index(ocp.objective_args["output"]), :] if self.obj_y else None
        opti.minimize(objective(ocp, self.scheme, self.T, self.T0, self.h, self.Us, y,
                                self.ys.get(self.obj_y[0], 1.0) if self.obj_y else 1.0))
        self._initial_guess()
        ipopt = dict(ocp.ipopt_options, **(solver_options or {}))
        opti.solver("ipopt", {"ipopt": ipopt, "print_time": False, "expand": ocp.expand,
                              "detect_simple_bounds": True})
        try:
            sol = opti.solve()
        except RuntimeError as exc:
            raise self._failure(exc) from exc
        return self._result(sol, opti.stats(), rate_expr)

    def _unknowns(self):
        """Scaled unknowns (states at the grid and collocation points, derivatives and algebraic variables at
        the collocation points, free inputs, T in units of its guess) and the physical expressions of them."""
        opti, dae, N, d, ocp = self.opti, self.dae, self.N, self.d, self.ocp
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        xs, ws, zs, us = self.xs, self.ws, self.zs, self.us
        self.Xs = opti.variable(nx, N + 1)
        self.Xcs = opti.variable(nx, N * d)
        self.Wcs = opti.variable(nx, N * d)   # state derivatives at the collocation points, scaled by ws
        self.Zcs = opti.variable(nz, N * d) if nz else None
        # inputs held at a value (bound lo == hi, e.g. a disturbance force at 0) are constants, not unknowns
        self.fixed_u = ocp.fixed_inputs()
        self.free_u = [i for i in range(nu) if i not in self.fixed_u]
        self.Uv = opti.variable(len(self.free_u), N)
        rows_u = [self.Uv[self.free_u.index(i), :] if i in self.free_u
                  else ca.DM(np.full((1, N), self.fixed_u[i] / us[i])) for i in range(nu)]
        self.Us = ca.vertcat(*rows_u) if nu else ca.MX(0, N)
        self.X, self.Xc, self.Wc = ca.diag(xs) @ self.Xs, ca.diag(xs) @ self.Xcs, ca.diag(ws) @ self.Wcs
        self.Zc = ca.diag(zs) @ self.Zcs if nz else ca.DM(0, N * d)
        self.U = ca.diag(us) @ self.Us
        if ocp.T_fixed is None:
            self.Tsc = opti.variable()          # T in units of its guess
            self.T = self.T0 * self.Tsc
            self._subject_to(self.Tsc >= 1e-6, "horizon", "T", 1.0, self.T0, lo=1e-6 * self.T0)
            opti.set_initial(self.Tsc, self.ref["T"] / self.T0)
        else:
            self.T = ocp.T_fixed
        self.h = self.T / N

    def _collocation(self):
        """Radau IIA: ``h x'(t_kj) = Σ_r C[r, j] x_kr``, each row in units of its state nominal; continuity
        ``x_{k+1} = x_kd``; the residual ``F = 0`` at every collocation point, each row by its scale."""
        N, d, C, tau = self.N, self.d, self.scheme.C, self.scheme.tau
        xs, ws, names = self.xs, self.ws, self.dae.x_names
        nx, st = len(names), self._subject_to
        for j in range(1, d + 1):
            terms = C[0, j - 1] * self.Xs[:, :N]
            for r in range(1, d + 1):
                terms = terms + C[r, j - 1] * self.Xcs[:, (r - 1)::d]
            st(ca.vec(self.h * ca.diag(ws / xs) @ self.Wcs[:, (j - 1)::d] - terms) == 0, "collocation equation",
               names * N, np.repeat((np.arange(N) + tau[j]) / N, nx), np.tile(xs, N))
        st(ca.vec(self.Xs[:, 1:] - self.Xcs[:, (d - 1)::d]) == 0, "continuity", names * N,
           np.repeat(np.arange(1, N + 1) / N, nx), np.tile(xs, N))
        self.Ucol = ca.horzcat(*[self.U[:, k] @ np.ones((1, d)) for k in range(N)])  # u held on each interval
        self.Pm = ca.repmat(ca.DM(self.ocp.p), 1, N * d)
        res = self.dae.F.map(N * d)(self.Wc, self.Xc, self.Zc, self.Ucol, self.Pm)
        self.rs = self.guess.residual_scales(self.ocp)
        nF = len(self.rs)
        st(ca.vec(ca.diag(1.0 / self.rs) @ res) == 0, "model residual", list(self.dae.eq_origin[:nF]) * (N * d),
           np.repeat(self.tc, nF), np.tile(self.rs, N * d))

    def _boundary(self):
        """Initial state, final values and rest, linear final rows, and the residual-vibration limits
        ``|L (x_T - x0) + l| <= limit`` (in units of the limit)."""
        ocp, xs, Xs, N, x0, st = self.ocp, self.xs, self.Xs, self.N, self.x0, self._subject_to
        names = self.dae.x_names
        st(Xs[:, 0] == x0 / xs, "initial value", names, 0.0, xs)
        for i, v in ocp.final_targets():      # v: the target (the row is x_N - v, in units of the state)
            st(Xs[i, N] == v / xs[i], "final value", names[i], 1.0, xs[i])
        term = ocp.terminal_rows(self.lin)
        if term is not None:
            Ct, tt = term
            CtS = Ct * xs[None, :]
            sc = np.max(np.abs(CtS), axis=1)
            sc = np.where(sc > 0, sc, 1.0)
            st(ca.mtimes(ca.DM(CtS / sc[:, None]), Xs[:, N]) == ca.DM(tt / sc), "final condition",
               ocp.terminal_names(len(tt)), 1.0, sc)
        self.res_expr = {}
        for n, (L, l_) in ocp.residual_rows(self.lin).items():
            lim = ocp.residual_limits[n]
            e = ca.mtimes(ca.DM(L * xs[None, :] / lim), Xs[:, N]) + ca.DM((l_ - L @ x0) / lim)
            self.res_expr[n] = ca.sqrt(ca.sumsqr(e)) * lim
            st(ca.sumsqr(e) <= 1.0, "residual-vibration limit (in units of the limit, squared)", n, 1.0)

    def _outputs(self):
        """Observables that are bounded, rate limited or in the objective, at the collocation points, and
        their nominals (given, else the largest magnitude along the reference motion)."""
        ocp, dae, N, d, ref = self.ocp, self.dae, self.N, self.d, self.ref
        y_names = [n for n in list(ocp.bounds) + list(ocp.rate_limits) if ocp.kind(n) == "y"]
        self.obj_y = [ocp.objective_args["output"]] if ocp.objective_kind in ("tracking", "vibration") else []
        self.all_y = all_y = list(dict.fromkeys(y_names + self.obj_y))
        self.Yc = dae.output_function(all_y).map(N * d)(self.Wc, self.Xc, self.Zc, self.Ucol, self.Pm) \
            if all_y else None
        self.ys = {n: ocp.nominal(n, default=np.nan) for n in all_y}
        if all_y:
            Yref = np.atleast_2d(np.asarray(dae.output_function(all_y).map(N * d)(
                ref["W"], ref["Xc"], ref["Z"], np.repeat(ref["U"].T, d, axis=1),
                np.tile(ocp.p[:, None], (1, N * d)))))
            for i, n in enumerate(all_y):
                if np.isnan(self.ys[n]):
                    m = float(np.max(np.abs(Yref[i]))) if Yref.size else 0.0
                    self.ys[n] = m if m > 0 else 1.0

    def _path_bounds(self):
        """``lo <= v <= hi`` on inputs (per interval), states (grid and collocation points) and observables
        (collocation points), in units of the signal's nominal."""
        opti, ocp, dae = self.opti, self.ocp, self.dae
        for n, (lo, hi) in ocp.bounds.items():
            kind = ocp.kind(n)
            if kind == "u":
                i = dae.u_names.index(n)
                if i in self.fixed_u:
                    continue
                expr, s, tf = self.Us[i, :], self.us[i], self.tk
            elif kind == "x":
                i = dae.x_names.index(n)
                expr, s = ca.horzcat(self.Xs[i, :], self.Xcs[i, :]), self.xs[i]
                tf = np.r_[np.arange(self.N + 1) / self.N, self.tc]
            else:
                s, tf = self.ys[n], self.tc
                expr = self.Yc[self.all_y.index(n), :] / s
            if lo == hi:
                c = ca.vec(expr) == lo / s
            elif np.isfinite(lo) and np.isfinite(hi):
                c = opti.bounded(lo / s, ca.vec(expr), hi / s)
            elif np.isfinite(lo):
                c = ca.vec(expr) >= lo / s
            elif np.isfinite(hi):
                c = ca.vec(expr) <= hi / s
            else:
                continue
            self._subject_to(c, "bound", n, tf, s, lo=lo, hi=hi)

    def _after_arrival(self, u_hold):
        """``(x', z)`` just after arrival, consistent with the final state and the held input (unknowns)."""
        opti, dae, nx, nz = self.opti, self.dae, self.dae.nx, self.dae.nz
        XDa = opti.variable(nx)
        opti.set_initial(XDa, np.zeros(nx))
        xd_a = ca.diag(self.ws) @ XDa
        if nz:
            Za = opti.variable(nz)
            opti.set_initial(Za, self.ref["Z"][-1] / self.zs)
            z_a = ca.diag(self.zs) @ Za
        else:
            z_a = ca.DM(0, 1)
        self._subject_to(ca.diag(1.0 / self.rs) @ dae.F(xd_a, self.X[:, self.N], z_a, u_hold, self.ocp.p) == 0,
                         "model residual just after arrival", list(dae.eq_origin[:len(self.rs)]), 1.0, self.rs)
        return xd_a, z_a

    def _rate_limits(self) -> dict:
        """``|v_{k+1} - v_k| <= limit h`` between interval ends, from the value before the move to the value
        after arrival (the model at its final state with the held input); returns the rates by name."""
        ocp, dae, N, d, x0 = self.ocp, self.dae, self.N, self.d, self.x0
        rate_expr = {}
        if not ocp.rate_limits:
            return rate_expr
        u_before = np.array([self.fixed_u.get(i, 0.0) for i in range(dae.nu)])
        xd_b, z_b = dae.initialize(x0, u_before, ocp.p, store=False)
        u_hold = ocp.held_inputs()
        if any(ocp.kind(n) == "y" for n in ocp.rate_limits):
            xd_a, z_a = self._after_arrival(u_hold)
        for n, lim in ocp.rate_limits.items():
            kind = ocp.kind(n)
            if kind == "u":
                i = dae.u_names.index(n)
                seq, first, last = self.U[i, :], u_before[i], u_hold[i]
            elif kind == "x":
                i = dae.x_names.index(n)
                seq, first, last = self.X[i, 1:], x0[i], None          # a state does not jump at arrival
            else:
                yf = dae.output_function([n])
                seq = self.Yc[self.all_y.index(n), (d - 1)::d]
                first = float(np.asarray(yf(xd_b, x0, z_b, u_before, ocp.p)).ravel()[0])
                last = yf(xd_a, self.X[:, N], z_a, u_hold, ocp.p)
            parts = [seq[:, 0] - first, seq[:, 1:] - seq[:, :-1]]
            if last is not None:
                parts.append(last - seq[:, -1])
            diff = ca.horzcat(*parts)                                           # (1, N or N+1)
            h0 = self.T0 / N
            g = diff / (lim * h0)                                               # in units of the allowed step
            hs = self.h / h0
            tf = np.minimum(np.arange(1, diff.numel() + 1) / N, 1.0)
            self._subject_to(ca.vec(g - hs) <= 0, "rate limit", n, tf, lim * h0, rate=True)
            self._subject_to(ca.vec(-g - hs) <= 0, "rate limit", n, tf, lim * h0, rate=True)
            rate_expr[n] = diff / self.h
        return rate_expr

    def _initial_guess(self):
        """The reference motion (or the warm start), scaled."""
        opti, ref = self.opti, self.ref
        opti.set_initial(self.Xs, (ref["X"] / self.xs).T)
        opti.set_initial(self.Xcs, ref["Xc"] / self.xs[:, None])
        opti.set_initial(self.Wcs, ref["W"] / self.ws[:, None])
        if self.dae.nz:
            opti.set_initial(self.Zcs, ref["Z"] / self.zs[:, None])
        if self.free_u:
            opti.set_initial(self.Uv, (ref["U"][:, self.free_u] / self.us[self.free_u]).T)

    def _failure(self, exc):
        """The :class:`OcpError` of a failed solve, with the violation and vibration bound at the last iterate."""
        opti = self.opti
        where, info = "", {}
        try:
            gv, lbg, ubg = (np.asarray(opti.debug.value(e), float).ravel() for e in (opti.g, opti.lbg, opti.ubg))
            viol = float(np.max(np.r_[0.0, lbg - gv, gv - ubg]))
            T = float(opti.debug.value(self.T)) if self.ocp.T_fixed is None else self.ocp.T_fixed
            where, info = describe(self.ledger, T, gv, lbg, ubg, units=partial(unit_of, self.dae))
        except Exception:  # noqa: BLE001 - diagnostic only
            viol = float("nan")
        vib = {}
        for n, e in self.res_expr.items():
            try:
                vib[n] = float(opti.debug.value(e))
            except Exception:  # noqa: BLE001 - diagnostic only
                vib[n] = None
        try:
            stats = opti.stats()
        except RuntimeError:     # Ipopt did not even start (it refused an option or the problem)
            return OcpError(f"Ipopt did not run on '{self.dae.name}': {str(exc).strip().splitlines()[-1]}")
        return convergence_error(self.dae.name, stats, viol, vib, self.ocp.residual_limits, where, info,
                                 units=partial(unit_of, self.dae))

    def _result(self, sol, stats, rate_expr) -> OcpResult:
        """The solution at the grid points (derivatives and algebraic variables: the last stage of each
        interval, consistent values at t = 0), bounded outputs, active fractions, residual bounds."""
        ocp, dae, N, d = self.ocp, self.dae, self.N, self.d
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        Xv = np.atleast_2d(sol.value(self.X)).reshape(nx, N + 1).T
        Uv = np.atleast_2d(sol.value(self.U)).reshape(nu, N).T
        Tv = float(sol.value(self.T)) if ocp.T_fixed is None else ocp.T_fixed
        xd0, z0 = dae.initialize(Xv[0], Uv[0], ocp.p, store=False)
        XDv = np.vstack([xd0, np.atleast_2d(sol.value(self.Wc)).reshape(nx, N * d)[:, (d - 1)::d].T])
        Zv = np.vstack([z0, np.atleast_2d(sol.value(self.Zc)).reshape(nz, N * d)[:, (d - 1)::d].T]) if nz \
            else np.zeros((N + 1, 0))
        outputs = {}
        if self.all_y:
            Ycv = np.atleast_2d(sol.value(self.Yc)).reshape(len(self.all_y), N * d)
            for i, n in enumerate(self.all_y):
                outputs[n] = np.r_[output_at(dae, ocp.p, n, Xv[0], Uv[0]), Ycv[i, (d - 1)::d]]
        active = {}
        for n, (lo, hi) in ocp.bounds.items():
            if n in outputs:
                v = outputs[n]
            elif n in dae.u_names:
                v = Uv[:, dae.u_names.index(n)]
            else:
                v = Xv[:, dae.x_names.index(n)]
            active[n] = active_fraction(v, lo, hi)
        for n, e in rate_expr.items():
            r = np.abs(np.atleast_1d(np.asarray(sol.value(e), float)).ravel())
            active[f"rate:{n}"] = float(np.mean(r >= ocp.rate_limits[n] * (1 - 1e-4)))
        return OcpResult(T=Tv, t=np.linspace(0, Tv, N + 1), x=Xv, u=Uv, outputs=outputs, x_names=list(dae.x_names),
                         u_names=list(dae.u_names), active=active,
                         stats={"return_status": stats.get("return_status"), "iter_count": stats.get("iter_count"),
                                "t_wall_total": stats.get("t_wall_total")}, dae=dae, p=ocp.p, xd=XDv, z=Zv,
                         residual={n: float(sol.value(e)) for n, e in self.res_expr.items()})
