"""Where a transcription starts: the reference motion, the nominal magnitudes and warm starts.

Ipopt needs a start and every unknown a nominal magnitude (a rotor angle of 60 rad and a screw stretch of
1 µm must both be O(1) unknowns). Both come from a *reference motion* (:func:`reference_motion`): a
simulation of the model linearized at the start, driven by the minimum-effort piecewise-constant input
that reaches the final values, propagated with the transcription's own Radau IIA steps (so it satisfies
the collocation equations of a linear model exactly). For minimum-time problems its horizon is stretched
until the bounded signals peak near their bounds (:func:`fit_reference`). A warm start replaces it: a
previous :class:`~bscomp.optimal.OcpResult` or a :class:`~bscomp.simulation.SimulationResult` of the same
model (:func:`from_simulation`), interpolated onto the grid (:func:`warm_reference`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from bscomp.errors import BscompError, UnknownNameError
from bscomp.optimal.collocation import radau
from bscomp.optimal.coordinates import affine_model
from bscomp.optimal.result import OcpResult

__all__ = ["Guess", "initial_guess", "linearize_start", "reference_motion", "fit_reference", "warm_reference",
           "scales", "rest_guess", "from_simulation"]


@dataclass
class Guess:
    """Start of a transcription.

    Attributes
    ----------
    x0 : ndarray (nx,)
        Initial state.
    lin : dict or None
        The model linearized at ``x0`` (:func:`bscomp.optimal.coordinates.affine_model`); None if it has no
        index-1 linearization there.
    T0 : float
        Horizon guess: the unit of T in a minimum-time problem.
    ref : dict
        Reference motion (or warm start) on the grid, see :func:`reference_motion`.
    xs, ws, zs, us : ndarray
        Nominal magnitudes of the states, state derivatives, algebraic variables and inputs.
    """

    x0: np.ndarray
    lin: dict | None
    T0: float
    ref: dict
    xs: np.ndarray
    ws: np.ndarray
    zs: np.ndarray
    us: np.ndarray

    def residual_scales(self, ocp) -> np.ndarray:
        """Row scales of F: the largest scaled term of each row (Jacobian at the start × nominals)."""
        dae, lin = ocp.dae, self.lin
        if lin is None:
            x0 = self.x0
            xd, z = dae.initialize(x0, np.zeros(dae.nu), ocp.p, store=False)
            J = [np.asarray(ca.DM(j)) for j in dae.jacobians(xd, x0, z, np.zeros(dae.nu), ocp.p)[1:]]
        else:
            J = [abs(j).toarray() if hasattr(j, "toarray") else np.asarray(j) for j in lin["J"]]
        Jxd, Jx, Jz, Ju = (np.abs(j) for j in J)
        cols = [Jxd * self.ws[None, :], Jx * self.xs[None, :], Ju * self.us[None, :]]
        if dae.nz:
            cols.append(Jz * self.zs[None, :])
        rs = np.max(np.hstack(cols), axis=1)
        return np.where(rs > 0, rs, 1.0)


def initial_guess(ocp) -> Guess:
    """Start state, linearization, horizon guess, reference motion (or warm start) and nominals of ``ocp``.

    The horizon guess is the fixed horizon, else the warm start's, else ``T_guess``; the reference is the
    warm start, the fitted minimum-time reference (:func:`fit_reference`) or the fixed-T reference.
    """
    x0 = ocp.start_state()
    lin = linearize_start(ocp, x0)
    T0 = ocp.T_fixed or (ocp.warm.T if ocp.warm is not None else ocp.T_guess)
    if ocp.warm is not None:
        ref = warm_reference(ocp, lin)
    elif ocp.T_fixed is None:
        ref = fit_reference(ocp, T0, lin)
    else:
        ref = reference_motion(ocp, T0, lin)
    return Guess(x0, lin, T0, ref, *scales(ocp, ref))


def linearize_start(ocp, x0) -> dict | None:
    """Affine model at the start (:func:`bscomp.optimal.coordinates.affine_model`, inputs at 0); None if the
    index-1 Jacobian cannot be factorised there or the linearization is not finite."""
    try:
        lin = affine_model(ocp.dae, ocp.p, x0)
    except (RuntimeError, BscompError, np.linalg.LinAlgError):
        return None
    if not all(np.all(np.isfinite(lin[k])) for k in ("A", "B", "Zx", "Zu")):
        return None
    return lin


def reference_motion(ocp, T: float | None = None, lin=None) -> dict:
    """Reference motion used for scaling and as the cold-start guess.

    The minimum-effort input (``min Σ (u_k/u_nom)²``, piecewise constant on the OCP grid) that takes the
    model, linearized at the start, to the final values (and to rest if ``final(rest=True)``) in time ``T``
    (default ``T_guess``); states are propagated with the transcription's own Radau IIA steps, so the motion
    satisfies the collocation equations of a linear model exactly: a drive moves along its rigid-body mode
    and its elastic coordinates carry the deflections that motion causes. Falls back to a straight line
    towards the least-strain final configuration (:func:`rest_guess`) if the model cannot be linearized.

    Returns
    -------
    dict with ``T``, ``X`` (N+1, nx), ``Xc``, ``W`` (nx, N d) states and derivatives at the collocation
    points, ``Z`` (nz, N d), ``U`` (N, nu).
    """
    T = float(T or ocp.T_fixed or ocp.T_guess)
    x0 = ocp.start_state()
    lin = linearize_start(ocp, x0) if lin is None else lin
    if lin is None or lin is False or ocp.dae.nx > 1500:
        return _straight_line(ocp, x0, T)
    steps = _radau_steps(lin, radau(ocp.d), T / ocp.N)
    if steps is None:
        return reference_motion(ocp, T, lin=False)
    U = _min_effort_inputs(ocp, lin, x0, steps)
    return _propagate(ocp, lin, x0, steps, U, T)


def _straight_line(ocp, x0, T) -> dict:
    """The straight line from ``x0`` to :func:`rest_guess` at constant speed, inputs and z at 0."""
    dae, N, d = ocp.dae, ocp.N, ocp.d
    xf = rest_guess(ocp, x0)
    s = np.linspace(0, 1, N + 1)
    X = x0[None, :] * (1 - s[:, None]) + xf[None, :] * s[:, None]
    sc = radau(d).stage_times(N)
    Xc = (x0[:, None] * (1 - sc[None, :]) + xf[:, None] * sc[None, :])
    return {"T": T, "X": X, "Xc": Xc, "W": np.repeat(((xf - x0) / T)[:, None], N * d, axis=1),
            "Z": np.zeros((dae.nz, N * d)), "U": np.zeros((N, dae.nu))}


def _radau_steps(lin, scheme, h):
    """One Radau IIA step of the affine model, exactly as the transcription discretises it:
    ``(1/h) (C_0j x_k + Σ_r C_rj x_kr) = xd0 + A x_kj + B u``, solved as ``x_kj = P_j x_k + Q_j u + f_j``
    (deviations from the start). Returns ``[(P_j, Q_j, f_j)]`` for j = 1..d, None if singular."""
    A, B, xd0 = lin["A"], lin["B"], lin["xd0"]
    nx, nu, d, C = A.shape[0], B.shape[1], scheme.d, scheme.C
    L = np.kron(C[1:, :].T, np.eye(nx)) / h - np.kron(np.eye(d), A)
    rhs = np.hstack([-np.kron(C[0, :][:, None], np.eye(nx)) / h, np.kron(np.ones((d, 1)), B),
                     np.kron(np.ones((d, 1)), xd0[:, None])])
    try:
        sol = np.linalg.solve(L, rhs)
    except np.linalg.LinAlgError:
        return None
    return [(sol[j * nx:(j + 1) * nx, :nx], sol[j * nx:(j + 1) * nx, nx:nx + nu], sol[j * nx:(j + 1) * nx, -1])
            for j in range(d)]


def _min_effort_inputs(ocp, lin, x0, steps) -> np.ndarray:
    """``min Σ_k |u_k / u_nom|²`` subject to the final values, rest and linear final rows, on the one-step
    maps ``steps``; inputs held at a value (bound lo == hi) stay there. Returns U (N, nu)."""
    dae, N = ocp.dae, ocp.N
    nx, nu = dae.nx, dae.nu
    Ah, Bh, fh = steps[-1]
    final = ocp.final_targets()
    rows = [i for i, _ in final]
    target = [v - x0[i] for i, v in final]          # deviation from x0
    Srows = np.eye(nx)[rows]
    term = ocp.terminal_rows(lin)
    if term is not None:
        Srows = np.vstack([Srows, term[0]])
        target = list(target) + list(term[1] - term[0] @ x0)
    un = np.array([ocp.nominal(n) for n in dae.u_names])
    fixed = ocp.fixed_inputs()
    un[list(fixed)] = 0.0          # inputs held at a value (e.g. a disturbance at 0) do not move the reference
    U = np.zeros((N, nu))
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
        U = v.reshape(N, nu) * un[None, :]
        if not np.all(np.isfinite(U)):
            U = np.zeros((N, nu))
    for i, v in fixed.items():
        U[:, i] = v
    return U


def _propagate(ocp, lin, x0, steps, U, T) -> dict:
    """States at the grid and collocation points under the inputs ``U``, derivatives and z from the affine
    model (the reference dict of :func:`reference_motion`)."""
    dae, N, d = ocp.dae, ocp.N, ocp.d
    nx, nz = dae.nx, dae.nz
    Ah, Bh, fh = steps[-1]
    dX = np.zeros((N + 1, nx))
    dXc = np.zeros((nx, N * d))
    for k in range(N):
        for j, (Aj, Bj, fj) in enumerate(steps):
            dXc[:, k * d + j] = Aj @ dX[k] + Bj @ U[k] + fj
        dX[k + 1] = Ah @ dX[k] + Bh @ U[k] + fh
    Ucol = np.repeat(U.T, d, axis=1)
    W = lin["xd0"][:, None] + lin["A"] @ dXc + lin["B"] @ Ucol
    Z = lin["z0"][:, None] + lin["Zx"] @ dXc + lin["Zu"] @ Ucol if nz else np.zeros((0, N * d))
    return {"T": T, "X": x0[None, :] + dX, "Xc": x0[:, None] + dXc, "W": W, "Z": Z, "U": U}


def bound_ratio(ocp, ref) -> float:
    """Largest ratio of a bounded signal along the reference motion to its bound (bounds that contain zero
    only); 0 if nothing is bounded."""
    dae, N, d = ocp.dae, ocp.N, ocp.d
    y_names = [n for n in ocp.bounds if ocp.kind(n) == "y"]
    Y = {}
    if y_names:
        Yv = np.atleast_2d(np.asarray(dae.output_function(y_names).map(N * d)(
            ref["W"], ref["Xc"], ref["Z"], np.repeat(ref["U"].T, d, axis=1), np.tile(ocp.p[:, None], (1, N * d)))))
        Y = dict(zip(y_names, Yv))
    r = 0.0
    for n, (lo, hi) in ocp.bounds.items():
        if not lo <= 0 <= hi:
            continue
        kind = ocp.kind(n)
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


def fit_reference(ocp, T, lin) -> dict:
    """Minimum-time problems: stretch or shrink the reference move until its bounded signals peak at 80-100 %
    of their bounds (a feasible, nearly tight start; inputs and accelerations of a rest-to-rest move scale
    as 1/T², hence the square root)."""
    ref = reference_motion(ocp, T, lin)
    if lin is None or not ocp.bounds:
        return ref
    for _ in range(10):
        r = bound_ratio(ocp, ref)
        if r <= 0 or 0.8 <= r <= 1.0:
            break
        T *= float(np.sqrt(r / 0.9))
        ref = reference_motion(ocp, T, lin)
    return ref


def warm_reference(ocp, lin) -> dict:
    """The warm start on this OCP's grid (linear interpolation in normalised time); derivatives and z from
    the affine model at the start where there is one, else finite differences and zeros."""
    w, N, d = ocp.warm, ocp.N, ocp.d
    tw = w.t / w.T
    tn = np.linspace(0, 1, N + 1)
    tc = radau(d).stage_times(N)
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
        Z = np.zeros((ocp.dae.nz, N * d))
    return {"T": w.T, "X": X, "Xc": Xc, "W": W, "Z": Z, "U": U}


def scales(ocp, ref):
    """Nominal magnitudes ``(xs, ws, zs, us)`` of states, state derivatives, algebraic variables and inputs:
    ``scale=``, bounds or boundary values where given (:meth:`Ocp.nominal`), else the largest magnitude along
    the reference motion, else 1. Magnitudes below 1e-12 of the largest one in their group are round-off,
    not motion."""
    dae = ocp.dae

    def pick(names, ref_mag, fallback):
        given = np.array([ocp.nominal(n, default=np.nan) for n in names]) if names else np.zeros(0)
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


def rest_guess(ocp, x0) -> np.ndarray:
    """Final-state guess: the least-strain static configuration that meets the final values
    (``min ½ dqᵀ K dq`` subject to the given coordinates), so an elastic drive is guessed to move along its
    rigid-body mode instead of stretching its stiffest joint."""
    dae = ocp.dae
    xf = x0.copy()
    for k, v in ocp.x_final.items():
        xf[dae.x_names.index(k)] = v
    m = dae.mech
    pos = [m.q_in_x[j] for j in sorted(m.q_in_x)]
    fixed = [i for i in pos if dae.x_names[i] in ocp.x_final]
    free = [i for i in pos if i not in fixed]
    if not fixed or not free:
        return xf
    xd, z = dae.initialize(x0, np.zeros(dae.nu), ocp.p, store=False)
    _, _, Jx, _, _ = dae.jacobians(xd, x0, z, np.zeros(dae.nu), ocp.p)
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


def from_simulation(sim, dae) -> OcpResult:
    """A warm start from a simulation of the same model: the recorded states and the input applied on each
    output interval, in ``dae``'s names and order, time shifted to start at 0.

    Parameters
    ----------
    sim : bscomp.simulation.SimulationResult
        E.g. the run of a hand-made input profile (a trapezoidal-velocity move) or of a controller; its
        output times become the warm start's grid (interpolated onto the OCP's).
    dae : Dae
        The OCP's model: every state and input of it must be in ``sim``.
    """
    missing = [n for n in dae.x_names if n not in sim.x_names] + [n for n in dae.u_names if n not in sim.u_names]
    if missing:
        raise UnknownNameError(f"warm start from a simulation: it has no {missing[:5]} of '{dae.name}' (simulate "
                               "the OCP's own model)")
    t = np.asarray(sim.t, float) - float(sim.t[0])
    x = np.column_stack([sim.x[:, sim.x_names.index(n)] for n in dae.x_names]) if dae.nx \
        else np.zeros((len(t), 0))
    # SimulationResult.u[i] is the input on (t_{i-1}, t_i]: interval k of the guess is row k + 1
    u = np.column_stack([sim.u[1:, sim.u_names.index(n)] for n in dae.u_names]) if dae.nu \
        else np.zeros((len(t) - 1, 0))
    return OcpResult(T=float(t[-1]), t=t, x=x, u=u, outputs={}, x_names=list(dae.x_names),
                     u_names=list(dae.u_names), active={}, stats={"source": "simulation"})
