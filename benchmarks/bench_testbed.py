"""Test-bed benchmark: flatten + compile time of the full 6-DOF model, and a nut-position x frequency sweep.

1. ``flatten`` (graph -> index-1 Dae, CasADi functions, modal damping) + ``second_order`` of the full
   6-DOF test bed (290 coordinates), best of 3. Goal < 2 s. Also the moving-joint variant
   (``nut_joint="moving"``), flattened once for a sweep.
2. Sweep: 100 nut positions x 1000 frequencies (1-300 Hz), inputs tau and F_d, outputs omega and x
   (Fig 4.2), with our API (:func:`bscomp.linear.sweeps.position_sweep`, ``method="tangent"`` on the test bed with
   the moving joint: one flattening, then per position the joint's tangent update, one symmetric
   eigen-decomposition and the exact FRF) against plain numpy/scipy on the same assembled matrices
   (per position: ``scipy.linalg.eigh`` of (K, M), the diagonal of the projected damping and a
   vectorised modal sum over the 1000 frequencies -- it drops the off-diagonal modal damping of the
   motor's viscous B, so it is the cheaper, approximate computation). Goal < 2 s.
   The old ``method="rebuild"`` path (re-flatten per position) is timed on one position and
   extrapolated.

BLAS is pinned to one thread (both sides) unless OMP_NUM_THREADS is set: on the 2-core CI machine
multi-threaded LAPACK runs the 290x290 eigh 2-30x slower under load. Timings are wall clock.

Run: python benchmarks/bench_testbed.py
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402

from bscomp import flatten, second_order  # noqa: E402
from bscomp.linear.sweeps import _tangent_component, _TangentUpdate, position_sweep  # noqa: E402
from bscomp.systems import get  # noqa: E402
from bscomp.systems.testbed import testbed  # noqa: E402

INPUTS = ["amp.u", "Fd.f"]          # amplifier command (the test bed's default input) and table force
OUTPUTS = ["rotor.w", "table.s"]
N_POS, N_FREQ = 100, 1000


def time_flatten(build, repeat=3):
    """Best-of-``repeat`` wall time [s] of flatten and of flatten + second_order."""
    best_f, best_fs = np.inf, np.inf
    for _ in range(repeat):
        system = build()
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
    the proportional modal damping; drops the coupling the discrete motor damper adds).
    """
    lam, phi = sla.eigh(K, M, driver="gvd")
    lam = np.clip(lam, 0.0, None)
    cd = np.sum(phi * (C @ phi), axis=0)
    b = phi.T @ B                                     # (m, n_in)
    cq, cv = Cq @ phi, Cv @ phi                       # (n_out, m)
    w = 2 * np.pi * freqs
    den = lam[None, :] + 1j * w[:, None] * cd[None, :] - w[:, None] ** 2          # (nf, m)
    c = cq[None, :, :] + 1j * w[:, None, None] * cv[None, :, :]                   # (nf, n_out, m)
    return (c / den[:, None, :]) @ b


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rebuild-positions", type=int, default=1, help="positions timed with method='rebuild'")
    args = ap.parse_args(argv)
    freqs = np.linspace(1.0, 300.0, N_FREQ)
    positions = np.linspace(0.1531, 0.7119, N_POS)          # L..R (toml CHOICE travel)

    print("== flatten + compile (best of 3) ==")
    for label, build, rep in (("full 6-DOF, point port (290)", lambda: get("testbed"), 3),
                              ("axial+torsional (98)", lambda: get("testbed", {"dofs": ("w", "tz")}), 3),
                              ("full 6-DOF, moving joint (290)", lambda: testbed("full", nut_joint="moving"), 1)):
        tf, tfs, _ = time_flatten(build, rep)
        print(f"  {label:32s} flatten {tf:6.2f} s   flatten + second_order {tfs:6.2f} s   (goal < 2 s)")

    print(f"\n== sweep: {N_POS} nut positions x {N_FREQ} frequencies, 2 inputs x 2 outputs, full 6-DOF ==")
    system = testbed("full", nut_joint="moving")
    t0 = time.perf_counter()
    res = position_sweep(lambda: system, positions, freqs=freqs, inputs=INPUTS, outputs=OUTPUTS,
                         method="tangent", progress=False)
    t_api = time.perf_counter() - t0
    st = res.stats                                    # the sweep's own timing of its parts
    t_flat = st["flatten_s"]
    owner = _tangent_component(system, "sn.z0")
    upd = _TangentUpdate(system, "sn.z0", *owner, INPUTS, OUTPUTS)
    mats = []
    so = upd.so0
    for x in positions:                               # assembled matrices for the baseline (untimed)
        M, K, Cs = upd.matrices(x)
        lam, phi, c, _ = upd.modal(x)
        C = M.toarray() @ phi @ np.diag(c) @ phi.T @ M.toarray() + Cs.toarray()
        mats.append((M.toarray(), C, K.toarray(), so.B.toarray(), so.Cq.toarray(), so.Cv.toarray()))
    t0 = time.perf_counter()
    H = np.stack([baseline_frf(*m, freqs) for m in mats])
    t_base = time.perf_counter() - t0
    err = np.max(np.abs(H - res.H)) / np.max(np.abs(res.H))
    t_sweep = st["positions_s"]
    t_after = t_api - t_flat
    print(f"  API position_sweep(method='tangent'): {t_api:6.2f} s total = {t_flat:5.2f} s flatten (compile) + "
          f"{t_after:5.2f} s sweep on the compiled model (goal < 2 s)")
    print(f"    of which {st['linearize_s']:5.2f} s nominal linearization, {st['check_s']:5.2f} s tangent check, "
          f"{t_sweep:5.2f} s for the {N_POS} positions")
    print(f"  numpy/scipy baseline on the assembled matrices: {t_base:6.2f} s   "
          f"ratio API per-position part / baseline {t_sweep / t_base:5.2f}x, sweep on the compiled model / "
          f"baseline {t_after / t_base:5.2f}x")
    print(f"  max |H_baseline - H_API| / max |H| = {err:.1e} (baseline drops the off-diagonal modal damping)")

    k = max(1, min(args.rebuild_positions, N_POS))
    pos = positions[np.linspace(0, N_POS - 1, k).round().astype(int)]
    t0 = time.perf_counter()
    position_sweep("testbed", pos, freqs=freqs, inputs=INPUTS, outputs=OUTPUTS, method="rebuild")
    t_rb = time.perf_counter() - t0
    print(f"  method='rebuild' (re-flatten per position) on {k}: {t_rb:6.2f} s -> {N_POS} positions "
          f"~{t_rb * N_POS / k:6.1f} s")


if __name__ == "__main__":
    main()
