"""The optimal-control problem statement, :class:`Ocp`: variables, bounds, objectives, final conditions.

A problem is stated on the model's names (states, inputs, observables), the way it reads on paper, and
is transcribed apart from the model (the Dae is not touched):

>>> ocp = Ocp("small_drive", N=100)
>>> ocp.bound("motor.tau", -8, 8).bound("table.v", -1, 1)
>>> ocp.initial({"table.s": 0.0}).final({"table.s": 0.1}, rest=True)
>>> res = ocp.minimize_time(T_guess=0.2).solve()

``solve`` starts from :func:`bscomp.optimal.guess.initial_guess` (a reference motion of the linearized
model, or a warm start) and transcribes by direct collocation (:mod:`bscomp.optimal.collocation`,
Radau IIA of degree ``d`` on the implicit DAE) or, for linear models, in real modal coordinates
(:mod:`bscomp.optimal.modal`); it returns an :class:`~bscomp.optimal.OcpResult`. A residual-vibration
limit after arrival is available for any linear(ized) model (:meth:`Ocp.limit_residual_vibration`).
"""

from __future__ import annotations

import copy
from typing import Callable

import numpy as np

from bscomp.errors import ArgumentTypeError, UnknownNameError, UsageError, check_mapping, check_number
from bscomp.model import as_dae, run_overrides
from bscomp.optimal.checks import (
    check_bound_pair,
    check_boundary_in_bounds,
    check_count,
    check_degree,
    check_signal,
    check_solver_options,
    check_warm_result,
    reference_values,
)
from bscomp.optimal.collocation import radau, solve_physical
from bscomp.optimal.coordinates import ModalDae, ModalError, modal_basis, output_rows, residual_rows
from bscomp.optimal.guess import from_simulation, initial_guess, reference_motion
from bscomp.optimal.modal import solve_modal
from bscomp.optimal.result import OcpError, OcpResult
from bscomp.simulation.result import SimulationResult

__all__ = ["Ocp"]

COORDINATES = ("physical", "modal", "modal-condensed", "modal-sparse")


