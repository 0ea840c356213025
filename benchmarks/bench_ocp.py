"""Optimal-control solve time (issue #7): minimum-time rest-to-rest 100 mm table move on the test bed.

The same problem on three models, for N = 100, 200, 400 intervals (Radau degree 3, Ipopt + MUMPS):

* **rigid** (baseline): the rigid-body model of Eq 4.2, ``J phi'' + B phi' = tau`` (J = 8.55e-3 kg m^2,
  B = 0.0321 kg m^2/s, Sec 4.2.1): the floor of what a transcription costs;
* **CMS reduced**: the axial + torsional test bed (C position) reduced by Component Mode Synthesis
  (thesis Sec 5.2.3) with the exterior DOF ``rotor.phi`` and ``sn.nut.w``, free-interface modes up to
  2 kHz plus the rigid-body mode: 6 coordinates, modes 119 / 275 / 1235 / 2150 / 2996 Hz;
* **axial+torsional**: the unreduced model (98 DOF, 196 states, modes to 182 kHz), solved with
  ``Ocp(coordinates="modal")`` (the real modal coordinates of the linear model; for its 196 states the
  sparse form: modal collocation states kept as variables, see docs/optimal.md) and
  ``final(..., rest_below_hz=2000)``: arrival at equilibrium of the modes below
  2 kHz (the reduced model's cut-off) instead of all 98 velocities zero, which is a square, degenerate
  condition on a 100-interval input (Ipopt stalls at a violation of 3e-6, measured).

Limits: |table velocity| <= 1 m/s (60 m/min) and |table acceleration| <= 1.5 G (Table 5.4);
|motor torque| <= 43 N m, the peak torque of the test bed's drive (thesis Sec 5.3.3). On the rigid
model the velocity bound is the rotor's (1 m/s / r_g) and the acceleration bound is implied by the torque.

Each solution is re-simulated with IDAS (``OcpResult.resimulate``) on the model it was solved on;
the re-simulation error is ``max_t |table.s_sim(t) - table.s_ocp(t)| / move`` over the grid the OCP
predicts (OCP values linearly interpolated between its grid points). Solve time is the wall time
of ``Ocp.solve()`` (transcription + Ipopt), from a cold start, model already flattened.

Run: python benchmarks/bench_ocp.py [N ...] [--full-max-N K] [--full-only]
(K: largest N tried on the full model; --full-only skips the rigid and reduced models)
"""

from __future__ import annotations

import argparse
import math
import time

import bscomp
from bscomp import System
from bscomp.components import FixedRotational, Inertia, SecondOrderBlock, Torque, TorsionalDamper
from bscomp.linear.reduction import reduce_second_order
from bscomp.optimal import Ocp
from bscomp.systems.testbed import testbed_axial_torsional

R_G = 0.010 / (2 * math.pi)   # lead / 2 pi [m/rad] (Sec B.1)
MOVE = 0.100                  # m (Sec 5.3.3: the 100 mm rapid move)
TAU_MAX = 43.0                # N m: peak torque of the test bed's drive (Sec 5.3.3)
V_MAX = 1.0                   # m/s (60 m/min, Table 5.4)
A_MAX = 1.5 * 9.81            # m/s^2 (1.5 G, Table 5.4)
J_RIGID, B_RIGID = 8.55e-3, 0.0321   # Eq 4.2, Sec 4.2.1


def reduced_drive(nut_position="C"):
    """CMS-reduced axial+torsional test bed in a System: (system, input, s, v, a, nut coordinate state)."""
    so = bscomp.second_order(testbed_axial_torsional(nut_position=nut_position, drive_input="torque"),
                             inputs=["motor.tau"],
                             outputs=["table.s", "table.v", "table.a", "rotor.phi"])
    red, _ = reduce_second_order(so, boundary=["rotor.phi", "sn.nut.w"], f_cut=2000.0)
    s = System("reduced_drive")
    s.add("plant", SecondOrderBlock(red))
    q_nut = f"plant.q{red.coordinates.index('sn.nut.w')}.q"
    return s, "plant.motor_tau", "plant.table_s", "plant.table_v", "plant.table_a", q_nut


