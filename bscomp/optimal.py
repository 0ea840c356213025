"""Optimal control of a flattened drive model with Ipopt (through CasADi).

The problem is stated on the model's names (states, inputs, observables) and transcribed by direct
collocation (Radau IIA, degree ``d``) of the implicit DAE ``F(x', x, z, u, p) = 0``: on interval k with
length h, the state polynomial through ``x_k, x_k1..x_kd`` gives ``x'(t_kj)`` and the residual is
imposed at every collocation point; inputs are piecewise constant (what a sampled drive applies).
Variables are scaled by nominal magnitudes (from bounds, boundary values or given ``scale``), so µm and
kN live in one problem. The transcription is chosen apart from the model: the Dae is not touched.

>>> ocp = Ocp(system, N=100)
>>> ocp.bound("motor.tau", -8, 8); ocp.bound("table.v", -1, 1)
>>> ocp.initial({"table.s": 0.0}); ocp.final({"table.s": 0.1}, rest=True)
>>> res = ocp.minimize_time(T_guess=0.2).solve()
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import casadi as ca
import numpy as np

from .errors import BscompError, UnknownNameError
from .linear import resolve_model

__all__ = ["Ocp", "OcpResult", "OcpError"]


class OcpError(BscompError):
    """Ipopt did not converge; the message gives its status, the largest violations and a hint."""


@dataclass
class OcpResult:
    """Solution of an :class:`Ocp`.

    Attributes
    ----------
    T : float
        Horizon [s].
    t : ndarray (N+1,)
        Interval boundaries.
    x : ndarray (N+1, nx)
    u : ndarray (N, nu)
        Piecewise-constant inputs on each interval.
    outputs : dict name -> ndarray (N+1,)
    active : dict name -> fraction of points where the bound is active (within 1e-6 of it)
    """

    T: float
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    outputs: dict
    x_names: list
    u_names: list
    active: dict
    stats: dict = field(default_factory=dict)
    dae: Any = None
    p: Any = None

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.x_names:
            return self.x[:, self.x_names.index(name)]
        if name in self.u_names:
            return self.u[:, self.u_names.index(name)]
        raise UnknownNameError(f"no signal '{name}' in this OCP result")

    def input_function(self, name) -> Callable:
        """The optimal piecewise-constant input as a function of time (for :func:`simulate`)."""
        u = self[name]
        t = self.t

        def f(tt):
            k = min(max(int(np.searchsorted(t, tt, side="right") - 1), 0), len(u) - 1)
            return u[k]
        return f

    def resimulate(self, model=None, outputs=None, n_per_interval=10, **kw):
        """Run the optimal input through :func:`bscomp.simulate.simulate` on the same model (default)
        or another one (e.g. the full model); returns (SimulationResult, max relative deviation of the
        recorded outputs from the OCP prediction)."""
        from .simulate import simulate

        model = model if model is not None else self.dae
        outputs = list(outputs or self.outputs)
        tt = np.linspace(self.t[0], self.t[-1], n_per_interval * (len(self.t) - 1) + 1)
        x0 = {n: v for n, v in zip(self.x_names, self.x[0])}
        r = simulate(model, tt, inputs={n: self.input_function(n) for n in self.u_names}, x0=x0,
                     outputs=outputs, **kw)
        dev = {}
        for n in outputs:
            if n in self.outputs:
                ref = np.interp(tt, self.t, self.outputs[n])
                dev[n] = float(np.max(np.abs(r[n] - ref)) / max(np.max(np.abs(ref)), 1e-300))
        return r, dev

    def plot(self, names=None, path=None, title="optimal control"):
        from .plotting import time_plot

        names = list(names or (list(self.outputs) + self.u_names))
        sig = []
        for n in names:
            v = self[n]
            sig.append(np.r_[v, v[-1]] if len(v) == len(self.t) - 1 else v)
        return time_plot(self.t, sig, names, title=title, path=path)


def _radau(d):
    tau = np.append(0.0, ca.collocation_points(d, "radau"))
    C = np.zeros((d + 1, d + 1))
    for j in range(d + 1):
        coeff = np.zeros(d + 1)
        coeff[j] = 1.0
        # Lagrange basis j
        p = np.poly1d([1.0])
        for r in range(d + 1):
            if r != j:
                p *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        dp = np.polyder(p)
        for r in range(d + 1):
            C[j, r] = dp(tau[r])
    return tau, C


class Ocp:
    """Optimal-control problem on a System or Dae (see module docstring).

    Parameters
    ----------
    model : System or Dae
    N : int
        Number of intervals.
    degree : int
        Radau collocation degree.
    params : dict, optional
        Parameter overrides.
    """

    def __init__(self, model, N: int = 100, degree: int = 3, params: dict | None = None):
        self.dae = resolve_model(model, params)
        self.p = self.dae.parameter_vector({k: v for k, v in (params or {}).items()
                                            if k not in self.dae.structural_parameters})
        self.N, self.d = int(N), int(degree)
        self.bounds: dict[str, tuple] = {}
        self.x_init: dict[str, float] = {}
        self.x_final: dict[str, float] = {}
        self.final_rest = False
        self.T_fixed: float | None = None
        self.T_guess = 1.0
        self.objective_kind = None
        self.objective_args: dict = {}
        self.scale: dict[str, float] = {}
        self.warm: OcpResult | None = None
        self.ipopt_options = {"print_level": 0, "max_iter": 3000, "tol": 1e-8}

    # ---- problem statement --------------------------------------------------------------------
    def _kind(self, name):
        d = self.dae
        if name in d.x_names:
            return "x"
        if name in d.u_names:
            return "u"
        if name in d.observables:
            return "y"
        raise UnknownNameError(f"'{name}' is not a state, input or output of '{d.name}'; inputs: {d.u_names}, "
                               f"states: {d.x_names[:8]}...")

    def bound(self, name, lo=-np.inf, hi=np.inf, scale=None):
        """Path bound ``lo <= name <= hi`` on a state, input or observable (enforced at every point)."""
        self._kind(name)
        if lo > hi:
            raise ValueError(f"bound on '{name}': lower {lo} > upper {hi}")
        self.bounds[name] = (float(lo), float(hi))
        if scale is not None:
            self.scale[name] = float(scale)
        return self

    def initial(self, values: dict):
        """Initial state values by name (others at the model's start values: at rest)."""
        for k in values:
            if self._kind(k) != "x":
                raise UnknownNameError(f"initial value for '{k}': only states can be given")
        self.x_init.update({k: float(v) for k, v in values.items()})
        return self

    def final(self, values: dict, rest: bool = True):
        """Final state values by name; ``rest=True`` also sets every velocity state to zero at the end."""
        for k in values:
            if self._kind(k) != "x":
                raise UnknownNameError(f"final value for '{k}': only states can be given")
        self.x_final.update({k: float(v) for k, v in values.items()})
        self.final_rest = rest
        return self

    def minimize_time(self, T_guess: float = 1.0):
        self.objective_kind = "time"
        self.T_guess = float(T_guess)
        self.T_fixed = None
        return self

    def minimize_effort(self, T: float, weights: dict | None = None):
        """Minimise ∫ Σ w_i u_i² dt over a fixed horizon T."""
        self.objective_kind = "effort"
        self.T_fixed = float(T)
        self.objective_args = {"weights": weights or {}}
        return self

    def minimize_tracking(self, T: float, output: str, reference: Callable, effort_weight: float = 0.0):
        """Minimise ∫ (y - r(t))² dt (+ effort) over a fixed horizon."""
        self._kind(output)
        self.objective_kind = "tracking"
        self.T_fixed = float(T)
        self.objective_args = {"output": output, "reference": reference, "effort_weight": effort_weight}
        return self

    def minimize_residual_vibration(self, T: float, output: str, T_settle: float):
        """Fixed-time move, then minimise ∫ y² over the last ``T_settle`` seconds (e.g. table acceleration
        or screw stretch after arrival)."""
        self._kind(output)
        self.objective_kind = "vibration"
        self.T_fixed = float(T)
        self.objective_args = {"output": output, "T_settle": float(T_settle)}
        return self

    def warm_start(self, result: OcpResult):
        self.warm = result
        return self

    # ---- transcription and solve ----------------------------------------------------------------
    def _nominal(self, name, default=1.0):
        if name in self.scale:
            return self.scale[name]
        vals = [abs(v) for v in self.bounds.get(name, ()) if np.isfinite(v)]
        vals += [abs(self.x_init.get(name, 0.0)), abs(self.x_final.get(name, 0.0))]
        m = max(vals) if vals else 0.0
        return m if m > 0 else default

    def solve(self, solver_options: dict | None = None) -> OcpResult:
        """Transcribe and solve with Ipopt; raises :class:`OcpError` if it does not converge."""
        dae, N, d = self.dae, self.N, self.d
        if self.objective_kind is None:
            raise OcpError("no objective: call minimize_time(), minimize_effort(), minimize_tracking() or "
                           "minimize_residual_vibration() first")
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        tau, C = _radau(d)
        opti = ca.Opti()
        xs = self._state_nominals()
        if self.warm is None:
            guess = np.abs(self._rest_guess(dae.x_start.copy()))
            unset = [i for i, n in enumerate(dae.x_names) if not n.startswith("der(") and n not in self.scale
                     and n not in self.bounds and n not in self.x_final and n not in self.x_init]
            for i in unset:
                if guess[i] > 0:
                    xs[i] = guess[i]
        # velocity/position nominal values: propagate from a related bounded signal if none given
        us = np.array([self._nominal(n) for n in dae.u_names])
        Xs = opti.variable(nx, N + 1)
        Xcs = opti.variable(nx, N * d)
        Wcs = opti.variable(nx, N * d)   # state derivatives at collocation points (scaled by xs)
        Zc = opti.variable(nz, N * d) if nz else None
        Us = opti.variable(nu, N)
        X = ca.diag(xs) @ Xs
        Xc = ca.diag(xs) @ Xcs
        U = ca.diag(us) @ Us
        if self.T_fixed is None:
            T = opti.variable()
            opti.subject_to(T >= 1e-6)
            opti.set_initial(T, self.T_guess)
        else:
            T = self.T_fixed
        h = T / N
        # collocation: derivative of the Lagrange polynomial at tau_j, j=1..d
        cols = []
        for j in range(1, d + 1):
            terms = C[0, j] * X[:, :N]
            for r in range(1, d + 1):
                terms = terms + C[r, j] * Xc[:, (r - 1)::d]
            cols.append(terms)
        # Wc = dx/dt at collocation points: (1/h) * sum_r C[r, j] x_r
        Wc = ca.diag(xs) @ Wcs
        for j in range(1, d + 1):
            opti.subject_to(ca.vec(h * Wc[:, (j - 1)::d] - cols[j - 1]) == 0)
        Fm = dae.F.map(N * d)
        Ucol = ca.horzcat(*[U[:, k] @ np.ones((1, d)) for k in range(N)])  # u held on each interval
        Pm = ca.repmat(ca.DM(self.p), 1, N * d)
        res = Fm(Wc, Xc, Zc if nz else ca.DM(0, N * d), Ucol, Pm)
        # residual scaling: row norms of the scaled Jacobian at the start (equations in N, N m, m/s...)
        rs = self._residual_scales(xs, us)
        opti.subject_to(ca.vec(ca.diag(1.0 / rs) @ res) == 0)
        opti.subject_to(ca.vec(X[:, 1:] - Xc[:, (d - 1)::d]) == 0)
        # boundary conditions
        x0 = dae.x_start.copy()
        for k, v in self.x_init.items():
            x0[dae.x_names.index(k)] = v
        opti.subject_to(Xs[:, 0] == x0 / xs)
        for k, v in self.x_final.items():
            i = dae.x_names.index(k)
            opti.subject_to(Xs[i, N] == v / xs[i])
        if self.final_rest:
            for i, n in enumerate(dae.x_names):
                if n.startswith("der("):
                    opti.subject_to(Xs[i, N] == 0)
        # path bounds
        y_names = [n for n in self.bounds if self._kind(n) == "y"]
        obj_y = []
        if self.objective_kind in ("tracking", "vibration"):
            obj_y = [self.objective_args["output"]]
        all_y = list(dict.fromkeys(y_names + obj_y))
        Yc = None
        if all_y:
            g = dae.output_function(all_y).map(N * d)
            Yc = g(Wc, Xc, Zc if nz else ca.DM(0, N * d), Ucol, Pm)
        for n, (lo, hi) in self.bounds.items():
            kind = self._kind(n)
            if kind == "u":
                i = dae.u_names.index(n)
                expr, s = Us[i, :], us[i]
            elif kind == "x":
                i = dae.x_names.index(n)
                expr, s = ca.horzcat(Xs[i, :], Xcs[i, :]), xs[i]
            else:
                i = all_y.index(n)
                s = self._nominal(n)
                expr = Yc[i, :] / s
            if np.isfinite(lo):
                opti.subject_to(ca.vec(expr) >= lo / s)
            if np.isfinite(hi):
                opti.subject_to(ca.vec(expr) <= hi / s)
        # objective (quadrature with Radau weights)
        B = np.zeros(d)
        for j in range(1, d + 1):
            p = np.poly1d([1.0])
            for r in range(d + 1):
                if r != j:
                    p *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
            P = np.polyint(p)
            B[j - 1] = P(1.0) - P(0.0)
        wq = np.tile(B, N)
        kind = self.objective_kind
        if kind == "time":
            J = T
        elif kind == "effort":
            w = np.array([self.objective_args["weights"].get(n, 1.0) for n in dae.u_names])
            J = h * ca.sum2(ca.sum1(ca.diag(w) @ (Us**2)))
        elif kind == "tracking":
            tc = np.concatenate([(k + tau[1:]) * (self.T_fixed / N) for k in range(N)])
            ref = np.array([self.objective_args["reference"](t) for t in tc])
            s = self._nominal(self.objective_args["output"])
            e = (Yc[0, :] - ref[None, :]) / s
            J = h * ca.sum2(e**2 * wq[None, :]) + self.objective_args["effort_weight"] * h * ca.sumsqr(Us)
        else:
            tc = np.concatenate([(k + tau[1:]) * (self.T_fixed / N) for k in range(N)])
            mask = (tc >= self.T_fixed - self.objective_args["T_settle"]).astype(float)
            s = self._nominal(self.objective_args["output"])
            e = Yc[0, :] / s
            J = h * ca.sum2(e**2 * (wq * mask)[None, :])
        opti.minimize(J)
        # initial guess
        if self.warm is not None and self.warm.x.shape == (N + 1, nx):
            opti.set_initial(Xs, (self.warm.x / xs).T)
            opti.set_initial(Us, (self.warm.u / us).T)
            if self.T_fixed is None:
                opti.set_initial(T, self.warm.T)
        else:
            xf = self._rest_guess(x0)
            lin = np.linspace(0, 1, N + 1)[None, :]
            guess = (x0 / xs)[:, None] * (1 - lin) + (xf / xs)[:, None] * lin
            opti.set_initial(Xs, guess)
            opti.set_initial(Xcs, np.repeat(guess[:, 1:], d, axis=1))
        opts = {"ipopt": dict(self.ipopt_options, **(solver_options or {})), "print_time": False, "expand": True}
        opti.solver("ipopt", opts)
        try:
            sol = opti.solve()
            stats = opti.stats()
        except RuntimeError as exc:
            stats = opti.stats()
            try:
                viol = float(np.max(np.abs(opti.debug.value(opti.g))))
            except Exception:  # noqa: BLE001 - diagnostic only
                viol = float("nan")
            raise OcpError(
                f"Ipopt did not converge on '{dae.name}' (status: {stats.get('return_status')}, iterations "
                f"{stats.get('iter_count')}, largest constraint violation {viol:.3g}). Hints: check that the final "
                "state is reachable within the bounds, give a better T_guess or warm start, loosen bounds, or "
                "give scale= for signals of very different magnitudes") from exc
        Xv = np.atleast_2d(sol.value(X)).reshape(nx, N + 1).T
        Uv = np.atleast_2d(sol.value(U)).reshape(nu, N).T
        Tv = float(sol.value(T)) if self.T_fixed is None else self.T_fixed
        t = np.linspace(0, Tv, N + 1)
        outputs = {}
        if all_y:
            Ycv = np.atleast_2d(sol.value(Yc)).reshape(len(all_y), N * d)
            for i, n in enumerate(all_y):
                outputs[n] = np.r_[self._y0(n, Xv[0], Uv[0]), Ycv[i, (d - 1)::d]]
        active = {}
        for n, (lo, hi) in self.bounds.items():
            if n in outputs:
                v = outputs[n]
            elif n in dae.u_names:
                v = Uv[:, dae.u_names.index(n)]
            else:
                v = Xv[:, dae.x_names.index(n)]
            span = max(abs(lo) if np.isfinite(lo) else 0, abs(hi) if np.isfinite(hi) else 0, 1e-300)
            act = np.zeros(len(v), bool)
            if np.isfinite(lo):
                act |= v <= lo + 1e-4 * span
            if np.isfinite(hi):
                act |= v >= hi - 1e-4 * span
            active[n] = float(np.mean(act))
        return OcpResult(T=Tv, t=t, x=Xv, u=Uv, outputs=outputs, x_names=list(dae.x_names),
                         u_names=list(dae.u_names), active=active,
                         stats={"return_status": stats.get("return_status"), "iter_count": stats.get("iter_count"),
                                "t_wall_total": stats.get("t_wall_total")}, dae=dae, p=self.p)

    def _rest_guess(self, x0):
        """Final-state guess: the least-strain static configuration that meets the final values
        (``min ½ dqᵀ K dq`` subject to the given coordinates), so an elastic drive is guessed to move
        along its rigid-body mode instead of stretching its stiffest joint."""
        dae = self.dae
        xf = x0.copy()
        for k, v in self.x_final.items():
            xf[dae.x_names.index(k)] = v
        m = dae.mech
        pos = [m.q_in_x[j] for j in sorted(m.q_in_x)]
        fixed = [i for i in pos if dae.x_names[i] in self.x_final]
        free = [i for i in pos if i not in fixed]
        if not fixed or not free:
            return xf
        xd, z = dae.initialize(x0, np.zeros(dae.nu), self.p, store=False)
        _, _, Jx, _, _ = dae.jacobians(xd, x0, z, np.zeros(dae.nu), self.p)
        Jx = np.asarray(ca.DM(Jx))
        rows = [m.balance_rows[j] for j in sorted(m.q_in_x)]
        K = Jx[np.ix_(rows, pos)]
        K = 0.5 * (K + K.T)
        fi = [pos.index(i) for i in fixed]
        fr = [pos.index(i) for i in free]
        d_fixed = xf[fixed] - x0[fixed]
        try:
            d_free = np.linalg.lstsq(K[np.ix_(fr, fr)], -K[np.ix_(fr, fi)] @ d_fixed, rcond=None)[0]
        except np.linalg.LinAlgError:
            return xf
        xf[free] = x0[free] + d_free
        return xf

    def _state_nominals(self):
        """Nominal magnitudes of the states: given scales, bounds, boundary values; a velocity without
        any of these gets 2 |Δq| / T from its position's boundary change (a triangular profile)."""
        dae = self.dae
        xs = np.array([self._nominal(n, default=np.nan) for n in dae.x_names])
        T = self.T_fixed or self.T_guess
        for i, n in enumerate(dae.x_names):
            if np.isnan(xs[i]) and n.startswith("der(") and n[4:-1] in dae.x_names:
                q = n[4:-1]
                dq = abs(self.x_final.get(q, 0.0) - self.x_init.get(q, 0.0))
                if dq > 0:
                    xs[i] = 2 * dq / T
        return np.where(np.isnan(xs) | (xs <= 0), 1.0, xs)

    def _residual_scales(self, xs, us):
        dae = self.dae
        x0 = dae.x_start.copy()
        xd, z = dae.initialize(x0, np.zeros(dae.nu), self.p)
        _, Jxd, Jx, Jz, Ju = dae.jacobians(xd, x0, z, np.zeros(dae.nu), self.p)
        T = self.T_fixed or self.T_guess
        cols = [np.abs(np.asarray(ca.DM(Jxd))) * (xs / T)[None, :], np.abs(np.asarray(ca.DM(Jx))) * xs[None, :],
                np.abs(np.asarray(ca.DM(Ju))) * us[None, :]]
        if dae.nz:
            cols.append(np.abs(np.asarray(ca.DM(Jz))))
        rs = np.max(np.hstack(cols), axis=1)
        return np.where(rs > 0, rs, 1.0)

    def _y0(self, name, x0, u0):
        xd, z = self.dae.initialize(x0, u0, self.p)
        return float(self.dae.output_function([name])(xd, x0, z, u0, self.p))