def _bound_value(name, v, side) -> float:
    """A bound as a float (``±inf`` for none, NaN kept for the caller's message), else :class:`UsageError`."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.number)):
        raise UsageError(f"bound on '{name}': the {side} bound must be a number (-inf/inf for none), got {v!r}")
    return float(v)


class Ocp:
    """Optimal-control problem on a drive model (see module docstring).

    Parameters
    ----------
    model : str, path, callable, System, Dae or ModelSpec
        Anything :func:`bscomp.model.as_dae` takes: a registered system name, a ``.py`` file defining
        ``build()``, a build function, a System, a flattened Dae or a :class:`~bscomp.model.ModelSpec`.
    N : int
        Number of intervals.
    degree : int
        Radau collocation degree.
    params : dict, optional
        Overrides: parameter values (dotted names) and, for a name, path, spec or build function, build
        keywords (no dot).
    coordinates : {"physical", "modal", "modal-condensed", "modal-sparse"}
        ``"modal"`` (linear models only): transcribe in the real modal coordinates ``ξ`` of the model's
        state matrix, ``x = x0 + P ξ``, ``ξ' = Λ ξ + P⁻¹ (B u + x'0)`` with ``Λ`` block diagonal (one
        2 x 2 block ``[[σ, ω], [-ω, σ]]`` per mode, 1 x 1 for real eigenvalues, one block for the rigid-body
        zero eigenvalues; see :mod:`bscomp.optimal.coordinates`). An exact change of coordinates: the optimum
        is the same, but every damping -- modal, discrete, non-proportional -- sits in the 2 x 2 blocks, so
        the collocation Jacobian has ~2 non-zeros per state instead of the dense rows of a modal damping
        matrix, and the modes are scaled one by one. Bounds, final values and outputs keep the model's
        names (they become rows of ``P``); the result is mapped back to the original states.
        Transcription: ``"modal-condensed"`` eliminates the states (inputs and T the only unknowns;
        O(N² nx) expressions), ``"modal-sparse"`` keeps the scaled modal collocation states as variables
        (O(N nx) sparse rows); ``"modal"`` chooses condensed up to
        :data:`bscomp.optimal.modal.SPARSE_MODAL_NX` states, sparse above.
    """

    def __init__(self, model, N: int = 100, degree: int = 3, params: dict | None = None,
                 coordinates: str = "physical"):
        if coordinates not in COORDINATES:
            raise UsageError("coordinates must be 'physical', 'modal', 'modal-condensed' or 'modal-sparse', not "
                             f"{coordinates!r}")
        self.coordinates = coordinates
        self.dae = as_dae(model, params)
        self.p = self.dae.parameter_vector(run_overrides(model, self.dae, params))
        self.N = check_count("N", N)
        self.d = check_degree(degree)
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
        self._terminal_names: list = []   # what each of those rows stands for (a final value by name)
        self._modal = None       # the ModalDae at the start state, built on demand (modal_dae)
        # MUMPS's default pivot tolerance (1e-6) gives inaccurate steps on the KKT systems of stiff
        # structures (stiffnesses of 1e8 N/m next to a free rigid-body mode): Ipopt then creeps for
        # hundreds of iterations. 1e-2 costs little and brought the reduced test bed from ~300 to ~15.
        self.ipopt_options = {"print_level": 0, "max_iter": 3000, "tol": 1e-8, "mumps_pivtol": 1e-2,
                              "mu_strategy": "adaptive"}
        self.expand = False      # MX maps: faster to build than SX expansion for N*d*nx in the 1e4s

    # ---- problem statement --------------------------------------------------------------------
    def bound(self, name, lo=-np.inf, hi=np.inf, scale=None):
        """Path bound ``lo <= name <= hi`` on a state, input or observable (enforced at every point)."""
        self._signal(name, "bound")
        lo, hi = (_bound_value(name, v, side) for v, side in ((lo, "lower"), (hi, "upper")))
        if lo != lo or hi != hi:
            raise UsageError(f"bound on '{name}': a bound is NaN (lo={lo}, hi={hi}); use -inf/inf for none")
        if lo > hi:
            raise UsageError(f"bound on '{name}': lower {lo} > upper {hi}")
        check_bound_pair(name, lo, hi)
        if scale is not None:
            scale = check_number(f"scale of '{name}'", scale, positive=True)
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
        self._signal(name, "bound_rate")
        if isinstance(limit, (int, float, np.number)) and not limit > 0:
            raise UsageError(f"rate limit on '{name}' must be > 0, not {limit}")
        limit = check_number(f"rate limit on '{name}'", limit, positive=True)
        self.rate_limits[name] = float(limit)
        return self

    def initial(self, values: dict):
        """Initial state values by name (others at the model's start values: at rest)."""
        values = check_mapping("initial(values)", values, "state values")
        for k in values:
            if self.kind(k) != "x":
                raise UnknownNameError(f"initial value for '{k}': only states can be given")
        self.x_init.update({k: check_number(f"initial value of '{k}'", v) for k, v in values.items()})
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
        values = check_mapping("final(values)", values, "state values")
        if rest_below_hz is not None:
            rest_below_hz = check_number("rest_below_hz", rest_below_hz, positive=True)
        for k in values:
            if self.kind(k) != "x":
                raise UnknownNameError(f"final value for '{k}': only states can be given")
        self.x_final.update({k: check_number(f"final value of '{k}'", v) for k, v in values.items()})
        self.final_rest = bool(rest) and rest_below_hz is None
        self.rest_below_hz = None if rest_below_hz is None else float(rest_below_hz)
        return self

    def minimize_time(self, T_guess: float = 1.0):
        """Minimise the horizon T; ``T_guess`` [s] starts the search (and is the unit of T in the NLP)."""
        self.objective_kind = "time"
        self.T_guess = check_number("T_guess", T_guess, positive=True)
        self.T_fixed = None
        return self

    def minimize_effort(self, T: float, weights: dict | None = None):
        """Minimise ∫ Σ w_i u_i² dt over a fixed horizon T."""
        weights = check_mapping("weights", weights, "input weights")
        for k, w in weights.items():
            if k not in self.dae.u_names:
                raise UnknownNameError(f"weight for '{k}', which is not an input of '{self.dae.name}' "
                                       f"({self.dae.u_names})")
            weights[k] = check_number(f"weight of '{k}'", w, nonnegative=True)
        self.objective_kind = "effort"
        self.T_fixed = check_number("T", T, positive=True)
        self.objective_args = {"weights": weights}
        return self

    def minimize_tracking(self, T: float, output: str, reference: Callable, effort_weight: float = 0.0):
        """Minimise ∫ (y - r(t))² dt (+ effort) over a fixed horizon."""
        self._signal(output, "minimize_tracking(output)")
        if not callable(reference):
            raise ArgumentTypeError(f"reference must be a function of t giving the wanted '{output}', got "
                                    f"{type(reference).__name__} {reference!r}")
        effort_weight = check_number("effort_weight", effort_weight, nonnegative=True)
        T = check_number("T", T, positive=True)
        reference_values(reference, output, radau(self.d).stage_times(self.N, T))   # refuse a bad one now
        self.objective_kind = "tracking"
        self.T_fixed = T
        self.objective_args = {"output": output, "reference": reference, "effort_weight": effort_weight}
        return self

    def minimize_residual_vibration(self, T: float, output: str, T_settle: float):
        """Fixed-time move, then minimise ∫ y² over the last ``T_settle`` seconds (e.g. table acceleration
        or screw stretch after arrival)."""
        self._signal(output, "minimize_residual_vibration(output)")
        T = check_number("T", T, positive=True)
        T_settle = check_number("T_settle", T_settle, positive=True)
        if T_settle > T:
            raise UsageError(f"T_settle = {T_settle} s is longer than the horizon T = {T} s: the vibration is "
                             "measured over the last T_settle seconds of the move; give T_settle <= T")
        self.objective_kind = "vibration"
        self.T_fixed = T
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
        (see :func:`bscomp.optimal.coordinates.residual_rows`). It is a guarantee, conservative by at most
        ``sqrt(Σ G_k / G_max)`` when one mode dominates. Unlike an equality "accelerations zero at T", it
        does not fight the piecewise-constant input on the last interval: the input jumps to the held value
        at ``T`` and the bound is on what follows. ``OcpResult.residual`` reports the bound at the optimum.
        Raises :class:`OcpError` at solve time if the limits cannot be met (with the bound reached).
        """
        limits, hold = check_mapping("limits", limits, "limits"), check_mapping("hold", hold, "input values")
        for k, v in limits.items():
            if self._signal(k, "limit_residual_vibration") == "u":
                raise UnknownNameError(f"residual-vibration limit on '{k}': give an output or a state, not an input")
            limits[k] = check_number(f"residual-vibration limit on '{k}'", v, positive=True)
        for k in hold:
            if self.kind(k) != "u":
                raise UnknownNameError(f"hold value for '{k}': only inputs can be held")
            hold[k] = check_number(f"hold value of '{k}'", hold[k])
        self.residual_limits.update({k: float(v) for k, v in limits.items()})
        self.hold.update({k: float(v) for k, v in (hold or {}).items()})
        return self

    def warm_start(self, result):
        """Start from a previous solution (an :class:`OcpResult`, interpolated if its N differs) or from a
        simulation of the same model (a :class:`~bscomp.simulation.SimulationResult`, e.g. of a hand-made
        input profile; see :func:`bscomp.optimal.guess.from_simulation`) instead of the reference motion."""
        if not isinstance(result, (SimulationResult, OcpResult)):
            raise ArgumentTypeError(f"warm_start takes an OcpResult or a SimulationResult, got {type(result).__name__}")
        self.warm = from_simulation(result, self.dae) if isinstance(result, SimulationResult) \
            else check_warm_result(result, self.dae)
        return self

    # ---- what the statement means (read by the guess and the transcriptions) --------------------------
    def kind(self, name) -> str:
        """``"x"`` (state), ``"u"`` (input) or ``"y"`` (observable) for a name of the model."""
        d = self.dae
        if name in d.x_names:
            return "x"
        if name in d.u_names:
            return "u"
        if name in d.observables:
            return "y"
        raise UnknownNameError(f"'{name}' is not a state, input or output of '{d.name}'; inputs: {d.u_names}, "
                               f"states: {d.x_names[:8]}...")

    def _signal(self, name, what) -> str:
        """:meth:`kind` of a name given as a signal (bounded, tracked, limited): a parameter or a constant
        output is refused (:class:`UnknownNameError`, :func:`bscomp.optimal.checks.check_signal`)."""
        kind = self.kind(name)
        if kind == "y":
            check_signal(self.dae, name, what)
        return kind

    def nominal(self, name, default=1.0) -> float:
        """Nominal magnitude given by the user: ``scale=``, else the largest finite bound or boundary value."""
        if name in self.scale:
            return self.scale[name]
        vals = [abs(v) for v in self.bounds.get(name, ()) if np.isfinite(v)]
        vals += [abs(self.x_init.get(name, 0.0)), abs(self.x_final.get(name, 0.0))]
        m = max(vals) if vals else 0.0
        return m if m > 0 else default

    def start_state(self) -> np.ndarray:
        """Initial state: the model's start values with the :meth:`initial` values set."""
        x0 = self.dae.x_start.copy()
        for k, v in self.x_init.items():
            x0[self.dae.x_names.index(k)] = v
        return x0

    def fixed_inputs(self) -> dict:
        """``{input index: value}`` of the inputs held at a value by ``bound(name, v, v)`` (constants)."""
        return {i: self.bounds[n][0] for i, n in enumerate(self.dae.u_names)
                if n in self.bounds and self.bounds[n][0] == self.bounds[n][1]}

    def held_inputs(self) -> np.ndarray:
        """Inputs after arrival: the ``hold`` values, else the fixed value of a fixed input, else 0."""
        u = np.zeros(self.dae.nu)
        for i, v in self.fixed_inputs().items():
            u[i] = v
        for i, n in enumerate(self.dae.u_names):
            if n in self.hold:
                u[i] = self.hold[n]
        return u

    def final_targets(self) -> list:
        """``[(state index, value)]``: the :meth:`final` values, then zero for every velocity state (``der(...)``)
        not given, if ``rest=True``."""
        names = self.dae.x_names
        out = [(names.index(k), v) for k, v in self.x_final.items()]
        if self.final_rest:
            out += [(i, 0.0) for i, n in enumerate(names) if n.startswith("der(") and n not in self.x_final]
        return out

    def terminal_rows(self, lin):
        """Linear final conditions ``R x_T = t`` beyond the named final values: the modal transcription's rows
        and the equilibrium rows of ``final(rest_below_hz=...)``; None if there are none."""
        parts = [r for r in (self._terminal, self._equilibrium_rows(lin)) if r is not None and len(r[1])]
        if not parts:
            return None
        return np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def terminal_names(self, n: int) -> list:
        """Names of the ``n`` rows of :meth:`terminal_rows` for messages: the final values a restated problem's
        rows stand for, then the slow modes brought to equilibrium (``final(rest_below_hz=...)``)."""
        names = list(self._terminal_names)[:n]
        return names + [f"equilibrium row {k + 1} (rest_below_hz)" for k in range(n - len(names))]

    def _equilibrium_rows(self, lin):
        """Rows ``(R, t)``, ``R x_T = t``: the modes with ``|λ| < 2π rest_below_hz`` at their equilibrium under
        the held input (``e_k = 0`` in :func:`bscomp.optimal.coordinates.residual_rows`)."""
        if self.rest_below_hz is None:
            return None
        if lin is None:
            raise OcpError("final(rest_below_hz=...) needs a model that can be linearized at the start")
        basis = self.dae.self_basis if isinstance(self.dae, ModalDae) else modal_basis(lin["A"])
        b = lin["xd0"] + lin["B"] @ self.held_inputs()
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

    def residual_rows(self, lin) -> dict:
        """``{name: (L, l)}``: ``|L (x_T - x0) + l| <= limit`` (see :meth:`limit_residual_vibration`)."""
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
                out[n] = residual_rows(lin, C[r], None, self.held_inputs(), basis=basis)
            except ModalError as exc:
                raise OcpError(f"residual-vibration limit on '{n}': {exc}") from exc
        return out

    def modal_dae(self) -> ModalDae:
        """The model in real modal coordinates at the start state (built once, :class:`OcpError` if the model
        is not linear or not block-diagonalisable)."""
        x0 = self.start_state()
        if self._modal is None or not np.array_equal(self._modal.lin["x0"], x0):
            try:
                self._modal = ModalDae.from_dae(self.dae, self.p, x0)
            except ModalError as exc:
                raise OcpError(f"coordinates='modal': {exc}") from exc
        return self._modal

    def restated(self, dae, terminal, warm=None, terminal_names=None) -> Ocp:
        """This problem on ``dae``, another set of coordinates of the same model (inputs, outputs and bounds
        keep their names; the modal transcription), its start at 0 and its final values replaced by linear
        rows ``terminal = (R, t)``, ``R x_T = t``; ``warm`` in the new coordinates."""
        sub = copy.copy(self)
        sub.dae, sub.coordinates, sub._modal = dae, "physical", None
        sub.x_init, sub.x_final, sub.final_rest = {}, {}, False
        sub._terminal, sub.warm = terminal, warm
        sub._terminal_names = list(terminal_names or [])
        return sub

    # ---- guess and solve -----------------------------------------------------------------------
    def reference(self, T: float | None = None, lin=None) -> dict:
        """Reference motion used for scaling and as the cold-start guess
        (:func:`bscomp.optimal.guess.reference_motion`)."""
        return reference_motion(self, T, lin)

    def solve(self, solver_options: dict | None = None) -> OcpResult:
        """Transcribe and solve with Ipopt; raises :class:`OcpError` if it does not converge.

        ``solver_options`` (a dict of Ipopt options over :attr:`ipopt_options`) is checked first: an option
        Ipopt does not know or a value out of its range raises :class:`UsageError` naming it. A start state or
        a final target outside a path bound on that state raises :class:`OcpError` before transcribing.

        Notes
        -----
        Scaling and the cold-start guess come from a *reference motion* (see :meth:`reference`): the
        minimum-effort rest-to-rest move of the model linearized at the start, over ``T_guess``,
        propagated with the transcription's own Radau steps. Every state, state derivative, algebraic
        variable and input is scaled by its largest magnitude along that motion (unless a bound,
        boundary value or ``scale=`` gives one), so a rotor angle of 60 rad and a screw stretch of 1 µm
        are both O(1) unknowns; each residual row is divided by its largest scaled term. A warm start
        replaces the reference motion by the given solution (interpolated if its N differs).
        Physical coordinates: :func:`bscomp.optimal.collocation.solve_physical`; modal:
        :func:`bscomp.optimal.modal.solve_modal`.
        """
        if self.objective_kind is None:
            raise OcpError("no objective: call minimize_time(), minimize_effort(), minimize_tracking() or "
                           "minimize_residual_vibration() first")
        solver_options = check_solver_options(self.ipopt_options, solver_options)
        check_boundary_in_bounds(self)
        if self.coordinates.startswith("modal"):
            return solve_modal(self, solver_options)
        return solve_physical(self, initial_guess(self), solver_options)
