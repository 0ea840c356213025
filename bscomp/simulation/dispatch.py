"""Time-domain simulation of a flattened model: IDAS (SUNDIALS, through CasADi), a compiled fixed-step
SDIRK3 (``method="fixed"``, :mod:`bscomp.simulation.fixed_step`) or exact zero-order-hold stepping of the
linearized model (``method="lti"``).

The implicit index-1 DAE ``F(x', x, z, u, p) = 0`` is handed to IDAS in semi-explicit form by making
the derivatives algebraic unknowns ``w``:

.. math:: \\dot x = w, \\qquad 0 = F(w, x, z, u, p)

whose algebraic Jacobian ``[dF/dw, dF/dz]`` is the index-1 matrix the kernel already checked. Keeping
accelerations algebraic makes them (and the table acceleration users look at) as accurate as the
states, rather than differences of velocities (see DESIGN.md, "Known pitfalls").

Inputs are held piecewise constant on the output grid (arrays: value at the interval start; callables:
value at the interval midpoint). Sampled-data controllers run at their own period with zero-order hold.
The maximum BDF order defaults to 2 (A-stable), which matters for lightly damped structures.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import casadi as ca
import numpy as np

from bscomp.errors import BscompError, UnknownNameError
from bscomp.linear.linearize import resolve_model
from bscomp.simulation.native import quiet_native_stderr

__all__ = ["simulate", "SimulationResult", "SimulationError", "SampledController"]


class SimulationError(BscompError):
    """The integrator failed; the message names the time window, the variable and a hint."""


@dataclass
class SampledController:
    """A discrete controller in the loop: every ``Ts`` it reads ``measure`` and sets ``actuate`` (ZOH).

    Parameters
    ----------
    law : callable
        ``law(t_k, y_k) -> u_k`` with ``y_k`` the measured outputs (array, order of ``measure``) and
        ``u_k`` the values of the actuated inputs (order of ``actuate``). It may keep internal state.
    measure : list of str
        Output names read at each sample (any observable).
    actuate : list of str
        System inputs it drives.
    Ts : float
        Sampling period [s].
    """

    law: Callable
    measure: list
    actuate: list
    Ts: float


@dataclass
class SimulationResult:
    """Time histories of a simulation.

    Attributes
    ----------
    t : ndarray (nt,)
    x, xd : ndarray (nt, nx)
        States and their derivatives.
    z : ndarray (nt, nz)
    u : ndarray (nt, nu)
        Inputs applied on the interval ending at each time (at t0: the first interval's).
    outputs : dict name -> ndarray (nt,)
    """

    t: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    z: np.ndarray
    u: np.ndarray
    x_names: list
    z_names: list
    u_names: list
    outputs: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.x_names:
            return self.x[:, self.x_names.index(name)]
        if name in self.z_names:
            return self.z[:, self.z_names.index(name)]
        if name in self.u_names:
            return self.u[:, self.u_names.index(name)]
        raise UnknownNameError(f"no signal '{name}' in this result; outputs: {list(self.outputs)}, states: "
                               f"{self.x_names[:10]}..., inputs: {self.u_names}")

    def to_csv(self, path, names=None):
        """Write t and the named signals (default: outputs, else states) as CSV with a header row."""
        names = list(names or (list(self.outputs) or self.x_names))
        data = np.column_stack([self.t] + [self[n] for n in names])
        np.savetxt(path, data, delimiter=",", header=",".join(["t"] + names), comments="")
        return path

    def plot(self, names=None, path=None, title=""):
        """Plot the named signals against time (one axis each)."""
        from bscomp.plotting.base import time_plot

        names = list(names or (list(self.outputs) or self.x_names[:4]))
        return time_plot(self.t, [self[n] for n in names], names, title=title, path=path)


def _input_matrix(dae, t, inputs, fixed):
    """(nu, nt-1) values held on each interval [t_k, t_k+1)."""
    nint = len(t) - 1
    U = np.zeros((dae.nu, max(nint, 1)))
    for k, v in (inputs or {}).items():
        if k not in dae.u_names:
            raise UnknownNameError(f"'{k}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
        i = dae.u_names.index(k)
        if callable(v):
            tm = 0.5 * (t[:-1] + t[1:])
            U[i] = np.array([float(v(tt)) for tt in tm])
        else:
            arr = np.asarray(v, float)
            if arr.ndim == 0:
                U[i] = float(arr)
            elif arr.shape == (len(t),):
                U[i] = arr[:-1]
            elif arr.shape == (nint,):
                U[i] = arr
            else:
                raise ValueError(f"input '{k}' has {arr.shape[0]} values; give one per time point ({len(t)}) or per "
                                 f"interval ({nint}), a scalar, or a function of t")
    for k in fixed:
        if k not in dae.u_names:
            raise UnknownNameError(f"'{k}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
    return U


def _integrator(dae, h, n_sub, opts, cache):
    key = (round(h, 15), n_sub, tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in opts.items())))
    if key not in cache:
        x = ca.MX.sym("x", dae.nx)
        w = ca.MX.sym("w", dae.nx)
        z = ca.MX.sym("z", dae.nz)
        u = ca.MX.sym("u", dae.nu)
        p = ca.MX.sym("p", dae.np)
        res = dae.F(w, x, z, u, p)
        d = {"x": x, "z": ca.vertcat(w, z), "p": ca.vertcat(u, p), "ode": w, "alg": res}
        grid = list(np.arange(1, n_sub + 1) * h)
        cache[key] = ca.integrator("sim", "idas", d, 0.0, grid, opts)
    return cache[key]


def simulate(model, t, inputs: dict | None = None, x0: dict | None = None, params: dict | None = None,
             outputs=None, controllers=None, rtol: float = 1e-6, atol: float = 1e-9, max_order: int = 2,
             progress: bool | None = None, max_num_steps: int = 100000, method: str = "idas", substeps: int = 1,
             newton_iter: int = 2, jit: bool = False) -> SimulationResult:
    """Integrate a System or Dae over the time grid ``t`` (IDAS, fixed-step SDIRK3, exact ZOH or split).

    Parameters
    ----------
    model : System or Dae
    t : array
        Output times (increasing); the first is the start time.
    inputs : dict, optional
        Input name -> scalar, array (per time point or per interval) or function of t.
    x0 : dict, optional
        Initial states by name (others at their start values; (x', z) made consistent).
    params : dict, optional
        Parameter overrides by dotted name.
    outputs : list of str, optional
        Observables to record (``"table.a"``...).
    controllers : list of SampledController, optional
        Discrete controllers in the loop (their actuated inputs are overwritten every ``Ts``).
    rtol, atol : float
        IDAS tolerances.
    max_order : int
        Maximum BDF order (2 keeps A-stability for lightly damped structures).
    progress : bool, optional
        Print a progress bar to stderr (default: when the run has more than 200 intervals and stderr is
        a terminal).
    method : {"idas", "fixed", "lti", "split"}
        ``"idas"``: the nonlinear DAE with IDAS (variable step, error controlled by rtol/atol).
        ``"fixed"``: the nonlinear DAE with a fixed-step, L-stable, 3rd-order SDIRK method
        (:mod:`bscomp.simulation.fixed_step`), ``substeps`` steps per output interval, exact Newton on the
        nonlinear equations; no error control (check it by halving the step), no per-step Python.
        Its error on the test bed's table acceleration at a 0.1 ms grid is ~1e-4 of the peak
        (``docs/benchmarks.md``). ``"lti"``: for **linear** models only, the model is
        linearized once at the start and stepped by exact zero-order-hold discretisation
        (``expm``, one matrix product per output step): the floor for linear structures driven by
        sampled inputs. It is exact for linear time-invariant models and wrong for nonlinear ones
        (friction, backlash, a moving nut): use "idas" or "fixed" there.
        ``"split"`` (**experimental**, :mod:`bscomp.simulation.split`): partitioned exponential integrator. The
        few variables entering F nonlinearly are found symbolically; the rest of the model is the linear part,
        integrated exactly for zero-order-held inputs and a held nonlinear correction ``g`` (its
        end-of-step value: implicit, damped Newton in the nonlinear unknowns only). The linear part is
        re-linearized per *regime* of the nonlinear laws (the tangent of friction sticking / sliding,
        backlash gap / contact; one cached discretisation per regime), so ``g`` is nearly constant
        inside a regime; steps where the regime changes are redone in 16 re-linearized sub-steps. Exact
        for linear models (equals "lti" to ~1e-10). Measured (``docs/nonlinear.md``): Coulomb
        oscillator 5e-3 / 7e-4 of x0 at 2^-12 / 2^-14 s steps; test bed with Table 5.2 friction and
        backlash, 0.4 s vs IDAS rtol 1e-8: table.v 1.3e-4, table.s 8e-6, rotor.w 7e-6 (IDAS default
        tolerances: 4.6e-4, 8e-5, 1.1e-4); 1 s of it in ~1.5 s wall for the first run from a start
        point, ~0.9 s for a repeated one (the set-up is cached on the Dae). Its accuracy is not error
        controlled; check it with ``substeps``.
    substeps : int
        ``method="fixed"`` / ``"split"``: integration steps per output interval.
    newton_iter : int
        ``method="split"``: Newton iterations always done per step (up to 4x more while unconverged).
        ``method="fixed"``: Newton iterations per stage when the model has nonlinear equations (one
        is exact for an affine model and used then); a chunk that has not converged is redone with
        four times as many and a backtracking line search, then fails with SimulationError.
    jit : bool
        ``method="fixed"`` / ``"split"``: compile the step to C with the system compiler (cached on disk, see
        :func:`bscomp.simulation.fixed_step.compiled`): ~10x faster on small (reduced) models, ~1 s to compile once.

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        With the time window, the largest state (IDAS) or the failing Newton iteration (fixed) and a
        hint.
    """
    dae = resolve_model(model, params)
    t = np.asarray(t, float)
    if t.ndim != 1 or len(t) < 2 or np.any(np.diff(t) <= 0):
        raise ValueError("t must be an increasing 1-D array of at least two times")
    controllers = list(controllers or [])
    p = dae.parameter_vector({k: v for k, v in (params or {}).items() if k not in dae.structural_parameters})
    xs = dae.x_start.copy()
    for k, v in (x0 or {}).items():
        if k not in dae.x_names:
            raise UnknownNameError(f"x0 names '{k}', which is not a state of '{dae.name}' ({dae.x_names[:8]}...)")
        xs[dae.x_names.index(k)] = float(v)
    U = _input_matrix(dae, t, inputs, [a for c in controllers for a in c.actuate])
    if method == "lti":
        return _simulate_lti(dae, t, U, xs, p, list(outputs or []), controllers)
    if method == "fixed":
        if int(substeps) < 1 or int(newton_iter) < 1:
            raise ValueError(f"substeps and newton_iter must be >= 1, got {substeps} and {newton_iter}")
        return _simulate_fixed(dae, t, U, xs, p, list(outputs or []), controllers, int(substeps), int(newton_iter),
                               progress, bool(jit))
    if method == "split":
        from bscomp.simulation.split import simulate_split

        if int(substeps) < 1 or int(newton_iter) < 1:
            raise ValueError(f"substeps and newton_iter must be >= 1, got {substeps} and {newton_iter}")
        return simulate_split(dae, t, U, xs, p, list(outputs or []), controllers, int(substeps), int(newton_iter),
                              progress, bool(jit))
    if method != "idas":
        raise ValueError(f"method must be 'idas', 'fixed', 'lti' or 'split', got {method!r}")
    opts = {"reltol": rtol, "abstol": atol, "max_order": float(max_order), "max_num_steps": max_num_steps,
            "disable_internal_warnings": True, "suppress_algebraic": True}
    outputs = list(outputs or [])
    meas_names = [m for c in controllers for m in c.measure]
    if outputs:
        dae.output_function(outputs)  # unknown output names fail before integrating
    mfun = dae.output_function(meas_names) if meas_names else None
    nt = len(t)
    X = np.zeros((nt, dae.nx))
    XD = np.zeros((nt, dae.nx))
    Z = np.zeros((nt, dae.nz))
    Uh = np.zeros((nt, dae.nu))
    xd, z = dae.initialize(xs, U[:, 0], p, store=False)
    X[0], XD[0], Z[0], Uh[0] = xs, xd, z, U[:, 0]
    cache = dae._cache.setdefault("idas_integrators", {})  # reused across simulate() calls on this Dae
    if progress is None:
        progress = nt > 200 and sys.stderr.isatty()
    t_wall = time.perf_counter()
    x_cur, w_cur, z_cur = xs, xd, z
    ctrl_next = [t[0] for _ in controllers]
    ctrl_u = [None for _ in controllers]
    n_calls = 0
    n_retries = 0
    u_prev = U[:, 0]
    k = 0
    # uniform stretches of the grid are integrated in chunks with one reusable integrator
    h_all = np.diff(t)
    while k < nt - 1:
        u_k = U[:, k].copy()
        # sampled controllers: update at their sample times (ZOH), forcing grid alignment
        for ci, c in enumerate(controllers):
            if t[k] + 1e-12 >= ctrl_next[ci]:
                y = np.asarray(mfun(w_cur, x_cur, z_cur, u_k, p)).ravel() if mfun is not None else np.zeros(0)
                off = sum(len(cc.measure) for cc in controllers[:ci])
                val = np.atleast_1d(np.asarray(c.law(t[k], y[off:off + len(c.measure)]), float))
                ctrl_u[ci] = val
                ctrl_next[ci] = ctrl_next[ci] + c.Ts * max(1, int(np.floor((t[k] - ctrl_next[ci]) / c.Ts + 1e-9)) + 0)
                while ctrl_next[ci] <= t[k] + 1e-12:
                    ctrl_next[ci] += c.Ts
            if ctrl_u[ci] is not None:
                for a, v in zip(c.actuate, ctrl_u[ci]):
                    u_k[dae.u_names.index(a)] = v
        # chunk of equal steps with equal inputs (no controller update inside)
        h = h_all[k]
        n = 1
        if not controllers:
            while (k + n < nt - 1 and n < 500 and abs(h_all[k + n] - h) < 1e-9 * h
                   and np.array_equal(U[:, k + n], U[:, k])):
                n += 1
        I = _integrator(dae, h, n, opts, cache)
        # consistent restart by our own Newton on the index-1 Jacobian (the inputs may have jumped)
        if not np.array_equal(u_k, u_prev):
            w_cur, z_cur = dae.initialize(x_cur, u_k, p, z_guess=z_cur, xd_guess=w_cur, store=False)
        u_prev = u_k
        try:
            try:
                with quiet_native_stderr():
                    r = I(x0=x_cur, z0=np.concatenate([w_cur, z_cur]), p=np.concatenate([u_k, p]))
            except RuntimeError:
                # IDACalcIC can fail on an already consistent point: retry without it, handing IDAS
                # the consistent derivatives directly
                retry = dict(opts, calc_ic=False, init_xdot=[float(v) for v in w_cur])
                with quiet_native_stderr():
                    r = _integrator(dae, h, n, retry, {})(x0=x_cur, z0=np.concatenate([w_cur, z_cur]),
                                                          p=np.concatenate([u_k, p]))
                n_retries += 1
        except RuntimeError as exc:
            big = int(np.argmax(np.abs(x_cur))) if dae.nx else 0
            raise SimulationError(
                f"IDAS failed on '{dae.name}' between t = {t[k]:.6g} s and t = {t[k + n]:.6g} s; largest state "
                f"'{dae.x_names[big] if dae.nx else '-'}' = {x_cur[big] if dae.nx else 0:.3g}. Hints: a stiff "
                "contact or a switching element (friction, backlash) needs smaller steps (denser t) or "
                "regularisation; lower rtol; check inputs for jumps of unphysical size. "
                f"IDAS said: {str(exc).splitlines()[-1][:300]}") from exc
        n_calls += 1
        xf = np.asarray(r["xf"]).reshape(dae.nx, n)
        zf = np.asarray(r["zf"]).reshape(dae.nx + dae.nz, n)
        if not np.all(np.isfinite(xf)):
            bad = int(np.argmax(~np.isfinite(xf).all(axis=1)))
            raise SimulationError(f"state '{dae.x_names[bad]}' became non-finite after t = {t[k]:.6g} s")
        X[k + 1:k + 1 + n] = xf.T
        XD[k + 1:k + 1 + n] = zf[:dae.nx].T
        Z[k + 1:k + 1 + n] = zf[dae.nx:].T
        Uh[k + 1:k + 1 + n] = u_k
        x_cur, w_cur, z_cur = xf[:, -1], zf[:dae.nx, -1], zf[dae.nx:, -1]
        k += n
        if progress and (n_calls % 20 == 0 or k == nt - 1):
            _progress_bar(dae.name, k / (nt - 1), t[k])
    wall = time.perf_counter() - t_wall
    out = _evaluate_outputs(dae, outputs, XD, X, Z, Uh, p)
    return SimulationResult(t=t, x=X, xd=XD, z=Z, u=Uh, x_names=list(dae.x_names), z_names=list(dae.z_names),
                            u_names=list(dae.u_names), outputs=out,
                            stats={"wall_s": wall, "integrator_calls": n_calls, "calc_ic_retries": n_retries,
                                   "real_time_factor": (t[-1] - t[0]) / wall if wall > 0 else np.inf})


def _simulate_fixed(dae, t, U, xs, p, outputs, controllers, substeps, newton_iter, progress, jit):
    """Fixed-step SDIRK3 on the nonlinear DAE (see ``simulate(method="fixed")`` and :mod:`._fixed_step`)."""
    from bscomp.simulation import fixed_step as fs

    if outputs:
        dae.output_function(outputs)  # unknown output names fail before integrating
    t_wall = time.perf_counter()
    nx, nz, nu, nt = dae.nx, dae.nz, dae.nu, len(t)
    m = nx + nz
    xd0, z0 = dae.initialize(xs, U[:, 0], p, store=False)
    X = np.empty((nt, nx))
    V = np.empty((nt, m))  # [x', z]
    E = np.zeros(nt)
    Uh = np.empty((nt, nu))
    X[0], V[0], Uh[0] = xs, np.concatenate([xd0, z0]), U[:, 0]
    Ut = np.ascontiguousarray(U.T)
    stepper = fs.Stepper(dae, p, xs, xd0, z0, U[:, 0], newton_iter, substeps, jit)
    h_all = np.diff(t)
    mfun = dae.output_function([mm for c in controllers for mm in c.measure]) if controllers else None
    ctrl_next = [t[0] for _ in controllers]
    ctrl_u = [None for _ in controllers]
    if progress is None:
        progress = nt > 200 and sys.stderr.isatty()
    n_calls, k = 0, 0
    while k < nt - 1:
        h = h_all[k]
        if controllers:
            u_k = Ut[k].copy()
            _sample_controllers(dae, controllers, t[k], u_k, ctrl_next, ctrl_u,
                                lambda uk, k=k: np.asarray(mfun(V[k, :nx], X[k], V[k, nx:], uk, p)).ravel())
            t_next = min(ctrl_next)
        else:
            t_next = np.inf
        n = 1
        while (k + n < nt - 1 and n < fs.CHUNK and abs(h_all[k + n] - h) < 1e-9 * h
               and t[k + n] + 1e-12 < t_next):
            n += 1
        Uc = _held_inputs(dae, Ut[k:k + n], controllers, ctrl_u)
        stepper.run(n, h, X[k], V[k], Uc, X[k + 1:k + 1 + n], V[k + 1:k + 1 + n], E[k + 1:k + 1 + n])
        Uh[k + 1:k + 1 + n] = Uc
        n_calls += 1
        tol = fs.NEWTON_TOL
        if not (np.isfinite(X[k + n]).all() and np.max(E[k + 1:k + 1 + n]) <= tol):  # NaN propagates to the end
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
        k += n
        if progress and (n_calls % 20 == 0 or k == nt - 1):
            _progress_bar(dae.name, k / (nt - 1), t[k])
    XD, Z = V[:, :nx], V[:, nx:]
    out = _evaluate_outputs(dae, outputs, XD, X, Z, Uh, p)
    wall = time.perf_counter() - t_wall
    return SimulationResult(t=t, x=X, xd=np.ascontiguousarray(XD), z=np.ascontiguousarray(Z), u=Uh,
                            x_names=list(dae.x_names), z_names=list(dae.z_names), u_names=list(dae.u_names),
                            outputs=out,
                            stats={"wall_s": wall, "method": "fixed", "scheme": "SDIRK3 (L-stable, order 3)",
                                   "step": float(np.min(h_all)) / substeps, "chunk_calls": n_calls,
                                   "newton_iterations": stepper.n_iter, "nonlinear_equations": len(stepper.nl),
                                   "newton_max_update": stepper.max_newton,
                                   "newton_retries": stepper.retries, "jit": jit,
                                   "real_time_factor": (t[-1] - t[0]) / wall if wall > 0 else np.inf})


def _evaluate_outputs(dae, names, XD, X, Z, Uh, p, chunk=1000):
    """Named outputs at every time point: ``{name: (nt,) array}``.

    The output Function is mapped over chunks of time points and called through zero-copy buffers on
    the (nt, n) arrays (CasADi is column-major, so their rows are its columns); converting large arrays
    to and from DM costs ~0.1 µs per number, which would dominate a fast run.
    """
    if not names:
        return {}
    nt = X.shape[0]
    n = min(chunk, nt)
    key = ("outmap", tuple(names), n)
    if key not in dae._cache:
        dae._cache[key] = dae.output_function(names).map("ymap", "serial", n, [4], [])
    fm = dae._cache[key]
    data = [np.ascontiguousarray(a, dtype=float) for a in (XD, X, Z, Uh)]
    pc = np.ascontiguousarray(p, dtype=float)
    Y = np.zeros((nt, len(names)))
    buf, ev = fm.buffer()
    buf.set_arg(4, memoryview(pc))
    starts = list(range(0, nt - n + 1, n))
    if starts[-1] + n < nt:
        starts.append(nt - n)  # last chunk overlaps the previous one: no padding needed
    for k in starts:
        ys = np.zeros((n, len(names)))
        for i, a in enumerate(data):
            buf.set_arg(i, memoryview(a[k:k + n].reshape(-1)))
        buf.set_res(0, memoryview(ys.reshape(-1)))
        ev()
        Y[k:k + n] = ys
    return {name: Y[:, i].copy() for i, name in enumerate(names)}


def _progress_bar(name, frac, t_now):
    """One progress line on stderr (overwritten; a newline at the end)."""
    sys.stderr.write(f"\r  simulating '{name}' [{'#' * int(30 * frac):<30}] {100 * frac:5.1f}%  t = {t_now:.4g} s")
    if frac >= 1.0:
        sys.stderr.write("\n")


def _held_inputs(dae, Uc, controllers, ctrl_u):
    """Input rows ``Uc`` with every sampled controller's actuated inputs replaced by its held output."""
    if not controllers:
        return Uc
    Uc = Uc.copy()
    for c, val in zip(controllers, ctrl_u):
        if val is not None:
            for a, v in zip(c.actuate, val):
                Uc[:, dae.u_names.index(a)] = v
    return Uc


def _sample_controllers(dae, controllers, t_k, u_k, ctrl_next, ctrl_u, y_of):
    """Update the sampled controllers due at ``t_k`` and write their held values into ``u_k`` (in place)."""
    y = None
    for ci, c in enumerate(controllers):
        if t_k + 1e-12 >= ctrl_next[ci]:
            if y is None:
                y = y_of(u_k)
            off = sum(len(cc.measure) for cc in controllers[:ci])
            ctrl_u[ci] = np.atleast_1d(np.asarray(c.law(t_k, y[off:off + len(c.measure)]), float))
            while ctrl_next[ci] <= t_k + 1e-12:
                ctrl_next[ci] += c.Ts
        if ctrl_u[ci] is not None:
            for a, v in zip(c.actuate, ctrl_u[ci]):
                u_k[dae.u_names.index(a)] = v


def _simulate_lti(dae, t, U, xs, p, outputs, controllers):
    """Exact ZOH stepping of the model linearized at the start point (see ``simulate(method="lti")``).

    In deviations ``e = x - x_s`` the step is ``e_{k+1} = A_d e_k + g_k`` with ``g_k = B_d (u_k - u_0) + f_d``.
    On a uniform grid without controllers and for models up to 32 states the recursion is solved for all
    steps at once in complex Schur coordinates of ``A_d`` (a triangular system of first-order filters,
    :func:`scipy.signal.lfilter`); otherwise it is one matrix-vector product per step.
    """
    import scipy.linalg as sla

    from bscomp.kernel.dae import _sp
    from bscomp.linear.linearize import explicit_form

    t_wall = time.perf_counter()
    nx, nu, nt = dae.nx, dae.nu, len(t)
    u0 = U[:, 0]
    xd0, z0 = dae.initialize(xs, u0, p, store=False)
    _, Jxd, Jx, Jz, Ju = dae.jacobians(xd0, xs, z0, u0, p)
    A, B, Zx, Zu = explicit_form(dae, _sp(Jxd), _sp(Jx), _sp(Jz), _sp(Ju))
    # affine model in deviations: x' = xd0 + A dx + B du
    h_all = np.diff(t)
    cache = {}  # per call: the discretisation depends on this call's linearization point

    def disc(h):
        key = round(h, 15)
        if key not in cache:
            n = nx + nu + 1
            Maug = np.zeros((n, n))
            Maug[:nx, :nx] = A * h
            Maug[:nx, nx:nx + nu] = B * h
            Maug[:nx, -1] = xd0 * h
            E = sla.expm(Maug)
            cache[key] = (E[:nx, :nx], E[:nx, nx:nx + nu], E[:nx, -1])
        return cache[key]

    Uh = np.empty((nt, nu))
    Uh[0] = u0
    uniform = bool(np.all(np.abs(h_all - h_all[0]) <= 1e-9 * h_all[0]))
    if not controllers and uniform and 0 < nx <= 32:
        Uh[1:] = U.T
        Ad, Bd, fd = disc(h_all[0])
        dX = _zoh_schur(Ad, Bd, fd, U.T - u0)
        X = xs + dX
    else:
        X = np.empty((nt, nx))
        X[0] = xs
        keys = np.round(h_all, 15)
        uniq, which = np.unique(keys, return_inverse=True)
        discs = [disc(h) for h in uniq]
        e = np.zeros(nx)
        if not controllers:
            Uh[1:] = U.T
            G = np.empty((nt - 1, nx))
            for j, (_, Bd, fd) in enumerate(discs):
                sel = which == j
                G[sel] = (U.T[sel] - u0) @ Bd.T + fd
            Ads = [d[0] for d in discs]
            for k in range(nt - 1):
                e = Ads[which[k]] @ e + G[k]
                X[k + 1] = e
            X[1:] += xs
        else:
            mfun = dae.output_function([m for c in controllers for m in c.measure])
            ctrl_next = [t[0] for _ in controllers]
            ctrl_u = [None for _ in controllers]
            for k in range(nt - 1):
                u_k = U[:, k].copy()

                def y_of(uk, k=k, e=e):
                    du = uk - u0
                    return np.asarray(mfun(xd0 + A @ e + B @ du, X[k], z0 + Zx @ e + Zu @ du, uk, p)).ravel()

                _sample_controllers(dae, controllers, t[k], u_k, ctrl_next, ctrl_u, y_of)
                Ad, Bd, fd = discs[which[k]]
                e = Ad @ e + Bd @ (u_k - u0) + fd
                X[k + 1] = xs + e
                Uh[k + 1] = u_k
        dX = X - xs
    dU = Uh - u0
    XD = xd0 + dX @ A.T + dU @ B.T
    Z = z0 + dX @ Zx.T + dU @ Zu.T
    out = _evaluate_outputs(dae, outputs, XD, X, Z, Uh, p)
    wall = time.perf_counter() - t_wall
    return SimulationResult(t=t, x=X, xd=XD, z=Z, u=Uh, x_names=list(dae.x_names), z_names=list(dae.z_names),
                            u_names=list(dae.u_names), outputs=out,
                            stats={"wall_s": wall, "method": "lti", "discretisations": len(cache),
                                   "real_time_factor": (t[-1] - t[0]) / wall if wall > 0 else np.inf})


def _zoh_schur(Ad, Bd, fd, dU):
    """All ``e_k`` (k = 0..N, e_0 = 0) of ``e_{k+1} = Ad e_k + Bd du_k + fd`` (rows of dU: du_k), no step loop.

    With ``Ad = Q T Q^H`` (complex Schur, unitary Q) the coordinates ``eta = Q^H e`` obey an upper
    triangular recursion (after balancing), solved from the last component up, each one a first-order filter
    (:func:`scipy.signal.lfilter`) driven by the input and the components already known. Only
    element-wise vector operations are used (no threaded BLAS on long arrays, which stalls on a busy
    machine); the work is O(n^2 N), meant for small models.
    """
    import scipy.linalg as sla
    from scipy.signal import lfilter

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
