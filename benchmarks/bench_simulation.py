"""1 s of the thesis's open-loop square-wave scenario (Sec 5.3.1: 5 Hz, 4.25 V peak-to-peak) on the
axial + torsional test-bed model (Ch 5, 98 coordinates, 196 states): our simulators vs scipy's
solve_ivp (BDF) on the same linear equations, in one run (issue: nonlinear simulation, item 6).

Runs, all recording the table acceleration and motor speed on a 0.1 ms grid:

* ``idas full``     bscomp.simulate, IDAS on the flattened DAE (BDF order <= 2)
* ``lti full``      bscomp.simulate(method="lti"): exact zero-order-hold stepping (the floor, linear only)
* ``idas reduced``  CMS-reduced model (Sec 5.2.3, modes <= 2 kHz + boundary DOF) in a SecondOrderBlock
* ``lti reduced``
* ``solve_ivp BDF`` baseline: x' = A x + B u of the full linearized model, integrated piecewise between
  the square-wave switches (rtol 1e-6, atol 1e-9, sparse Jacobian)

Accuracy: max |a - a_ref| / max |a_ref| of the table acceleration against ``lti full``.
Run: python benchmarks/bench_simulation.py [T_end]
"""

from __future__ import annotations

import sys
import time

import numpy as np
import scipy.sparse as sp
from scipy.integrate import solve_ivp

import bscomp
from bscomp import System
from bscomp.components import SecondOrderBlock
from bscomp.reduce import reduce_second_order
from bscomp.simulate import simulate
from bscomp.systems.testbed import testbed_axial_torsional

K_A, K_T = 6.4898, 0.4769          # Eq 4.1
U_PP, F_SQ = 4.25, 5.0             # Sec 5.3.1: 4.25 V peak-to-peak, 5 Hz


def torque(t):
    return K_A * K_T * 0.5 * U_PP * (1.0 if (t * F_SQ) % 1.0 < 0.5 else -1.0)


def main(T_end: float = 1.0):
    t = np.arange(0.0, T_end + 1e-12, 1e-4)
    outs = ["table.a", "rotor.w"]
    system = testbed_axial_torsional()
    rows = []

    def run(name, fn):
        t0 = time.perf_counter()
        a, w = fn()
        wall = time.perf_counter() - t0
        rows.append((name, wall, a, w))
        print(f"  {name:<15} {wall:8.2f} s wall", flush=True)

    dae = bscomp.flatten(system)
    run("lti full", lambda: _sim(dae, t, outs, "lti"))
    run("idas full", lambda: _sim(dae, t, outs, "idas"))
    so = bscomp.second_order(dae, inputs=["motor.tau"], outputs=outs)
    red, info = reduce_second_order(so, boundary=["rotor.phi", "sn.nut.w"], f_cut=2000.0)
    rs = System("reduced")
    rs.add("plant", SecondOrderBlock(red))
    rdae = bscomp.flatten(rs)
    routs = ["plant.table_a", "plant.rotor_w"]
    run("idas reduced", lambda: _sim(rdae, t, routs, "idas", u="plant.motor_tau"))
    run("lti reduced", lambda: _sim(rdae, t, routs, "lti", u="plant.motor_tau"))
    run("solve_ivp BDF", lambda: _scipy(so, t))
    ref_a = rows[0][2]
    print(f"\nmodel: {dae.nx} states full, {red.M.shape[0]} coordinates reduced "
          f"(modes up to {info.mode_frequencies.max():.0f} Hz); simulated {T_end} s")
    print(f"{'run':<15} {'wall [s]':>9} {'x real time':>12} {'vs BDF':>8} {'table.a error':>14}")
    t_bdf = rows[-1][1]
    for name, wall, a, _ in rows:
        err = np.max(np.abs(a - ref_a)) / np.max(np.abs(ref_a))
        print(f"{name:<15} {wall:>9.2f} {T_end / wall:>12.2f} {t_bdf / wall:>8.1f} {err:>14.2e}")


def _sim(dae, t, outs, method, u="motor.tau"):
    r = simulate(dae, t, inputs={u: torque}, outputs=outs, method=method, max_num_steps=10**6)
    return r[outs[0]], r[outs[1]]


def _scipy(so, t):
    """Baseline: the same linear equations x' = A x + B u through scipy's BDF, restarted at switches."""
    n = so.n
    M = so.M.toarray()
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ so.K.toarray(), -Minv @ so.C.toarray()]])
    B = np.vstack([np.zeros((n, 1)), Minv @ so.B.toarray()])
    As = sp.csr_matrix(A)
    Ca = so.Ca.toarray()
    Cv = so.Cv.toarray()
    switches = np.arange(0.0, t[-1] + 1e-12, 0.5 / F_SQ)
    switches = np.append(switches, t[-1]) if switches[-1] < t[-1] else switches
    x = np.zeros(2 * n)
    a_out = np.zeros(len(t))
    w_out = np.zeros(len(t))
    for k in range(len(switches) - 1):
        t0, t1 = switches[k], switches[k + 1]
        u = torque(0.5 * (t0 + t1))
        sel = (t >= t0 - 1e-12) & (t <= t1 + 1e-12)
        sol = solve_ivp(lambda _, y, u=u: As @ y + B[:, 0] * u, (t0, t1), x, method="BDF",
                        t_eval=np.clip(t[sel], t0, t1),
                        rtol=1e-6, atol=1e-9, jac=As)
        X = sol.y
        xd = A @ X + B * u
        a_out[sel] = (Ca @ xd[n:] + Cv @ X[n:])[0]
        w_out[sel] = (Ca @ xd[n:] + Cv @ X[n:])[1]
        x = X[:, -1]
    return a_out, w_out


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 1.0)
