"""Optimal control of a flattened drive model with Ipopt (through CasADi).

The problem is stated on the model's names (states, inputs, observables) and transcribed by direct
collocation (Radau IIA, degree ``d``) of the implicit DAE ``F(x', x, z, u, p) = 0``: on interval k with
length h, the state polynomial through ``x_k, x_k1..x_kd`` gives ``x'(t_kj)`` and the residual is
imposed at every collocation point; inputs are piecewise constant (what a sampled drive applies).
Variables are scaled by nominal magnitudes (given ``scale``, bounds, boundary values, else the largest
value along a reference motion of the linearized model, see :meth:`Ocp.reference`), so µm and kN live
in one problem; the reference motion is also the cold-start guess. The transcription is chosen apart
from the model: the Dae is not touched. Linear models can be transcribed in modal coordinates with the
states eliminated or kept (``Ocp(..., coordinates="modal")``), and a residual-vibration limit after arrival is
available for any linear(ized) model (:meth:`Ocp.limit_residual_vibration`).

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

from bscomp.errors import BscompError, UnknownNameError
from bscomp.linear.linearize import resolve_model

__all__ = ["Ocp", "OcpResult", "OcpError"]

# coordinates="modal" keeps the modal states as collocation variables (sparse) above this many states and
# eliminates them (condensed: inputs and T the only unknowns, O(N² nx) expressions) up to it
SPARSE_MODAL_NX = 40


def active_fraction(v, lo, hi) -> float:
    """Fraction of the values ``v`` within 1e-4 (relative to the larger finite bound) of ``lo`` or ``hi``."""
    v = np.asarray(v, float)
    span = max(abs(lo) if np.isfinite(lo) else 0, abs(hi) if np.isfinite(hi) else 0, 1e-300)
    act = np.zeros(len(v), bool)
    if np.isfinite(lo):
        act |= v <= lo + 1e-4 * span
    if np.isfinite(hi):
        act |= v >= hi - 1e-4 * span
    return float(np.mean(act))


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
    active : dict name -> fraction of points where the bound is active (within 1e-4 of it); rate limits as
        ``"rate:<name>"`` (fraction of intervals at the limit)
    residual : dict name -> certified residual-vibration amplitude after arrival (unit of the output), for
        the outputs given to :meth:`Ocp.limit_residual_vibration` (see there)
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
    xd: Any = None
    z: Any = None
    residual: dict = field(default_factory=dict)

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.x_names:
            return self.x[:, self.x_names.index(name)]
        if name in self.u_names:
            return self.u[:, self.u_names.index(name)]
        if self.dae is not None and self.xd is not None and name in self.dae.observables:
            # any other observable, from the solution at the grid points (input of the interval ending there)
            n = len(self.t)
            uk = np.vstack([self.u[:1], self.u])
            y = self.dae.output_function([name]).map(n)(self.xd.T, self.x.T, self.z.T, uk.T,
                                                        np.tile(np.asarray(self.p)[:, None], (1, n)))
            self.outputs[name] = np.asarray(y).ravel()
            return self.outputs[name]
        raise UnknownNameError(f"no signal '{name}' in this OCP result")

    def input_function(self, name) -> Callable:
        """The optimal piecewise-constant input as a function of time (for :func:`simulate`)."""
        u = self[name]
        t = self.t

        def f(tt):
            k = min(max(int(np.searchsorted(t, tt, side="right") - 1), 0), len(u) - 1)
            return u[k]
        return f

    def resimulate(self, model=None, outputs=None, n_per_interval=10, names: dict | None = None, **kw):
        """Run the optimal input through :func:`bscomp.simulation.simulate` on the same model (default)
        or another one (e.g. the full model the OCP's reduced model came from); returns
        (SimulationResult, deviation per name). The deviation of a recorded output or state is
        ``max_t |sim(t) - ocp(t)| / max_t |ocp(t)|``, the OCP values interpolated linearly between its
        grid points; states are recorded by naming them in ``outputs`` too. ``names`` maps this result's
        names to the other model's (e.g. ``{"plant.motor_tau": "motor.tau", "plant.table_s": "table.s"}``
        for a reduced model in a SecondOrderBlock); inputs not in the other model must be mapped or be
        zero, else :class:`OcpError`. The SimulationResult uses the other model's names; ``dev`` this
        result's. Further keywords go to ``simulate`` (e.g. ``method="lti"`` for a linear model)."""
        from bscomp.simulation.dispatch import simulate

        names = dict(names or {})
        model = resolve_model(model) if model is not None else self.dae
        outputs = list(outputs or self.outputs)
        tt = np.linspace(self.t[0], self.t[-1], n_per_interval * (len(self.t) - 1) + 1)
        inputs = {}
        for n in self.u_names:
            m = names.get(n, n)
            if m in model.u_names:
                inputs[m] = self.input_function(n)
            elif np.any(self[n] != 0.0):
                raise OcpError(f"resimulate: input '{n}' of the OCP is not an input of '{model.name}' "
                               f"({model.u_names}); map it with names={{'{n}': ...}}")
        x0 = {names.get(n, n): v for n, v in zip(self.x_names, self.x[0]) if names.get(n, n) in model.x_names}
        r = simulate(model, tt, inputs=inputs, x0=x0,
                     outputs=[names.get(n, n) for n in outputs if names.get(n, n) not in model.x_names], **kw)
        dev = {}
        for n in outputs:
            if n in self.outputs or n in self.x_names or (self.xd is not None and n in self.dae.observables):
                ref = np.interp(tt, self.t, self[n])
                dev[n] = float(np.max(np.abs(r[names.get(n, n)] - ref)) / max(np.max(np.abs(ref)), 1e-300))
        return r, dev

    def plot(self, names=None, path=None, title="optimal control"):
        from bscomp.plotting.base import time_plot

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
    coordinates : {"physical", "modal", "modal-condensed", "modal-sparse"}
        ``"modal"`` (linear models only): transcribe in the real modal coordinates ``ξ`` of the model's
        state matrix, ``x = x0 + P ξ``, ``ξ' = Λ ξ + P⁻¹ (B u + x'0)`` with ``Λ`` block diagonal (one
        2 x 2 block ``[[σ, ω], [-ω, σ]]`` per mode, 1 x 1 for real eigenvalues, one block for the rigid-body
        zero eigenvalues; see :mod:`bscomp.optimal.modal`). An exact change of coordinates: the optimum is
        the same, but every damping -- modal, discrete, non-proportional -- sits in the 2 x 2 blocks, so
        the collocation Jacobian has ~2 non-zeros per state instead of the dense rows of a modal damping
        matrix, and the modes are scaled one by one. Bounds, final values and outputs keep the model's
        names (they become rows of ``P``); the result is mapped back to the original states.
        Transcription: ``"modal-condensed"`` eliminates the states (inputs and T the only unknowns;
        O(N² nx) expressions), ``"modal-sparse"`` keeps the scaled modal collocation states as variables
        (O(N nx) sparse rows); ``"modal"`` chooses condensed up to ``SPARSE_MODAL_NX`` states, sparse above.
    """

    def __init__(self, model, N: int = 100, degree: int = 3, params: dict | None = None,
                 coordinates: str = "physical"):
        if coordinates not in ("physical", "modal", "modal-condensed", "modal-sparse"):
            raise ValueError("coordinates must be 'physical', 'modal', 'modal-condensed' or 'modal-sparse', not "
                             f"{coordinates!r}")
        self.coordinates = coordinates
        self.dae = resolve_model(model, params)
        self.p = self.dae.parameter_vector({k: v for k, v in (params or {}).items()
                                            if k not in self.dae.structural_parameters})
        self.N, self.d = int(N), int(degree)
        self.bounds: dict[str, tuple] = {}
        self.rate_limits: dict[str, float] = {}
        self.x_init: dict[str, float] = {}
        self.x_final: dict[str, float] = {}
        self.final_rest = False
        self.T_fixed: float | None = None
        self.T_guess = 1.0
        self.objective_kind = None
        self.objective_args: dict = {}
        self.scale: dict[str, float] = {}
        self.warm: OcpResult | None = None
        self.residual_limits: dict[str, float] = {}
        self.rest_below_hz: float | None = None
        self.hold: dict[str, float] = {}
        self._terminal = None    # (rows over x, targets): linear final conditions (modal transcription)
        self._modal = None
        # MUMPS's default pivot tolerance (1e-6) gives inaccurate steps on the KKT systems of stiff
        # structures (stiffnesses of 1e8 N/m next to a free rigid-body mode): Ipopt then creeps for
        # hundreds of iterations. 1e-2 costs little and brought the reduced test bed from ~300 to ~15.
        self.ipopt_options = {"print_level": 0, "max_iter": 3000, "tol": 1e-8, "mumps_pivtol": 1e-2,
                              "mu_strategy": "adaptive"}
        self.expand = False      # MX maps: faster to build than SX expansion for N*d*nx in the 1e4s

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

    def bound_rate(self, name, limit):
        """Rate limit ``|d(name)/dt| <= limit`` on an input, state or observable, e.g. a **jerk limit**
        ``bound_rate("table.a", j_max)`` [m/s³] or a torque slew rate ``bound_rate("motor.tau", r)`` [N m/s].

        Measured on the transcription's grid: the change of the value between the ends of consecutive
        intervals (for an input: between consecutive piecewise-constant values), from the value before
        the move (the model at rest with its free inputs at 0) to the end of the first interval, and from
        the end of the last interval to the value just after arrival (final state, inputs held as in
        :meth:`limit_residual_vibration`, default 0: a jerk limit thus also brings the acceleration back
        to zero), each divided by the interval length ``h = T/N``: ``|y_{k+1} - y_k| <= limit h``. For an
        output that a piecewise-constant input moves in steps (the acceleration of a rigid inertia under a
        torque staircase) this is the average rate of the staircase; as N grows the minimum time
        converges to the continuous one (tested against the analytic jerk-limited move). Physical
        coordinates only.
        """
        self._kind(name)
        if not limit > 0:
            raise ValueError(f"rate limit on '{name}' must be > 0, not {limit}")
        self.rate_limits[name] = float(limit)
        return self

    def initial(self, values: dict):
        """Initial state values by name (others at the model's start values: at rest)."""
        for k in values:
            if self._kind(k) != "x":
                raise UnknownNameError(f"initial value for '{k}': only states can be given")
        self.x_init.update({k: float(v) for k, v in values.items()})
        return self

    def final(self, values: dict, rest: bool = True, rest_below_hz: float | None = None):
        """Final state values by name.

        ``rest=True`` also sets every velocity state to zero at the end. ``rest_below_hz=f`` replaces that
        by arrival at *equilibrium* of the modes of the linear(ized) model slower than ``f`` [Hz]
        (``|λ| < 2π f``, the rigid-body velocity mode included): each such mode's coordinates are at their
        static values under the held input (see :meth:`limit_residual_vibration`), so those modes carry
        no residual vibration; faster modes are left free. On a detailed model (the 98-DOF test bed has
        modes to 180 kHz) ``rest=True`` asks the piecewise-constant input to stop modes it cannot resolve:
        with N intervals and ~N velocities to zero the problem is square and degenerate (measured: Ipopt
        stalls at a constraint violation of 3e-6). Choose ``f`` like the cut-off of a reduced model.
        """
        for k in values:
            if self._kind(k) != "x":
                raise UnknownNameError(f"final value for '{k}': only states can be given")
        self.x_final.update({k: float(v) for k, v in values.items()})
        self.final_rest = bool(rest) and rest_below_hz is None
        self.rest_below_hz = None if rest_below_hz is None else float(rest_below_hz)
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

    def limit_residual_vibration(self, limits: dict, hold: dict | None = None):
        """Limit the residual vibration after arrival (linear models; linearized at the start otherwise).

        After ``T`` the inputs are *held* at ``hold`` (by name; default 0 for every input, or the value
        of an input fixed by ``bound(name, v, v)``) -- e.g. the motor torque released at arrival. From the
        state at ``T`` the model then moves freely to an equilibrium; for every output ``y`` in ``limits``
        the constraint guarantees ``|y(t) - y(∞)| <= limits[y]`` for **all** ``t >= T`` (unit of ``y``:
        m for ``table.s``, m/s² for ``table.a``, ...). With ``final(..., rest=True)`` and ``y`` the
        position given in ``final``, ``y(∞)`` is also within the limit of the target, so the move settles
        to ``± limit`` at arrival.

        Measure: the free response is a sum of damped modes, ``y(t) - y(∞) = Σ_k C P_k e^{Λ_k (t-T)} e_k``
        (``e_k``: the modal distance of the state at ``T`` from the equilibrium under the held input), so
        ``|y(t) - y(∞)| <= Σ_k G_k |e_k|`` with ``G_k = |C P_k|``; the constraint is the Cauchy-Schwarz
        bound ``sqrt(Σ G_k) sqrt(Σ G_k |e_k|²) <= limit``, one smooth convex inequality on the final state
        (see :func:`bscomp.optimal.modal.residual_rows`). It is a guarantee, conservative by at most
        ``sqrt(Σ G_k / G_max)`` when one mode dominates. Unlike an equality "accelerations zero at T", it
        does not fight the piecewise-constant input on the last interval: the input jumps to the held value
        at ``T`` and the bound is on what follows. ``OcpResult.residual`` reports the bound at the optimum.
        Raises :class:`OcpError` at solve time if the limits cannot be met (with the bound reached).
        """
        for k, v in limits.items():
            if self._kind(k) == "u":
                raise UnknownNameError(f"residual-vibration limit on '{k}': give an output or a state, not an input")
            if not v > 0:
                raise ValueError(f"residual-vibration limit on '{k}' must be > 0, not {v}")
        for k in hold or {}:
            if self._kind(k) != "u":
                raise UnknownNameError(f"hold value for '{k}': only inputs can be held")
        self.residual_limits.update({k: float(v) for k, v in limits.items()})
        self.hold.update({k: float(v) for k, v in (hold or {}).items()})
        return self

    def _hold_vector(self):
        u = np.zeros(self.dae.nu)
        for i, n in enumerate(self.dae.u_names):
            if n in self.hold:
                u[i] = self.hold[n]
            elif n in self.bounds and self.bounds[n][0] == self.bounds[n][1]:
                u[i] = self.bounds[n][0]
        return u

    def _terminal_rows(self, lin):
        """Linear final conditions ``R x_T = t`` beyond the named final values: the modal transcription's rows
        and the equilibrium rows of ``final(rest_below_hz=...)``; None if there are none."""
        parts = [r for r in (self._terminal, self._equilibrium_rows(lin)) if r is not None and len(r[1])]
        if not parts:
            return None
        return np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _equilibrium_rows(self, lin):
        """Rows ``(R, t)``, ``R x_T = t``: the modes with ``|λ| < 2π rest_below_hz`` at their equilibrium under
        the held input (``e_k = 0`` in :func:`bscomp.optimal.modal.residual_rows`)."""
        from bscomp.optimal.modal import ModalDae, modal_basis

        if self.rest_below_hz is None:
            return None
        if lin is None:
            raise OcpError("final(rest_below_hz=...) needs a model that can be linearized at the start")
        basis = self.dae.self_basis if isinstance(self.dae, ModalDae) else modal_basis(lin["A"])
        b = lin["xd0"] + lin["B"] @ self._hold_vector()
        pb = basis["Pinv"] @ b
        R, t = [], []
        for idx, kind, lam in basis["blocks"]:
            if kind == "zero" or abs(lam) >= 2 * np.pi * self.rest_below_hz:
                continue
            Lk = basis["Lam"][np.ix_(idx, idx)]
            R.append(basis["Pinv"][idx])
            t.append(basis["Pinv"][idx] @ lin["x0"] - np.linalg.solve(Lk, pb[idx]))
        if not R:
            return None
        return np.vstack(R), np.concatenate(t)

    def _residual_rows(self, lin):
        """{name: (L, l)}: ``|L (x_T - x0) + l| <= limit`` (see :meth:`limit_residual_vibration`)."""
        from bscomp.optimal.modal import ModalDae, ModalError, output_rows, residual_rows

        if not self.residual_limits:
            return {}
        if lin is None:
            raise OcpError("limit_residual_vibration needs a model that can be linearized at the start")
        dae = self.dae
        names = list(self.residual_limits)
        if isinstance(dae, ModalDae):
            _, C, _ = dae.rows(names)
            basis = dae.self_basis
        else:
            _, C, _ = output_rows(dae, self.p, dict(lin, u0=np.zeros(dae.nu)), names)
            basis = None
        out = {}
        for r, n in enumerate(names):
            try:
                out[n] = residual_rows(lin, C[r], None, self._hold_vector(), basis=basis)
            except ModalError as exc:
                raise OcpError(f"residual-vibration limit on '{n}': {exc}") from exc
        return out

    def warm_start(self, result: OcpResult):
        self.warm = result
        return self

    # ---- transcription and solve ----------------------------------------------------------------
    def _nominal(self, name, default=1.0):
        """Nominal magnitude given by the user: ``scale=``, else the largest finite bound or boundary value."""
        if name in self.scale:
            return self.scale[name]
        vals = [abs(v) for v in self.bounds.get(name, ()) if np.isfinite(v)]
        vals += [abs(self.x_init.get(name, 0.0)), abs(self.x_final.get(name, 0.0))]
        m = max(vals) if vals else 0.0
        return m if m > 0 else default

    def _x0(self):
        x0 = self.dae.x_start.copy()
        for k, v in self.x_init.items():
            x0[self.dae.x_names.index(k)] = v
        return x0

    def solve(self, solver_options: dict | None = None) -> OcpResult:
        """Transcribe and solve with Ipopt; raises :class:`OcpError` if it does not converge.

        Notes
        -----
        Scaling and the cold-start guess come from a *reference motion* (see :meth:`reference`): the
        minimum-effort rest-to-rest move of the model linearized at the start, over ``T_guess``,
        propagated with the transcription's own Radau steps. Every state, state derivative, algebraic
        variable and input is scaled by its largest magnitude along that motion (unless a bound,
        boundary value or ``scale=`` gives one), so a rotor angle of 60 rad and a screw stretch of 1 µm
        are both O(1) unknowns; each residual row is divided by its largest scaled term. A warm start
        replaces the reference motion by the given solution (interpolated if its N differs).
        """
        dae, N, d = self.dae, self.N, self.d
        if self.objective_kind is None:
            raise OcpError("no objective: call minimize_time(), minimize_effort(), minimize_tracking() or "
                           "minimize_residual_vibration() first")
        if self.coordinates.startswith("modal"):
            return self._solve_modal(solver_options)
        nx, nz, nu = dae.nx, dae.nz, dae.nu
        tau, C = _radau(d)
        x0 = self._x0()
        lin = self._linearize(x0)
        T0, ref = self._start(lin)
        xs, ws, zs, us = self._scales(ref)
        opti = ca.Opti()
        Xs = opti.variable(nx, N + 1)
        Xcs = opti.variable(nx, N * d)
        Wcs = opti.variable(nx, N * d)   # state derivatives at the collocation points, scaled by ws
        Zcs = opti.variable(nz, N * d) if nz else None
        # inputs held at a value (bound lo == hi, e.g. a disturbance force at 0) are constants, not unknowns
        fixed_u = {i: self.bounds[n][0] for i, n in enumerate(dae.u_names)
                   if n in self.bounds and self.bounds[n][0] == self.bounds[n][1]}
        free_u = [i for i in range(nu) if i not in fixed_u]
        Uv = opti.variable(len(free_u), N)
        rows_u = [Uv[free_u.index(i), :] if i in free_u else ca.DM(np.full((1, N), fixed_u[i] / us[i]))
                  for i in range(nu)]
        Us = ca.vertcat(*rows_u) if nu else ca.MX(0, N)
        X, Xc, Wc = ca.diag(xs) @ Xs, ca.diag(xs) @ Xcs, ca.diag(ws) @ Wcs
        Zc = ca.diag(zs) @ Zcs if nz else ca.DM(0, N * d)
        U = ca.diag(us) @ Us
        if self.T_fixed is None:
            Tsc = opti.variable()          # T in units of its guess
            T = T0 * Tsc
            opti.subject_to(Tsc >= 1e-6)
            opti.set_initial(Tsc, ref["T"] / T0)
        else:
            T = self.T_fixed
        h = T / N
        # collocation (Radau IIA): h x'(t_kj) = sum_r C[r, j] x_kr, each row in units of its state nominal
        for j in range(1, d + 1):
            terms = C[0, j] * Xs[:, :N]
            for r in range(1, d + 1):
                terms = terms + C[r, j] * Xcs[:, (r - 1)::d]
            opti.subject_to(ca.vec(h * ca.diag(ws / xs) @ Wcs[:, (j - 1)::d] - terms) == 0)
        opti.subject_to(ca.vec(Xs[:, 1:] - Xcs[:, (d - 1)::d]) == 0)
        Ucol = ca.horzcat(*[U[:, k] @ np.ones((1, d)) for k in range(N)])  # u held on each interval
        Pm = ca.repmat(ca.DM(self.p), 1, N * d)
        res = dae.F.map(N * d)(Wc, Xc, Zc, Ucol, Pm)
        rs = self._residual_scales(lin, xs, ws, zs, us)
        opti.subject_to(ca.vec(ca.diag(1.0 / rs) @ res) == 0)
        # boundary conditions
        opti.subject_to(Xs[:, 0] == x0 / xs)
        for k, v in self.x_final.items():
            i = dae.x_names.index(k)
            opti.subject_to(Xs[i, N] == v / xs[i])
        if self.final_rest:
            for i, n in enumerate(dae.x_names):
                if n.startswith("der("):
                    opti.subject_to(Xs[i, N] == 0)
        term = self._terminal_rows(lin)
        if term is not None:
            Ct, tt = term
            CtS = Ct * xs[None, :]
            sc = np.max(np.abs(CtS), axis=1)
            sc = np.where(sc > 0, sc, 1.0)
            opti.subject_to(ca.mtimes(ca.DM(CtS / sc[:, None]), Xs[:, N]) == ca.DM(tt / sc))
        # residual vibration after arrival: |L (x_T - x0) + l| <= limit, in units of the limit
        res_expr = {}
        for n, (L, l_) in self._residual_rows(lin).items():
            lim = self.residual_limits[n]
            e = ca.mtimes(ca.DM(L * xs[None, :] / lim), Xs[:, N]) + ca.DM((l_ - L @ x0) / lim)
            res_expr[n] = ca.sqrt(ca.sumsqr(e)) * lim
            opti.subject_to(ca.sumsqr(e) <= 1.0)
        # path bounds
        y_names = [n for n in list(self.bounds) + list(self.rate_limits) if self._kind(n) == "y"]
        obj_y = [self.objective_args["output"]] if self.objective_kind in ("tracking", "vibration") else []
        all_y = list(dict.fromkeys(y_names + obj_y))
        Yc = dae.output_function(all_y).map(N * d)(Wc, Xc, Zc, Ucol, Pm) if all_y else None
        ys = {n: self._nominal(n, default=np.nan) for n in all_y}
        if Yc is not None and ref is not None:
            Yref = np.atleast_2d(np.asarray(dae.output_function(all_y).map(N * d)(
                ref["W"], ref["Xc"], ref["Z"], np.repeat(ref["U"].T, d, axis=1), np.tile(self.p[:, None], (1, N * d)))))
            for i, n in enumerate(all_y):
                if np.isnan(ys[n]):
                    m = float(np.max(np.abs(Yref[i]))) if Yref.size else 0.0
                    ys[n] = m if m > 0 else 1.0
        for n, (lo, hi) in self.bounds.items():
            kind = self._kind(n)
            if kind == "u":
                i = dae.u_names.index(n)
                if i in fixed_u:
                    continue
                expr, s = Us[i, :], us[i]
            elif kind == "x":
                i = dae.x_names.index(n)
                expr, s = ca.horzcat(Xs[i, :], Xcs[i, :]), xs[i]
            else:
                s = ys[n]
                expr = Yc[all_y.index(n), :] / s
            if lo == hi:
                opti.subject_to(ca.vec(expr) == lo / s)
                continue
            if np.isfinite(lo) and np.isfinite(hi):
                opti.subject_to(opti.bounded(lo / s, ca.vec(expr), hi / s))
            elif np.isfinite(lo):
                opti.subject_to(ca.vec(expr) >= lo / s)
            elif np.isfinite(hi):
                opti.subject_to(ca.vec(expr) <= hi / s)
        # rate limits: |v_{k+1} - v_k| <= limit h between interval ends, from the value before the move to
        # the value after arrival (the model at its final state with the held input)
        rate_expr = {}
        after = {}
        if self.rate_limits:
            u_before = np.array([fixed_u.get(i, 0.0) for i in range(nu)])
            xd_b, z_b = dae.initialize(x0, u_before, self.p, store=False)
            u_hold = self._hold_vector()
            if any(self._kind(n) == "y" for n in self.rate_limits):
                # (x', z) just after arrival: consistent with the final state and the held input
                XDa = opti.variable(nx)
                opti.set_initial(XDa, np.zeros(nx))
                xd_a = ca.diag(ws) @ XDa
                if nz:
                    Za = opti.variable(nz)
                    opti.set_initial(Za, ref["Z"][-1] / zs)
                    z_a = ca.diag(zs) @ Za
                else:
                    z_a = ca.DM(0, 1)
                opti.subject_to(ca.diag(1.0 / rs) @ dae.F(xd_a, X[:, N], z_a, u_hold, self.p) == 0)
                after = {"xd": xd_a, "z": z_a}
        for n, lim in self.rate_limits.items():
            kind = self._kind(n)
            if kind == "u":
                i = dae.u_names.index(n)
                seq, first, last = U[i, :], u_before[i], u_hold[i]
            elif kind == "x":
                i = dae.x_names.index(n)
                seq, first, last = X[i, 1:], x0[i], None          # a state does not jump at arrival
            else:
                yf = dae.output_function([n])
                seq = Yc[all_y.index(n), (d - 1)::d]
                first = float(np.asarray(yf(xd_b, x0, z_b, u_before, self.p)).ravel()[0])
                last = yf(after["xd"], X[:, N], after["z"], u_hold, self.p)
            parts = [seq[:, 0] - first, seq[:, 1:] - seq[:, :-1]]
            if last is not None:
                parts.append(last - seq[:, -1])
            diff = ca.horzcat(*parts)                                           # (1, N or N+1)
            h0 = T0 / N
            g = diff / (lim * h0)                                               # in units of the allowed step
            hs = h / h0
            opti.subject_to(ca.vec(g - hs) <= 0)
            opti.subject_to(ca.vec(-g - hs) <= 0)
            rate_expr[n] = diff / h
        # objective (quadrature with Radau weights)
        wq = np.tile(_radau_weights(tau, d), N)
        kind = self.objective_kind
        if kind == "time":
            J = T / T0
        elif kind == "effort":
            w = np.array([self.objective_args["weights"].get(n, 1.0) for n in dae.u_names])
            J = h * ca.sum2(ca.sum1(ca.diag(w) @ (Us**2)))
        elif kind == "tracking":
            tc = np.concatenate([(k + tau[1:]) * (self.T_fixed / N) for k in range(N)])
            ref_t = np.array([self.objective_args["reference"](t) for t in tc])
            s = ys[self.objective_args["output"]]
            e = (Yc[all_y.index(self.objective_args["output"]), :] - ref_t[None, :]) / s
            J = h * ca.sum2(e**2 * wq[None, :]) + self.objective_args["effort_weight"] * h * ca.sumsqr(Us)
        else:
            tc = np.concatenate([(k + tau[1:]) * (self.T_fixed / N) for k in range(N)])
            mask = (tc >= self.T_fixed - self.objective_args["T_settle"]).astype(float)
            s = ys[self.objective_args["output"]]
            e = Yc[all_y.index(self.objective_args["output"]), :] / s
            J = h * ca.sum2(e**2 * (wq * mask)[None, :])
        opti.minimize(J)
        # initial guess: the reference motion (or the warm start)
        opti.set_initial(Xs, (ref["X"] / xs).T)
        opti.set_initial(Xcs, ref["Xc"] / xs[:, None])
        opti.set_initial(Wcs, ref["W"] / ws[:, None])
        if nz:
            opti.set_initial(Zcs, ref["Z"] / zs[:, None])
        if free_u:
            opti.set_initial(Uv, (ref["U"][:, free_u] / us[free_u]).T)
        ipopt = dict(self.ipopt_options, **(solver_options or {}))
        opti.solver("ipopt", {"ipopt": ipopt, "print_time": False, "expand": self.expand,
                              "detect_simple_bounds": True})
        try:
            sol = opti.solve()
            stats = opti.stats()
        except RuntimeError as exc:
            stats = opti.stats()
            try:
                viol = float(np.max(np.abs(opti.debug.value(opti.g))))
            except Exception:  # noqa: BLE001 - diagnostic only
                viol = float("nan")
            vib = ""
            if res_expr:
                parts = []
                for n, e in res_expr.items():
                    try:
                        parts.append(f"'{n}' {float(opti.debug.value(e)):.3g} (limit {self.residual_limits[n]:.3g})")
                    except Exception:  # noqa: BLE001 - diagnostic only
                        parts.append(f"'{n}' ? (limit {self.residual_limits[n]:.3g})")
                vib = (" Residual-vibration bound at the last iterate: " + ", ".join(parts) + "; a limit below what "
                       "the input grid can reach is infeasible: raise N (finer torque shaping before arrival) or the "
                       "limit, or add time (fixed-T problems).")
            raise OcpError(
                f"Ipopt did not converge on '{dae.name}' (status: {stats.get('return_status')}, iterations "
                f"{stats.get('iter_count')}, largest scaled constraint violation {viol:.3g}).{vib} Hints: check that "
                "the final state is reachable within the bounds, give a better T_guess or warm start, loosen bounds, "
                "or give scale= for signals of very different magnitudes") from exc
        Xv = np.atleast_2d(sol.value(X)).reshape(nx, N + 1).T
        Uv = np.atleast_2d(sol.value(U)).reshape(nu, N).T
        Tv = float(sol.value(T)) if self.T_fixed is None else self.T_fixed
        xd0, z0 = dae.initialize(Xv[0], Uv[0], self.p, store=False)
        XDv = np.vstack([xd0, np.atleast_2d(sol.value(Wc)).reshape(nx, N * d)[:, (d - 1)::d].T])
        Zv = np.vstack([z0, np.atleast_2d(sol.value(Zc)).reshape(nz, N * d)[:, (d - 1)::d].T]) if nz \
            else np.zeros((N + 1, 0))
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
            active[n] = active_fraction(v, lo, hi)
        for n, e in rate_expr.items():
            r = np.abs(np.atleast_1d(np.asarray(sol.value(e), float)).ravel())
            active[f"rate:{n}"] = float(np.mean(r >= self.rate_limits[n] * (1 - 1e-4)))
        return OcpResult(T=Tv, t=t, x=Xv, u=Uv, outputs=outputs, x_names=list(dae.x_names),
                         u_names=list(dae.u_names), active=active,
                         stats={"return_status": stats.get("return_status"), "iter_count": stats.get("iter_count"),
                                "t_wall_total": stats.get("t_wall_total")}, dae=dae, p=self.p, xd=XDv, z=Zv,
                         residual={n: float(sol.value(e)) for n, e in res_expr.items()})

    def _start(self, lin):
        """Horizon guess and the reference motion it starts from: the warm start, the fitted minimum-time
        reference, or the fixed-T reference (also the scaling, see :meth:`_scales`)."""
        T0 = self.T_fixed or (self.warm.T if self.warm is not None and self.T_fixed is None else self.T_guess)
        if self.warm is not None:
            return T0, self._warm_reference(lin)
        if self.T_fixed is None:
            return T0, self._fit_reference(T0, lin)
        return T0, self.reference(T0, lin)

    def _solve_modal(self, solver_options):
        """``coordinates="modal"``: the same problem on :class:`bscomp.optimal.modal.ModalDae` (final values and
        rest become rows of ``P``), transcribed by :func:`bscomp.optimal.modal.solve_condensed`, mapped back."""
        from bscomp.optimal.modal import ModalDae, ModalError, solve_condensed

        if self.rate_limits:
            raise OcpError(f"bound_rate ({sorted(self.rate_limits)}) is transcribed in physical coordinates only: "
                           "use Ocp(..., coordinates='physical') or drop the rate limit")
        dae = self.dae
        x0 = self._x0()
        if self._modal is None or not np.array_equal(self._modal.lin["x0"], x0):
            try:
                self._modal = ModalDae.from_dae(dae, self.p, x0)
            except ModalError as exc:
                raise OcpError(f"coordinates='modal': {exc}") from exc
        md = self._modal
        sub = Ocp.__new__(Ocp)
        sub.__dict__.update(self.__dict__)
        sub.dae, sub.coordinates, sub._modal = md, "physical", None
        sub.x_init, sub.x_final, sub.final_rest = {}, {}, False
        rows, tgt = [], []
        for k, v in self.x_final.items():
            i = dae.x_names.index(k)
            rows.append(md.P[i])
            tgt.append(v - x0[i])
        if self.final_rest:
            for i, n in enumerate(dae.x_names):
                if n.startswith("der(") and n not in self.x_final:
                    rows.append(md.P[i])
                    tgt.append(-x0[i])
        sub._terminal = (np.array(rows).reshape(len(rows), md.nx), np.array(tgt, float))
        if self.warm is not None:
            w = self.warm
            xi = md.from_physical(w.x) if w.x.shape[1] == dae.nx else w.x
            sub.warm = OcpResult(T=w.T, t=w.t, x=xi, u=w.u, outputs={}, x_names=md.x_names, u_names=w.u_names,
                                 active={})
        sparse = self.coordinates == "modal-sparse" or (self.coordinates == "modal" and md.nx > SPARSE_MODAL_NX)
        r = solve_condensed(sub, solver_options, sparse=sparse)
        X = md.to_physical(r.x)
        XD = r.xd @ md.P.T
        uk = np.vstack([r.u[:1], r.u])
        Z = (md.lin["z0"][None, :] + (X - x0[None, :]) @ md.lin["Zx"].T + uk @ md.lin["Zu"].T) if dae.nz \
            else np.zeros((len(r.t), 0))
        stats = dict(r.stats, coordinates="modal", modal_info=dict(md.info))
        return OcpResult(T=r.T, t=r.t, x=X, u=r.u, outputs=r.outputs, x_names=list(dae.x_names),
                         u_names=list(dae.u_names), active=r.active, stats=stats, dae=dae, p=self.p, xd=XD, z=Z,
                         residual=r.residual)

    # ---- scaling and initial guess ---------------------------------------------------------------
    def _linearize(self, x0):
        """Affine model at the start, ``x' = xd0 + A (x - x0) + B u``, ``z = z0 + Zx (x - x0) + Zu u``;
        None if the index-1 Jacobian cannot be factorised there."""
        from bscomp.kernel.dae import _sp
        from bscomp.linear.linearize import explicit_form

        dae = self.dae
        u0 = np.zeros(dae.nu)
        try:
            xd0, z0 = dae.initialize(x0, u0, self.p, store=False)
            _, Jxd, Jx, Jz, Ju = dae.jacobians(xd0, x0, z0, u0, self.p)
            Jxd, Jx, Jz, Ju = _sp(Jxd), _sp(Jx), _sp(Jz), _sp(Ju)
            A, B, Zx, Zu = explicit_form(dae, Jxd, Jx, Jz, Ju)
        except (RuntimeError, BscompError, np.linalg.LinAlgError):
            return None
        if not all(np.all(np.isfinite(a)) for a in (A, B, Zx, Zu)):
            return None
        return {"x0": x0, "xd0": np.asarray(xd0, float), "z0": np.asarray(z0, float),
                "A": A, "B": B, "Zx": Zx, "Zu": Zu, "J": (Jxd, Jx, Jz, Ju)}

    def reference(self, T: float | None = None, lin=None) -> dict:
        """Reference motion used for scaling and as the cold-start guess.

        The minimum-effort input (``min Σ (u_k/u_nom)²``, piecewise constant on the OCP grid) that takes
        the model, linearized at the start, to the final values (and to rest if ``final(rest=True)``)
        in time ``T`` (default ``T_guess``); states are propagated with the transcription's own Radau
        IIA steps, so the motion satisfies the collocation equations of a linear model exactly: a drive
        moves along its rigid-body mode and its elastic coordinates carry the deflections that motion
        causes. Falls back to a straight line towards
        the least-strain final configuration if the model cannot be linearized.

        Returns
        -------
        dict with ``T``, ``X`` (N+1, nx), ``Xc``, ``W`` (nx, N d) states and derivatives at the
        collocation points, ``Z`` (nz, N d), ``U`` (N, nu).
        """
        dae, N, d = self.dae, self.N, self.d
        T = float(T or self.T_fixed or self.T_guess)
        x0 = self._x0()
        lin = self._linearize(x0) if lin is None else lin
        tau, _ = _radau(d)
        nx, nu, nz = dae.nx, dae.nu, dae.nz
        if lin is None or lin is False or nx > 1500:
            xf = self._rest_guess(x0)
            s = np.linspace(0, 1, N + 1)
            X = x0[None, :] * (1 - s[:, None]) + xf[None, :] * s[:, None]
            sc = np.concatenate([(k + tau[1:]) / N for k in range(N)])
            Xc = (x0[:, None] * (1 - sc[None, :]) + xf[:, None] * sc[None, :])
            return {"T": T, "X": X, "Xc": Xc, "W": np.repeat(((xf - x0) / T)[:, None], N * d, axis=1),
                    "Z": np.zeros((nz, N * d)), "U": np.zeros((N, nu))}
        A, B, xd0 = lin["A"], lin["B"], lin["xd0"]
        h = T / N
        # one Radau IIA step of the affine model, exactly as the transcription discretises it:
        # (1/h) (C0j x_k + sum_r Crj x_kr) = xd0 + A x_kj + B u  ->  x_kj = Pj x_k + Qj u + fj
        _, Cr = _radau(d)
        L = np.kron(Cr[1:, 1:].T, np.eye(nx)) / h - np.kron(np.eye(d), A)
        rhs = np.hstack([-np.kron(Cr[0, 1:][:, None], np.eye(nx)) / h, np.kron(np.ones((d, 1)), B),
                         np.kron(np.ones((d, 1)), xd0[:, None])])
        try:
            sol = np.linalg.solve(L, rhs)
        except np.linalg.LinAlgError:
            return self.reference(T, lin=False)
        colloc = [(sol[j * nx:(j + 1) * nx, :nx], sol[j * nx:(j + 1) * nx, nx:nx + nu], sol[j * nx:(j + 1) * nx, -1])
                  for j in range(d)]
        Ah, Bh, fh = colloc[-1]
        # final conditions (deviation from x0)
        rows, target = [], []
        for k, v in self.x_final.items():
            i = dae.x_names.index(k)
            rows.append(i)
            target.append(v - x0[i])
        if self.final_rest:
            for i, n in enumerate(dae.x_names):
                if n.startswith("der(") and i not in rows:
                    rows.append(i)
                    target.append(-x0[i])
        Srows = np.eye(nx)[rows]
        term = self._terminal_rows(lin if lin else None)
        if term is not None:
            Srows = np.vstack([Srows, term[0]])
            target = list(target) + list(term[1] - term[0] @ x0)
        un = np.array([self._nominal(n) for n in dae.u_names])
        fixed = {i: self.bounds[n][0] for i, n in enumerate(dae.u_names)
                 if n in self.bounds and self.bounds[n][0] == self.bounds[n][1]}
        un[list(fixed)] = 0.0          # inputs held at a value (e.g. a disturbance at 0) do not move the reference
        Uref = np.zeros((N, nu))
        if len(target) and nu:
            free = np.zeros(nx)          # x_N - x0 with u = 0
            for _ in range(N):
                free = Ah @ free + fh
            S = Srows
            G = np.zeros((len(target), N, nu))
            for k in range(N - 1, -1, -1):
                G[:, k, :] = S @ Bh
                S = S @ Ah
            G = G.reshape(len(target), N * nu) * np.tile(un, N)[None, :]
            v = np.linalg.lstsq(G, np.asarray(target) - Srows @ free, rcond=1e-12)[0]
            Uref = v.reshape(N, nu) * un[None, :]
            if not np.all(np.isfinite(Uref)):
                Uref = np.zeros((N, nu))
        for i, v in fixed.items():
            Uref[:, i] = v
        dX = np.zeros((N + 1, nx))
        dXc = np.zeros((nx, N * d))
        for k in range(N):
            for j, (Aj, Bj, fj) in enumerate(colloc):
                dXc[:, k * d + j] = Aj @ dX[k] + Bj @ Uref[k] + fj
            dX[k + 1] = Ah @ dX[k] + Bh @ Uref[k] + fh
        Ucol = np.repeat(Uref.T, d, axis=1)
        W = xd0[:, None] + A @ dXc + B @ Ucol
        Z = lin["z0"][:, None] + lin["Zx"] @ dXc + lin["Zu"] @ Ucol if nz else np.zeros((0, N * d))
        return {"T": T, "X": x0[None, :] + dX, "Xc": x0[:, None] + dXc, "W": W, "Z": Z, "U": Uref}

    def _bound_ratio(self, ref):
        """Largest ratio of a bounded signal along the reference motion to its bound (bounds that
        contain zero only); 0 if nothing is bounded."""
        dae, N, d = self.dae, self.N, self.d
        y_names = [n for n in self.bounds if self._kind(n) == "y"]
        Y = {}
        if y_names:
            Yv = np.atleast_2d(np.asarray(dae.output_function(y_names).map(N * d)(
                ref["W"], ref["Xc"], ref["Z"], np.repeat(ref["U"].T, d, axis=1), np.tile(self.p[:, None], (1, N * d)))))
            Y = dict(zip(y_names, Yv))
        r = 0.0
        for n, (lo, hi) in self.bounds.items():
            if not lo <= 0 <= hi:
                continue
            kind = self._kind(n)
            if kind == "u":
                v = ref["U"][:, dae.u_names.index(n)]
            elif kind == "x":
                i = dae.x_names.index(n)
                v = np.r_[ref["X"][:, i], ref["Xc"][i]]
            else:
                v = Y[n]
            if hi > 0:
                r = max(r, float(np.max(v)) / hi)
            if lo < 0:
                r = max(r, float(np.min(v)) / lo)
        return r

    def _fit_reference(self, T, lin):
        """Minimum-time problems: stretch or shrink the reference move until its bounded signals peak at
        80-100 % of their bounds (a feasible, nearly tight start; inputs and accelerations of a
        rest-to-rest move scale as 1/T², hence the square root)."""
        ref = self.reference(T, lin)
        if lin is None or not self.bounds:
            return ref
        for _ in range(10):
            r = self._bound_ratio(ref)
            if r <= 0 or 0.8 <= r <= 1.0:
                break
            T *= float(np.sqrt(r / 0.9))
            ref = self.reference(T, lin)
        return ref

    def _warm_reference(self, lin):
        """The warm-start solution on this OCP's grid (linear interpolation in normalised time)."""
        w, N, d = self.warm, self.N, self.d
        tau, _ = _radau(d)
        tw = w.t / w.T
        tn = np.linspace(0, 1, N + 1)
        tc = np.concatenate([(k + tau[1:]) / N for k in range(N)])
        X = np.column_stack([np.interp(tn, tw, w.x[:, i]) for i in range(w.x.shape[1])])
        Xc = np.vstack([np.interp(tc, tw, w.x[:, i]) for i in range(w.x.shape[1])])
        km = np.clip(np.searchsorted(tw, (np.arange(N) + 0.5) / N) - 1, 0, len(w.u) - 1)
        U = w.u[km]
        Ucol = np.repeat(U.T, d, axis=1)
        if lin is not None:
            dXc = Xc - lin["x0"][:, None]
            W = lin["xd0"][:, None] + lin["A"] @ dXc + lin["B"] @ Ucol
            Z = lin["z0"][:, None] + lin["Zx"] @ dXc + lin["Zu"] @ Ucol
        else:
            W = np.gradient(Xc, tc * w.T, axis=1)
            Z = np.zeros((self.dae.nz, N * d))
        return {"T": w.T, "X": X, "Xc": Xc, "W": W, "Z": Z, "U": U}

    def _scales(self, ref):
        """Nominal magnitudes (states, state derivatives, algebraic variables, inputs): ``scale=``,
        bounds or boundary values where given, else the largest magnitude along the reference motion,
        else 1. Magnitudes below 1e-12 of the largest one in their group are round-off, not motion."""
        dae = self.dae

        def pick(names, ref_mag, fallback):
            given = np.array([self._nominal(n, default=np.nan) for n in names]) if names else np.zeros(0)
            big = float(np.max(ref_mag)) if ref_mag.size else 0.0
            ok = ref_mag > 1e-12 * big
            out = np.where(np.isnan(given), np.where(ok & (ref_mag > 0), ref_mag, fallback), given)
            return np.where(out > 0, out, 1.0)

        xmag = np.maximum(np.max(np.abs(ref["X"]), axis=0), np.max(np.abs(ref["Xc"]), axis=1))
        xs = pick(dae.x_names, xmag, np.ones(dae.nx))
        wmag = np.max(np.abs(ref["W"]), axis=1) if ref["W"].size else np.zeros(dae.nx)
        ws = np.where(wmag > 1e-12 * (np.max(wmag) if wmag.size else 0.0), wmag, xs / ref["T"])
        ws = np.where(ws > 0, ws, 1.0)
        zmag = np.max(np.abs(ref["Z"]), axis=1) if ref["Z"].size else np.zeros(dae.nz)
        zs = pick(dae.z_names, zmag, np.ones(dae.nz))
        umag = np.max(np.abs(ref["U"]), axis=0) if ref["U"].size else np.zeros(dae.nu)
        us = pick(dae.u_names, umag, np.ones(dae.nu))
        return xs, ws, zs, us

    def _residual_scales(self, lin, xs, ws, zs, us):
        """Row scales of F: the largest scaled term of each row (Jacobian at the start × nominals)."""
        if lin is None:
            x0 = self._x0()
            xd, z = self.dae.initialize(x0, np.zeros(self.dae.nu), self.p, store=False)
            J = self.dae.jacobians(xd, x0, z, np.zeros(self.dae.nu), self.p)[1:]
            J = [np.asarray(ca.DM(j)) for j in J]
        else:
            J = [abs(j).toarray() if hasattr(j, "toarray") else np.asarray(j) for j in lin["J"]]
        Jxd, Jx, Jz, Ju = (np.abs(j) for j in J)
        cols = [Jxd * ws[None, :], Jx * xs[None, :], Ju * us[None, :]]
        if self.dae.nz:
            cols.append(Jz * zs[None, :])
        rs = np.max(np.hstack(cols), axis=1)
        return np.where(rs > 0, rs, 1.0)

    def _y0(self, name, x0, u0):
        xd, z = self.dae.initialize(x0, u0, self.p, store=False)
        return float(self.dae.output_function([name])(xd, x0, z, u0, self.p))

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


def _radau_weights(tau, d):
    """Quadrature weights of the Radau points on [0, 1]."""
    B = np.zeros(d)
    for j in range(1, d + 1):
        p = np.poly1d([1.0])
        for r in range(d + 1):
            if r != j:
                p *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        P = np.polyint(p)
        B[j - 1] = P(1.0) - P(0.0)
    return B