def rigid_drive():
    s = System("rigid")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J_RIGID))
    s.add("B", TorsionalDamper(d=B_RIGID))
    s.add("ground", FixedRotational())
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("B.flange_a", "ground.flange")
    s.connect("B.flange_b", "rotor.flange_b")
    return s


def solve(model, u, final, bounds, N, T_guess=0.2, fixed=(), coordinates="physical", rest_below_hz=None):
    ocp = Ocp(model, N=N, coordinates=coordinates).bound(u, -TAU_MAX, TAU_MAX)
    for name in fixed:                      # other inputs (the table disturbance force) held at 0
        ocp.bound(name, 0.0, 0.0)
    for name, lim in bounds.items():
        ocp.bound(name, -lim, lim)
    ocp.initial({}).final(final, rest_below_hz=rest_below_hz).minimize_time(T_guess=T_guess)
    t0 = time.perf_counter()
    res = ocp.solve()
    return res, time.perf_counter() - t0


def row(label, N, wall, base, r, err):
    ratio = f"{wall / base:.1f}x" if base else "-"
    e = f"{err:.2e}" if err is not None else "-"
    print(f"{label:<18} {N:>4} {wall:>9.2f} {ratio:>8} {r.stats['iter_count']:>6} {r.T:>8.4f} {e:>12}", flush=True)


def main(Ns=(100, 200, 400), full_max_N=400, full_only=False):
    print(f"{'model':<18} {'N':>4} {'solve[s]':>9} {'vs rigid':>8} {'iters':>6} {'T [s]':>8} {'resim err':>12}")
    base = {N: None for N in Ns}
    rig = bscomp.flatten(rigid_drive())
    for N in () if full_only else Ns:
        r, wall = solve(rig, "motor.tau", {"rotor.phi": MOVE / R_G}, {"rotor.w": V_MAX / R_G}, N)
        base[N] = wall
        sim, dev = r.resimulate(outputs=["rotor.phi"])
        row("rigid (Eq 4.2)", N, wall, None, r, dev["rotor.phi"])
    s, u, ys, yv, ya, q_nut = reduced_drive()
    red = bscomp.flatten(s)
    sign = -1.0   # table.s = -sn.nut.w: the table axis is the screw's -z (systems/testbed.py)
    for N in () if full_only else Ns:
        try:
            r, wall = solve(red, u, {q_nut: sign * MOVE}, {yv: V_MAX, ya: A_MAX}, N)
            sim, dev = r.resimulate(outputs=[ys])
            row("CMS reduced", N, wall, base[N], r, dev[ys])
        except bscomp.BscompError as exc:
            print(f"{'CMS reduced':<18} {N:>4} failed: {str(exc)[:300]}", flush=True)
    full = bscomp.flatten(testbed_axial_torsional(drive_input="torque"))
    for N in Ns:
        if N > full_max_N:
            print(f"{'axial+torsional':<18} {N:>4} skipped (--full-max-N {full_max_N})", flush=True)
            continue
        try:
            r, wall = solve(full, "motor.tau", {"sn.nut.w": sign * MOVE}, {"table.v": V_MAX, "table.a": A_MAX}, N,
                            fixed=("Fd.f",), coordinates="modal", rest_below_hz=2000.0)
            sim, dev = r.resimulate(outputs=["table.s"])
            row("axial+torsional", N, wall, base[N], r, dev["table.s"])
            if N == min(n for n in Ns if n <= full_max_N):
                # the same (modal, rest below 2 kHz) problem on the reduced model, for comparison
                r2, wall2 = solve(red, u, {q_nut: sign * MOVE}, {yv: V_MAX, ya: A_MAX}, N, coordinates="modal",
                                  rest_below_hz=2000.0)
                _, dev2 = r2.resimulate(outputs=[ys])
                row("CMS red. (modal)", N, wall2, base[N], r2, dev2[ys])
        except bscomp.BscompError as exc:
            print(f"{'axial+torsional':<18} {N:>4} failed: {str(exc)[:300]}", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("N", nargs="*", type=int, default=[100, 200, 400])
    ap.add_argument("--full-max-N", type=int, default=400)
    ap.add_argument("--full-only", action="store_true", help="only the 98-DOF model (and its reduced comparison)")
    a = ap.parse_args()
    main(tuple(a.N), a.full_max_N, a.full_only)
