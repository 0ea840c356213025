"""A design study of the thesis test bed: the first axial mode over thrust-bearing and coupling stiffness,
and over the nut position, as a tidy table and first-mode maps (docs/sweeps.md).

Run: python examples/design_sweep.py OUT_DIR [--dask]

``--dask`` runs the same study on a 2-worker ``distributed.LocalCluster`` (loopback) instead of the local
process pool and checks that the table is the same.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from bscomp.design_sweep import design_study
from bscomp.model import ModelSpec


def main(out_dir="out/design_sweep", dask=False):
    # ---- model: the Ch 5 test bed with the moving nut joint (the nut position is the parameter sn.z0)
    spec = ModelSpec("testbed_axial_torsional", {"nut_joint": "moving"})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    # ---- solve: 25 x 25 bearing x coupling stiffness at the centre, and 25 x 40 bearing x nut position
    stiff = {"b1.k_axial": np.linspace(1.0e8, 5.0e8, 25), "coupling.k_T": np.linspace(2000.0, 8000.0, 25),
             "sn.z0": [0.4325]}
    travel = {"b1.k_axial": np.linspace(1.0e8, 5.0e8, 25), "sn.z0": np.linspace(0.153, 0.712, 40)}
    t0 = time.perf_counter()
    tab = design_study(spec, stiff)                       # local process pool (all CPUs)
    tab2 = design_study(spec, travel)
    print(f"{len(tab) + len(tab2)} variants in {time.perf_counter() - t0:.1f} s "
          f"({tab.stats['executor']}; kinds {tab.stats['kinds']})")
    if dask:
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None) as cluster, \
                Client(cluster) as client:
            remote = design_study(spec, stiff, executor=client.get_executor())
        print(f"Dask: same table: {np.allclose(remote.data, tab.data, rtol=1e-12)}")

    # ---- post-process: table files and the first-mode maps
    labels = {"b1.k_axial": "thrust-bearing pair b1.k_axial [N/m]", "coupling.k_T": "coupling k_T [N m/rad]",
              "sn.z0": "nut position sn.z0 [m] (x from the free end A)", "f1": "f1 [Hz]", "f2": "f2 [Hz]"}
    tab.to_csv(out / "first_mode_stiffness.csv")
    tab2.to_csv(out / "first_mode_travel.csv")
    tab.plot_map("b1.k_axial", "coupling.k_T", "f1", path=out / "sweep_first_mode_map.png",
                 title="test bed, nut at C: first elastic mode f1 [Hz]", labels=labels)
    tab.plot_map("b1.k_axial", "coupling.k_T", "f2", path=out / "sweep_second_mode_map.png",
                 title="test bed, nut at C: second elastic mode f2 [Hz]", labels=labels)
    tab2.plot_map("sn.z0", "b1.k_axial", "f1", path=out / "sweep_first_mode_travel.png",
                  title="test bed: first elastic mode f1 [Hz] over the nut travel", labels=labels)
    k = int(np.argmin(np.abs(tab["b1.k_axial"] - 2.7e8) + np.abs(tab["coupling.k_T"] - 4000.0) / 1e3))
    print(f"f1 = {tab['f1'][k]:.1f} Hz at k_axial {tab['b1.k_axial'][k]:.3g}, k_T {tab['coupling.k_T'][k]:.0f}; "
          f"range {np.nanmin(tab['f1']):.1f}-{np.nanmax(tab['f1']):.1f} Hz")
    return tab, tab2


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(args[0] if args else "out/design_sweep", dask="--dask" in sys.argv)
