"""Test-bed benchmark: flatten + compile time of the full 6-DOF model, and a nut-position x frequency sweep.

1. ``flatten`` (graph -> index-1 Dae, CasADi functions, modal damping) + ``second_order`` of the full
   6-DOF test bed (290 coordinates), best of 3. Goal < 2 s.
2. Sweep: 100 nut positions x 1000 frequencies (1-300 Hz), inputs tau and F_d, outputs omega and x
   (Fig 4.2), with our API (:func:`bscomp.sweep.position_sweep` on the registered name ``"testbed"``:
   rebuild, flatten, modes and FRF per position) against plain numpy/scipy on the assembled matrices
   (per position: ``scipy.linalg.eigh`` of (K, M), modal damping and residues, and a vectorised modal
   sum over the 1000 frequencies). Goal < 2 s.

Our API costs minutes per position on the 6-DOF model, so by default it runs on ``--api-positions``
positions (default 1; the Ch 5 axial+torsional model on 3) and the 100-position time is extrapolated
linearly (each position is independent work); the baseline runs on the same positions and is
extrapolated the same way. ``--api-positions 100`` runs everything (hours). Timings are wall clock: run
on an idle machine.

Run: python benchmarks/bench_testbed.py [--api-positions N] [--workers W]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.linalg as sla

from bscomp import flatten, second_order
from bscomp.sweep import position_sweep
from bscomp.systems import get

INPUTS = ["motor.tau", "Fd.f"]
OUTPUTS = ["rotor.w", "table.s"]
N_POS, N_FREQ = 100, 1000


def time_flatten(dofs=None, repeat=3):
    """Best-of-``repeat`` wall time [s] of flatten and of flatten + second_order."""
    best_f, best_fs = np.inf, np.inf
    for _ in range(repeat):
        system = get("testbed", {"dofs": dofs} if dofs else None)
        t0 = time.perf_counter()
        dae = flatten(system)
        t1 = time.perf_counter()
        second_order(dae, inputs=INPUTS, outputs=OUTPUTS)
        t2 = time.perf_counter()
        best_f, best_fs = min(best_f, t1 - t0), min(best_fs, t2 - t0)
    return best_f, best_fs, dae


def baseline_frf(M, C, K, B, Cq, Cv, freqs):
    """Plain numpy/scipy FRF of ``M q'' + C q' + K q = B u``, ``y = Cq q + Cv q'`` by modal superposition.

    ``eigh(K, M)`` gives mass-normalised modes; damping is the diagonal of the projected C (exact for
    the proportional modal damping; the rigid-body mode keeps its decay rate B/J).
    """
    lam, phi = sla.eigh(K, M)
    lam = np.clip(lam, 0.0, None)
    cd = np.einsum("ik,ij,jk->k", phi, C, phi)
    b = phi.T @ B                                     # (m, n_in)
    cq, cv = Cq @ phi, Cv @ phi                       # (n_out, m)
    w = 2 * np.pi * freqs
    den = lam[None, :] + 1j * w[:, None] * cd[None, :] - w[:, None] ** 2          # (nf, m)
    c = cq[None, :, :] + 1j * w[:, None, None] * cv[None, :, :]                   # (nf, n_out, m)
    return np.einsum("fom,mi->foi", c / den[:, None, :], b)


def run_api(positions, freqs, dofs, workers):
    t0 = time.perf_counter()
    res = position_sweep("testbed", positions, freqs=freqs, inputs=INPUTS, outputs=OUTPUTS,
                         overrides={"dofs": dofs} if dofs else None, workers=workers)
    return time.perf_counter() - t0, res


def run_baseline(positions, freqs, dofs):
    """Matrices assembled by bscomp (untimed), FRF sweep timed in numpy."""
    mats = []
    for x in positions:
        so = second_order(get("testbed", {"nut_position": float(x), **({"dofs": dofs} if dofs else {})}),
                          inputs=INPUTS, outputs=OUTPUTS)
        mats.append([a.toarray() for a in (so.M, so.C, so.K, so.B, so.Cq, so.Cv)])
    t0 = time.perf_counter()
    H = [baseline_frf(*m, freqs) for m in mats]
    return time.perf_counter() - t0, np.stack(H)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--api-positions", type=int, default=1, help="positions run with our API (6-DOF model)")
    ap.add_argument("--workers", type=int, default=None, help="process pool for our API sweep")
    args = ap.parse_args(argv)
    freqs = np.linspace(1.0, 300.0, N_FREQ)
    all_positions = np.linspace(0.1531, 0.7119, N_POS)          # L..R (toml CHOICE travel)

    print("== flatten + compile (best of 3) ==")
    rows = []
    for label, dofs in (("full 6-DOF (290 coordinates)", None), ("axial+torsional (98)", ("w", "tz"))):
        tf, tfs, dae = time_flatten(dofs)
        rows.append((label, tf, tfs))
        print(f"  {label:32s} flatten {tf:6.2f} s   flatten + second_order {tfs:6.2f} s   (goal < 2 s)")

    print(f"\n== sweep: {N_POS} nut positions x {N_FREQ} frequencies, 2 inputs x 2 outputs ==")
    for label, dofs, k in (("full 6-DOF", None, args.api_positions),
                           ("axial+torsional", ("w", "tz"), max(3, args.api_positions))):
        k = min(k, N_POS)
        pos = all_positions[np.linspace(0, N_POS - 1, k).round().astype(int)]
        t_api, res = run_api(pos, freqs, dofs, args.workers)
        t_base, H = run_baseline(pos, freqs, dofs)
        err = np.max(np.abs(H - res.H)) / np.max(np.abs(res.H))
        scale = N_POS / k
        print(f"  {label:16s} measured on {k} position(s): API {t_api:8.2f} s, numpy baseline {t_base:6.3f} s "
              f"(max rel. difference of H {err:.1e})")
        print(f"  {'':16s} extrapolated to {N_POS}: API {t_api * scale:9.1f} s, baseline {t_base * scale:7.2f} s, "
              f"ratio API/baseline {t_api / t_base:8.0f}x   (goal < 2 s)")


if __name__ == "__main__":
    main()
