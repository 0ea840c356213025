"""Variable-step BDF integration of the implicit DAE with IDAS (SUNDIALS, through CasADi): ``simulate``'s
default method (``method="idas"``).

The implicit index-1 DAE ``F(x', x, z, u, p) = 0`` is handed to IDAS in semi-explicit form by making
the derivatives algebraic unknowns ``w``:

.. math:: \\dot x = w, \\qquad 0 = F(w, x, z, u, p)

whose algebraic Jacobian ``[dF/dw, dF/dz]`` is the index-1 matrix the kernel already checked. Keeping
accelerations algebraic makes them (and the table acceleration users look at) as accurate as the
states, rather than differences of velocities (see DESIGN.md, "Known pitfalls"). The maximum BDF order
defaults to 2 (A-stable), which matters for lightly damped structures.

Uniform stretches of the grid with equal held inputs are integrated in chunks of up to 500 output
intervals by one integrator (cached on the Dae per step, chunk length and options); where the inputs jump,
``(x', z)`` are made consistent by the Dae's own Newton on the index-1 Jacobian before IDAS restarts.

Absolute tolerances are per component. The states ``x`` get the user's ``atol``. The algebraic unknowns
``(w, z)`` are outside the error test (``suppress_algebraic``) but inside IDAS's Newton convergence tests
(corrector and ``IDACalcIC``), which measure corrections in the same weighted norm. Their computed values
carry a round-off floor that does not shrink with the step: ``w`` solves ``F = 0`` whose terms can be
large and cancel (the stiffness forces of a rigid-body motion of many radians through ``K ~ 1e8``). When
``rtol |w_i| + atol`` is below that floor, a restart (which begins with tiny steps, whose true corrections
are below the noise) fails the convergence-rate test at every step size (``IDA_CONV_FAIL``, or
``IDA_LINESEARCH_FAIL`` in ``IDACalcIC``), decided by the last bits of the arithmetic. So the algebraic
tolerances are raised to :data:`KAPPA` times the floor estimated from the Jacobian
(:func:`algebraic_atol`); the accuracy asked of the states is unchanged.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bscomp.simulation.common import HUGE, Progress, SampledLoop, finish
from bscomp.simulation.native import quiet_native_stderr
from bscomp.simulation.result import SimulationError

__all__ = ["simulate_idas"]

CHUNK = 500  # most output intervals per integrator call
KAPPA = 1e3  # algebraic absolute tolerances >= KAPPA x their round-off floor (IDACalcIC's test needs < 1 / 300)


def integrator(dae, h, n_sub, opts, cache):
    """The IDAS integrator over ``n_sub`` output steps of length ``h`` (cached in ``cache``)."""
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


def simulate_idas(problem, options):
    """``simulate(method="idas")``: the nonlinear DAE with IDAS, error controlled by ``rtol`` / ``atol``.

    Parameters
    ----------
    problem : SimulationProblem
    options : SimulationOptions
        ``rtol``, ``atol`` (of the states; the algebraic unknowns' are kept above their round-off floor,
        see the module notes), ``max_order`` (BDF), ``max_num_steps``.

    Returns
    -------
    SimulationResult
        ``stats``: ``integrator_calls``, ``calc_ic_retries``, ``algebraic_atol_max`` (the largest absolute
        tolerance the algebraic unknowns were given).
    """
    dae, t, U, p = problem.dae, problem.t, problem.U, problem.p
    opts = {"reltol": options.rtol, "abstol": options.atol, "max_order": float(options.max_order),
            "max_num_steps": options.max_num_steps, "disable_internal_warnings": True, "suppress_algebraic": True}
    loop = SampledLoop(dae, problem.controllers, t[0])
    nt = len(t)
    X, XD = np.zeros((nt, dae.nx)), np.zeros((nt, dae.nx))
    Z, Uh = np.zeros((nt, dae.nz)), np.zeros((nt, dae.nu))
    xd, z = dae.initialize(problem.x0, U[:, 0], p, store=False)
    X[0], XD[0], Z[0], Uh[0] = problem.x0, xd, z, U[:, 0]
    cache = dae._cache.setdefault("idas_integrators", {})  # reused across simulate() calls on this Dae
    progress = Progress(dae.name, t, problem.progress)
    t_wall = time.perf_counter()
    x_cur, w_cur, z_cur = problem.x0, xd, z
    n_calls = n_retries = k = 0
    u_prev = U[:, 0]
    h_all = np.diff(t)
    atol_alg = np.full(dae.nx + dae.nz, float(options.atol))
    while k < nt - 1:
        u_k = U[:, k].copy()
        loop.sample(t[k], u_k, lambda uk, w=w_cur, x=x_cur, z=z_cur: loop.measure(w, x, z, uk, p))
        # chunk of equal steps with equal inputs (a controller may change the input at every step)
        h, n = h_all[k], 1
        if not loop:
            while (k + n < nt - 1 and n < CHUNK and abs(h_all[k + n] - h) < 1e-9 * h
                   and np.array_equal(U[:, k + n], U[:, k])):
                n += 1
        # consistent restart by our own Newton on the index-1 Jacobian (the inputs may have jumped)
        if not np.array_equal(u_k, u_prev):
            w_cur, z_cur = dae.initialize(x_cur, u_k, p, z_guess=z_cur, xd_guess=w_cur, store=False)
        u_prev = u_k
        atol_alg = _raise_to_floor(atol_alg, algebraic_atol(dae, x_cur, w_cur, z_cur, u_k, p, n * h))
        opts_k = dict(opts, abstolv=[float(options.atol)] * dae.nx + [float(v) for v in atol_alg])
        xf, zf, retried = _integrate(dae, integrator(dae, h, n, opts_k, cache), opts_k, h, n, x_cur, w_cur, z_cur,
                                     u_k, p, (t[k], t[k + n]))
        n_calls += 1
        n_retries += retried
        X[k + 1:k + 1 + n] = xf.T
        XD[k + 1:k + 1 + n] = zf[:dae.nx].T
        Z[k + 1:k + 1 + n] = zf[dae.nx:].T
        Uh[k + 1:k + 1 + n] = u_k
        x_cur, w_cur, z_cur = xf[:, -1], zf[:dae.nx, -1], zf[dae.nx:, -1]
        k += n
        progress.update(n_calls, k)
    return finish(problem, X, XD, Z, Uh, {"method": "idas", "integrator_calls": n_calls,
                                          "calc_ic_retries": n_retries,
                                          "algebraic_atol_max": float(np.max(atol_alg, initial=0.0))}, t_wall)


def algebraic_atol(dae, x, w, z, u, p, span):
    """:data:`KAPPA` times the round-off floor of the algebraic unknowns ``(w, z)`` near a point: ``(nx + nz,)``.

    Parameters
    ----------
    dae : Dae
    x, w, z, u, p : ndarray
        A consistent point (``w = x'``).
    span : float
        Length [s] of the window about to be integrated: the states are taken as large as
        ``|x| + span |w|``, what they can reach in it.

    Returns
    -------
    ndarray
        The absolute tolerances the Newton tests on ``(w, z)`` can meet.

    Notes
    -----
    Each residual row sums terms of magnitude :math:`T_j = \\sum_k |\\partial F_j / \\partial y_k|\\,|y_k|`
    and is computed to about :math:`\\varepsilon T_j`; through the index-1 Jacobian
    :math:`W = [\\partial F / \\partial w, \\partial F / \\partial z]` that is an error of about
    :math:`\\varepsilon\\, |W^{-1}|\\, T` in the unknowns, estimated here by three sparse solves with
    right-hand sides :math:`\\varepsilon T` of random sign (fixed seed: the result is reproducible).
    """
    if dae.nx + dae.nz == 0:
        return np.zeros(0)
    _, Jxd, Jx, Jz, Ju = dae.jacobians_at(w, x, z, u, p)
    T = abs(Jxd) @ np.abs(w) + abs(Jx) @ (np.abs(x) + span * np.abs(w))
    if dae.nz:
        T = T + abs(Jz) @ np.abs(z)
    if dae.nu:
        T = T + abs(Ju) @ np.abs(u)
    lu = spla.splu(sp.hstack([Jxd, Jz]).tocsc())
    signs = np.random.default_rng(0).choice([-1.0, 1.0], size=(3, T.size))
    floor = np.max(np.abs([lu.solve(np.finfo(float).eps * T * s) for s in signs]), axis=0)
    return KAPPA * floor


def _raise_to_floor(current, need):
    """``current`` tolerances, each raised where below ``need`` to the decade above ``need`` (so few distinct
    values, hence few integrators, occur in a run)."""
    low = need > current
    if not np.any(low):
        return current
    out = current.copy()
    out[low] = 10.0 ** np.ceil(np.log10(need[low]))
    return out


def _check_magnitudes(dae, x, w, z, u, window):
    """SimulationError naming the largest of the states, rates, algebraic unknowns and inputs when it exceeds
    :data:`HUGE` (an input in the wrong unit, a runaway): IDAS is not called on such a point."""
    groups = [(x, dae.x_names, "state "), (w, dae.x_names, "the rate of state "), (z, dae.z_names, "unknown "),
              (u, dae.u_names, "input ")]
    big, what = 0.0, ""
    for v, names, kind in groups:
        i = int(np.argmax(np.abs(v))) if len(v) else None
        if i is not None and abs(float(v[i])) > big:
            big, what = abs(float(v[i])), f"{kind}'{names[i]}'"
    if big > HUGE:
        raise SimulationError(f"IDAS on '{dae.name}' at t = {window[0]:.6g} s: {what} = {big:.3g}, beyond "
                              f"{HUGE:g} -- an input in the wrong unit or of an unphysical size (inputs here: "
                              f"{dict(zip(dae.u_names, np.round(u, 6).tolist(), strict=True))}"[:400] + ")")


def _integrate(dae, I, opts, h, n, x, w, z, u, p, window):
    """One integrator call from a consistent ``(x, x' = w, z)``: ``(X (nx, n), [X'; Z] (nx + nz, n), retried)``.

    ``IDACalcIC`` can fail on an already consistent point: then the call is retried without it, handing IDAS
    the consistent derivatives directly. Raises SimulationError naming the window and the largest state.
    """
    retried = 0
    _check_magnitudes(dae, x, w, z, u, window)
    try:
        try:
            with quiet_native_stderr():
                r = I(x0=x, z0=np.concatenate([w, z]), p=np.concatenate([u, p]))
        except RuntimeError:
            retry = dict(opts, calc_ic=False, init_xdot=[float(v) for v in w])
            with quiet_native_stderr():
                r = integrator(dae, h, n, retry, {})(x0=x, z0=np.concatenate([w, z]), p=np.concatenate([u, p]))
            retried = 1
    except RuntimeError as exc:
        big = int(np.argmax(np.abs(x))) if dae.nx else 0
        raise SimulationError(
            f"IDAS failed on '{dae.name}' between t = {window[0]:.6g} s and t = {window[1]:.6g} s; largest state "
            f"'{dae.x_names[big] if dae.nx else '-'}' = {x[big] if dae.nx else 0:.3g}. Hints: a stiff "
            "contact or a switching element (friction, backlash) needs smaller steps (denser t) or "
            "regularisation; lower rtol; check inputs for jumps of unphysical size. "
            f"IDAS said: {str(exc).splitlines()[-1][:300]}") from exc
    xf = np.asarray(r["xf"]).reshape(dae.nx, n)
    zf = np.asarray(r["zf"]).reshape(dae.nx + dae.nz, n)
    if not np.all(np.isfinite(xf)):
        bad = int(np.argmax(~np.isfinite(xf).all(axis=1)))
        raise SimulationError(f"state '{dae.x_names[bad]}' became non-finite after t = {window[0]:.6g} s")
    return xf, zf, retried
