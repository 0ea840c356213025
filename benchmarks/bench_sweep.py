"""Design-sweep benchmark: a 10^4-variant modes sweep of the test bed, serially, on 2 local processes and
on a 2-worker Dask ``distributed.LocalCluster`` (loopback).

Grid: thrust-bearing stiffness ``b1.k_axial`` (10 values, 1.5-4e8 N/m) x coupling stiffness
``coupling.k_T`` (10 values, 2500-6000 N m/rad) x nut position ``sn.z0`` (100 values over the thread),
test bed ``testbed_axial_torsional`` with the moving nut joint (98 coordinates), analysis ``"modes"``
(6 elastic modes and their damping ratios). Per variant: the affine stiffness sensitivities and the nut's
tangent update, one dense ``eigh`` (:mod:`bscomp._sweep_eval`); baseline: the same variant by a full
rebuild (``bscomp.linear.modes`` of the re-built system), timed on a few variants.

Each executor is run cold (every worker flattens the model once: the set-up) and warm (the workers keep
their evaluator). Printed: variants/s and the parallel efficiency ``rate / (2 x serial rate)``.
BLAS is pinned to one thread. On the shared 2-core machine "2 workers" compete with everything else.

Run: python benchmarks/bench_sweep.py [N_VARIANTS]   (default 10000; 1000 for a quick look)
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402

import numpy as np  # noqa: E402

from bscomp import design_sweep  # noqa: E402
from bscomp.design_sweep import design_study  # noqa: E402
from bscomp.linear import modes  # noqa: E402
from bscomp.model import ModelSpec  # noqa: E402

SPEC = ModelSpec("testbed_axial_torsional", {"nut_joint": "moving"})


def grid(n):
    n_pos = max(1, n // 100)
    return {"b1.k_axial": np.linspace(1.5e8, 4.0e8, 10), "coupling.k_T": np.linspace(2500.0, 6000.0, 10),
            "sn.z0": np.linspace(0.16, 0.70, n_pos)}


def run(label, g, executor, serial_rate=None):
    rows = []
    for phase in ("cold", "warm"):
        if phase == "cold":
            design_sweep._CACHE.clear()           # forked workers must not inherit a built model
        t0 = time.perf_counter()
        tab = design_study(SPEC, g, executor=executor)
        wall = time.perf_counter() - t0
        rate = len(tab) / wall
        eff = "" if serial_rate is None else f"{rate / (2 * serial_rate[phase]):.2f}"
        print(f"  {label:<22} {phase:<5} {len(tab):>6} variants {wall:8.2f} s {rate:9.1f} variants/s "
              f"{1e3 / rate:7.2f} ms/variant  efficiency {eff or '-'}", flush=True)
        rows.append((phase, rate, tab))
    return {p: r for p, r, _ in rows}, rows[-1][2]


def main(n=10_000):
    g = grid(n)
    print(f"bench_sweep: {SPEC.source} {SPEC.overrides}, grid {[(k, len(v)) for k, v in g.items()]}; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at start")
    t0 = time.perf_counter()
    for z in (0.2, 0.5, 0.65):
        md = modes(SPEC.with_overrides({"b1.k_axial": 3e8, "coupling.k_T": 4000.0, "sn.z0": z}).system())
    rebuild = (time.perf_counter() - t0) / 3
    print(f"  baseline: full rebuild + modes per variant {rebuild * 1e3:.0f} ms "
          f"(10^4 variants would take {rebuild * 1e4 / 60:.0f} min serially); f1 = "
          f"{md.frequencies[~md.rigid_body][0]:.3f} Hz at z0 = 0.65")
    serial, ref = run("serial", g, "serial")
    with ProcessPoolExecutor(max_workers=2) as pool:
        _, tab_p = run("2 local processes", g, pool, serial)
    assert np.allclose(tab_p.data, ref.data, rtol=1e-12, equal_nan=True)
    try:
        import distributed
    except ImportError:
        print("  2 Dask workers: skipped (pip install 'dask[distributed]')")
        return
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, silence_logs=40) as cluster, \
            distributed.Client(cluster) as client:
        _, tab_d = run("2 Dask workers", g, client.get_executor(), serial)
    assert np.allclose(tab_d.data, ref.data, rtol=1e-12, equal_nan=True)
    print(f"  speed-up of the compiled evaluator over a rebuild: {rebuild * serial['warm']:.0f}x (serial, warm); "
          f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10_000)
