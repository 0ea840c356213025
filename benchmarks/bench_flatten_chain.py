"""Flatten + linearize time of an N-DOF spring-mass chain (issue: acausal kernel, item 11).

Times our pipeline (build System -> flatten -> second-order linearization, and the dense python-control
StateSpace for N <= 1000) against a hand-written numpy/scipy baseline that assembles the same sparse
M, K directly, for N = 100, 300, 1000, 3000, and prints the growth exponent of our time.

Run: python benchmarks/bench_flatten_chain.py
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from bscomp import flatten, linearize, second_order
from bscomp.systems import mass_spring_chain


def build(N, m=0.1, k=1.0e6):
    return mass_spring_chain([m] * N, [k] * N, name=f"chain{N}", first=0)


def baseline(N, m=0.1, k=1.0e6):
    """Hand-written sparse M, K of the same chain (what a MATLAB/numpy user would type)."""
    M = sp.identity(N, format="csr") * m
    main = np.full(N, 2 * k)
    main[-1] = k
    K = sp.diags([main, -k * np.ones(N - 1), -k * np.ones(N - 1)], [0, 1, -1], format="csr")
    B = np.zeros((N, 1))
    B[-1] = 1.0
    return M, K, B


def main():
    Ns = [100, 300, 1000, 3000]
    rows = []
    for N in Ns:
        t0 = time.perf_counter()
        s = build(N)
        t1 = time.perf_counter()
        dae = flatten(s)
        t2 = time.perf_counter()
        so = second_order(dae, inputs=["F.f"], outputs=[f"m{N - 1}.s"])
        t3 = time.perf_counter()
        t_ss = float("nan")
        if N <= 1000:
            linearize(dae, inputs=["F.f"], outputs=[f"m{N - 1}.s"])
            t_ss = time.perf_counter() - t3
        tb0 = time.perf_counter()
        M, K, B = baseline(N)
        tb = time.perf_counter() - tb0
        err = abs(so.K - K).max() / 1e6 + abs(so.M - M).max() / 0.1
        rows.append((N, t1 - t0, t2 - t1, t3 - t2, t_ss, tb, err))
    print(f"{'N':>6} {'build[s]':>9} {'flatten[s]':>11} {'2nd-order[s]':>13} {'StateSpace[s]':>14} "
          f"{'numpy[s]':>9} {'ratio':>8} {'|dK|,|dM|':>10}")
    for N, tbd, tf, tl, tss, tb, err in rows:
        ratio = (tf + tl) / tb
        print(f"{N:>6} {tbd:>9.3f} {tf:>11.3f} {tl:>13.3f} {tss:>14.3f} {tb:>9.5f} {ratio:>8.0f} {err:>10.1e}")
    t = np.array([r[2] + r[3] for r in rows])
    n = np.array([r[0] for r in rows], float)
    slope = np.polyfit(np.log(n), np.log(t), 1)[0]
    print(f"growth exponent of flatten+linearize (fit over N = {Ns}): {slope:.2f}")
    print("ratio = (flatten + second-order linearization) / hand-assembled numpy matrices")


if __name__ == "__main__":
    main()
