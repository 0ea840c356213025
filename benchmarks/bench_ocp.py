"""Optimal-control solve time (issue: optimal trajectories, item 5): minimum-time rest-to-rest table
move with torque, velocity and acceleration bounds, on the CMS-reduced test-bed drive and on the
axial + torsional model, for N = 100, 200, 400 intervals; each solution is re-simulated with IDAS and
the final-position error reported. Baseline: the same problem on the rigid-body model (Eq 4.2) as the
floor of what a transcription costs.

Run: python benchmarks/bench_ocp.py [N ...]
"""

from __future__ import annotations

import math
import sys
import time

import bscomp
from bscomp import System
from bscomp.components import FixedRotational, Inertia, SecondOrderBlock, Torque, TorsionalDamper
from bscomp.optimal import Ocp
from bscomp.reduce import reduce_second_order
from bscomp.systems.testbed import testbed_axial_torsional

R_G = 0.010 / (2 * math.pi)
MOVE = 0.02          # m
TAU_MAX = 8.0        # N m (amplifier/motor limit used for the study)
V_MAX = 1.0          # m/s (60 m/min, Table 5.4)
A_MAX = 1.5 * 9.81   # m/s^2 (1.5 G, Table 5.4)


def reduced_drive():
    so = bscomp.second_order(testbed_axial_torsional(), inputs=["motor.tau"],
                             outputs=["table.s", "table.v", "table.a", "rotor.phi"])
    red, _ = reduce_second_order(so, boundary=["rotor.phi", "sn.nut.w"], f_cut=2000.0)
    s = System("reduced_drive")
    s.add("plant", SecondOrderBlock(red))
    return s, "plant.motor_tau", "plant.table_s", "plant.table_v", "plant.table_a"


def rigid_drive():
    s = System("rigid")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=8.55e-3))
    s.add("B", TorsionalDamper(d=0.0321))
    s.add("ground", FixedRotational())
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("B.flange_a", "ground.flange")
    s.connect("B.flange_b", "rotor.flange_b")
    return s


def solve(system, u, pos_state, final, vel_out=None, acc_out=None, N=100):
    ocp = Ocp(system, N=N).bound(u, -TAU_MAX, TAU_MAX)
    if vel_out:
        ocp.bound(vel_out, -V_MAX, V_MAX)
    if acc_out:
        ocp.bound(acc_out, -A_MAX, A_MAX)
    ocp.initial({}).final(final).minimize_time(T_guess=0.1)
    t0 = time.perf_counter()
    res = ocp.solve()
    return res, time.perf_counter() - t0


def main(Ns=(100, 200, 400)):
    print(f"{'model':<18} {'N':>4} {'solve [s]':>10} {'iters':>6} {'T [s]':>8} {'resim final pos err':>20}")
    s = rigid_drive()
    for N in Ns:
        r, wall = solve(s, "motor.tau", "rotor.phi", {"rotor.phi": MOVE / R_G}, N=N)
        print(f"{'rigid (Eq 4.2)':<18} {N:>4} {wall:>10.2f} {r.stats['iter_count']:>6} {r.T:>8.4f} {'-':>20}")
    s, u, ys, yv, ya = reduced_drive()
    dae = bscomp.flatten(s)
    nut = [n for n in dae.x_names if n.endswith("q1.q")][0]  # exterior DOF 2: the nut's axial motion
    for N in Ns:
        try:
            r, wall = solve(dae, u, None, {nut: -MOVE}, vel_out=yv, acc_out=ya, N=N)
            sim, dev = r.resimulate(outputs=[ys])
            err = abs(abs(sim[ys][-1]) - MOVE) / MOVE
            print(f"{'CMS reduced':<18} {N:>4} {wall:>10.2f} {r.stats['iter_count']:>6} {r.T:>8.4f} {err:>20.2e}")
        except bscomp.BscompError as exc:
            print(f"{'CMS reduced':<18} {N:>4} failed: {str(exc)[:300]}")


if __name__ == "__main__":
    main(tuple(int(a) for a in sys.argv[1:]) or (100, 200, 400))
