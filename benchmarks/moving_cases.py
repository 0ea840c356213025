"""Cases and baselines of ``benchmarks/bench_simulation.py --moving`` (issue 16): the thesis's Ch 5 scenario
-- 0.6 s of the 5 Hz, +-2.125 V square wave on the axial + torsional test bed with Table 5.2 guideway
friction and screw-nut backlash -- with the nut frozen at C or moving along the screw (Sec 5.2.2.3).

* :func:`drive` builds the models (examples/nonlinear_scenarios.py with ``nut_joint`` and the mesh as
  options); :func:`six_dof` the full 6-DOF test bed with the same effects; :func:`reduced` the CMS-reduced
  test bed (Sec 5.2.3) with them.
* :func:`reference` is IDAS at rtol 1e-9, atol 1e-12 on the same equations, cached in
  ``benchmarks/.cache`` (about an hour per case on the 2-core machine) with the wall time it took.
* :func:`sundae` is scikit-sundae's IDA on the same residual and Jacobian (CasADi Functions of the Dae),
  restarted at the input switches; ``None`` when scikit-sundae is not installed.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from bscomp.kernel.flattening import flatten
from bscomp.simulation.dispatch import simulate
from bscomp.systems.testbed import testbed
from bscomp.systems.thesis_effects import with_friction_backlash

AMP, F_SQ, T_END, DT = 2.125, 5.0, 0.6, 1e-4
OUTS = ["table.a", "table.v", "rotor.phi", "backlash.f"]
CACHE = Path(__file__).resolve().parent / ".cache"


def square(t):
    """Amplifier command amp.u [V]: the 4.25 V peak-to-peak, 5 Hz square wave (Sec 5.3.1)."""
    return AMP if (t * F_SQ) % 1.0 < 0.5 else -AMP


def _effects(s):
    """Table 5.2 guideway friction and screw-nut backlash
    (:func:`bscomp.systems.thesis_effects.with_friction_backlash`)."""
    return with_friction_backlash(s)


def drive(nut_joint="moving", n_elements=None):
    """Axial + torsional test bed at C with friction and backlash (the issue-16 case), flattened."""
    return flatten(_effects(testbed("axial_torsional", "C", nut_joint=nut_joint, n_elements=n_elements)))


def reduced(n_modes=3, effects=True):
    """The CMS-reduced twin of :func:`drive` (thesis Sec 5.2.3 / 5.3.2: sub-model 1 to 2 exterior DOF, ``n_modes``
    free-interface modes and the rigid-body mode, MA recovery at the moving nut; ``systems/reduced_testbed.py``),
    flattened; ``effects=False``: the moving nut alone."""
    from bscomp.systems.reduced_testbed import reduce_testbed

    full = testbed("axial_torsional", "C", nut_joint="moving")
    return flatten(reduce_testbed(_effects(full) if effects else full, n_modes)[0])


def six_dof(nut_joint="moving"):
    """The full 6-DOF test bed at C with the same friction and backlash, flattened."""
    return flatten(_effects(testbed("full", "C", nut_joint=nut_joint)))


def grid(dt=DT, T=T_END):
    return dt * np.arange(int(round(T / dt)) + 1)


def nrmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)) / np.sqrt(np.mean(np.asarray(b) ** 2)))


def reference(dae, name, t, recompute=False):
    """IDAS rtol 1e-9, atol 1e-12 on ``dae`` over ``t``: ``(outputs, wall [s])``, cached on disk."""
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"ref_{name}_{t[-1]:g}_{len(t)}.npz"
    if path.exists() and not recompute:
        d = np.load(path)
        return {o: d[o] for o in OUTS}, float(json.loads(str(d["meta"]))["wall_s"])
    t0 = time.perf_counter()
    r = simulate(dae, t, inputs={"amp.u": square}, outputs=OUTS, rtol=1e-9, atol=1e-12, max_num_steps=10**7)
    wall = time.perf_counter() - t0
    np.savez(path, meta=json.dumps({"wall_s": wall}), **{o: r[o] for o in OUTS})
    return {o: r[o] for o in OUTS}, wall


def sundae(dae, t, rtol=1e-6, atol=1e-9):
    """scikit-sundae IDA (dense, BDF order <= 2) on the Dae's residual and Jacobian: ``(outputs, wall)``, or
    None without scikit-sundae. Restarted at every input switch (consistent rates by the Dae's Newton)."""
    try:
        from sksundae.ida import IDA
    except ImportError:
        return None
    from bscomp.simulation.common import evaluate_outputs

    p = dae.p0
    F, Jac = dae.F, dae.jacobians
    nx, nz = dae.nx, dae.nz
    iu = dae.u_names.index("amp.u")
    u = np.zeros(dae.nu)

    def res(tt, y, yp, r):                # unknowns [x; z]; the algebraic z's rates do not enter
        r[:] = np.asarray(F(yp[:nx], y[:nx], y[nx:], u, p)).ravel()

    def jac(tt, y, yp, r, cj, JJ):
        _, Jxd, Jx, Jz, _ = Jac(yp[:nx], y[:nx], y[nx:], u, p)
        JJ[:, :nx] = np.asarray(Jx) + cj * np.asarray(Jxd)
        if nz:
            JJ[:, nx:] = np.asarray(Jz)

    t0 = time.perf_counter()
    switches = np.r_[np.arange(0.0, t[-1], 0.5 / F_SQ), t[-1]]
    X, XD, Z = np.zeros((len(t), nx)), np.zeros((len(t), nx)), np.zeros((len(t), nz))
    x, z = dae.x_start.copy(), np.zeros(nz)
    alg = list(range(nx, nx + nz)) or None
    for a, b in zip(switches[:-1], switches[1:], strict=True):
        u[iu] = square(0.5 * (a + b))
        xd, z = dae.initialize(x, u, p, z_guess=z, store=False)
        sel = np.flatnonzero((t >= a - 1e-12) & (t <= b + 1e-12))
        solver = IDA(res, jacfn=jac, rtol=rtol, atol=atol, max_order=2, max_num_steps=10**6, algebraic_idx=alg)
        sol = solver.solve(t[sel], np.r_[x, z], np.r_[xd, np.zeros(nz)])
        X[sel], XD[sel], Z[sel] = sol.y[:, :nx], sol.yp[:, :nx], sol.y[:, nx:]
        x, z = sol.y[-1, :nx], sol.y[-1, nx:]
    U = np.tile(u, (len(t), 1))
    for a, b in zip(switches[:-1], switches[1:], strict=True):
        U[(t > a + 1e-12) & (t <= b + 1e-12), iu] = square(0.5 * (a + b))
    U[0, iu] = square(0.0)
    y = evaluate_outputs(dae, OUTS, XD, X, Z, U, p)
    return y, time.perf_counter() - t0


def forget(dae):
    """Drop what a modal run leaves on the Dae (its simulators, the output expressions' Functions), so the next run
    is timed as a first run on the flattened model (the compiled kernels still load from the disk cache)."""
    for key in [k for k in dae._cache if k == "modal_simulators"
                or (isinstance(k, tuple) and k and k[0] in ("modal_outputs", "modal_other"))]:
        del dae._cache[key]


def timed(fn, repeat=1):
    """``(result, best wall [s], best process CPU [s])`` of ``fn()`` over ``repeat`` calls."""
    best_w = best_c = np.inf
    out = None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        best_w, best_c = min(best_w, time.perf_counter() - w0), min(best_c, time.process_time() - c0)
    return out, best_w, best_c
