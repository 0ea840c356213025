"""Stepped-sine benchmark: the FRF of the test bed with Table 5.2 guideway friction at 2 V, by simulation.

``bscomp.stepped_sine(dae, "amp.u", ["rotor.w", "table.a"], freqs, 2.0)`` on the axial + torsional test bed at C
with the friction of ``with_friction_backlash(..., backlash=False)`` (196 states), 8 frequencies 10-400 Hz:
``method="modal"`` (``jit=True``, kernels from the disk cache); then, on the lowest and the highest of them,
against the same stepped sine run by IDAS (``method="idas"``, rtol 1e-6 -- the integrator a user would otherwise
reach for; all 8 did not finish in 12 min), and the difference of the two FRFs. Printed: wall per method, the
ratio, the largest relative difference of |H|, the linearized FRF's ratio to the stepped sine at 10 Hz (what the
linearization misses at this amplitude); and the describing function (``bscomp.describing_frf``, one harmonic)
on the 8 frequencies beside the stepped sine, with their difference.

BLAS pinned to one thread. Run: ``python benchmarks/bench_stepped_sine.py [--quick]`` (``--quick``: 3 frequencies).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

import bscomp  # noqa: E402
from bscomp.errors import ModelLimitationWarning  # noqa: E402
from bscomp.systems import get  # noqa: E402
from bscomp.systems.thesis_effects import with_friction_backlash  # noqa: E402

OUTS = ["rotor.w", "table.a"]


def main(quick=False):
    dae = bscomp.flatten(with_friction_backlash(get("testbed_axial_torsional"), backlash=False))
    freqs = np.geomspace(10.0, 400.0, 3 if quick else 8)
    bscomp.stepped_sine(dae, "amp.u", OUTS, freqs[:1], 2.0, jit=True, settle=4, periods=1)   # compile once
    t0 = time.perf_counter()
    a = bscomp.stepped_sine(dae, "amp.u", OUTS, freqs, 2.0, jit=True)
    w_all = time.perf_counter() - t0
    print(f"  modal (jit)      {w_all:8.2f} s for {freqs.size} frequencies (settled after "
          f"{a.settle_periods.tolist()} periods)", flush=True)
    t0 = time.perf_counter()
    df = bscomp.describing_frf(dae, "amp.u", OUTS, freqs, 2.0)
    w_df = time.perf_counter() - t0
    e = np.abs(np.abs(df.H) / np.abs(a.H) - 1)[:, :, 0]
    print(f"  describing_frf   {w_df:8.3f} s for the same (one harmonic; {w_all / w_df:.0f}x faster); | |H_df| / "
          f"|H_stepped| - 1 | per frequency, table.a: {np.round(e[:, 1], 3).tolist()}", flush=True)
    sub = freqs[[0, -1]]                      # the baseline on two of them (IDAS takes minutes per frequency)
    walls, res = {}, {}
    for label, kw in (("modal (jit)", {"jit": True}), ("IDAS rtol 1e-6", {"method": "idas", "rtol": 1e-6})):
        t0 = time.perf_counter()
        res[label] = bscomp.stepped_sine(dae, "amp.u", OUTS, sub, 2.0, **kw)
        walls[label] = time.perf_counter() - t0
        print(f"  {label:<16} {walls[label]:8.2f} s for {sub.tolist()} Hz", flush=True)
    d = np.max(np.abs(np.abs(res["modal (jit)"].H) / np.abs(res["IDAS rtol 1e-6"].H) - 1))
    print(f"  ratio {walls['IDAS rtol 1e-6'] / walls['modal (jit)']:.0f}x; largest | |H_modal| / |H_idas| - 1 | = "
          f"{d:.1e}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelLimitationWarning)
        lin = bscomp.frf(dae, "amp.u", OUTS, freqs)
    print(f"  linearized FRF at {freqs[0]:g} Hz: table.a |H_lin| / |H_2V| = {abs(lin.H[0, 1, 0] / a.H[0, 1, 0]):.3f}")
    return a, res


if __name__ == "__main__":
    main("--quick" in sys.argv)
