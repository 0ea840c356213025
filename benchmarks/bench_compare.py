"""compare's time series of a nonlinear model: ``method="modal"`` at ``residuals.MODAL_TOL`` (what ``compare`` runs
since 2026-12-07), at its default ``tol`` 1e-3, and IDAS at rtol 1e-7 (what it ran before), side by side in one run.

The model is the demo's last comparison: the FE test bed (``testbed_axial_torsional``) with the re-calibrated
values, the guideway friction and the table part that ``bscomp demo`` finds on the bundled truth
``systems/data/truths/axial_torsional/joint_friction`` (values as diagnose prints them), built at the record's nut
position; the input is the record's measured 0.6 s square wave at 5 kHz. Printed: the wall of each (best of
``--repeat``; the first modal run, which builds its set-up, separately), the ratio, the NRMSE of each channel
between the two and, with ``--reference``, against IDAS at rtol 1e-10 (~250 s on the 2-core machine), and the
fit percentages compare reports. BLAS on one thread.

Run: ``python benchmarks/bench_compare.py [--repeat 3] [--reference]``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from importlib import resources  # noqa: E402

import numpy as np  # noqa: E402

from bscomp.components import CoulombFriction, Damper, Fixed, Mass, Spring  # noqa: E402
from bscomp.kernel.flattening import flatten  # noqa: E402
from bscomp.simulation.dispatch import simulate  # noqa: E402
from bscomp.systems import get  # noqa: E402
from bscomp.validate.candidates import DetachedBodyDamping  # noqa: E402
from bscomp.validate.datasets import TimeData  # noqa: E402
from bscomp.validate.measurements import load_all  # noqa: E402
from bscomp.validate.residuals import MODAL_TOL, build_for_data, fit_percent  # noqa: E402

CASE = ("axial_torsional", "joint_friction")


def demo_model(nut_position=None):
    """The FE test bed with what ``bscomp demo`` adds (its printed lines)."""
    s = get("testbed_axial_torsional", {} if nut_position is None else {"nut_position": nut_position})
    s.set("table.m", 232.232)
    s.set("coupling.k_T", 4191.87)
    s.set("b1.k_axial", 2.69515e+08)
    s.add("effect_ground", Fixed())
    s.add("friction", CoulombFriction(F_c_pos=2447.845357, F_c_neg=2447.845357, v_reg=1e-4, d_pos=959.1929429,
                                      d_neg=959.1929429))
    s.connect("friction.flange_a", "effect_ground.flange")
    s.connect("friction.flange_b", "table.flange_b")
    s.add("sub_spring", Spring(c=37569688.88))
    s.add("sub_loss", Damper(d=2458.438384))
    s.add("sub_mass", Mass(m=33.30065567))
    s.connect("table.flange_a", "sub_spring.flange_a")
    s.connect("sub_spring.flange_b", "sub_mass.flange_a")
    s.connect("table.flange_a", "sub_loss.flange_a")
    s.connect("sub_loss.flange_b", "sub_mass.flange_a")
    s.damping = DetachedBodyDamping(s.damping, ["sub_mass.s"])
    return s


def nrmse(y, y0):
    return float(np.sqrt(np.mean((np.asarray(y) - y0) ** 2)) / np.sqrt(np.mean(np.asarray(y0) ** 2)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs of each method (best wall printed)")
    ap.add_argument("--reference", action="store_true", help="also IDAS at rtol 1e-10 (~250 s) for the accuracy")
    a = ap.parse_args(argv)
    root = resources.files("bscomp.systems") / "data" / "truths" / CASE[0] / CASE[1]
    data = next(d for d in load_all([str(root / "time.csv")]) if isinstance(d, TimeData))
    dae = flatten(build_for_data(demo_model, data, None))
    names = list(data.outputs) + ["table.v"]
    run = dict(inputs=dict(data.inputs), outputs=names)
    methods = {f"modal tol {MODAL_TOL:g} (now)": dict(method="modal", modal_options={"tol": MODAL_TOL}),
               "IDAS rtol 1e-7 (before)": dict(method="idas", rtol=1e-7, atol=1e-10),
               "modal tol 1e-3 (default)": dict(method="modal")}
    res, wall = {}, {}
    for label, kw in methods.items():
        times = []
        for _ in range(max(1, a.repeat)):
            t0 = time.perf_counter()
            res[label] = simulate(dae, data.t, **run, **kw)
            times.append(time.perf_counter() - t0)
        wall[label] = times
    if a.reference:
        t0 = time.perf_counter()
        res["IDAS rtol 1e-10 (reference)"] = simulate(dae, data.t, **run, method="idas", rtol=1e-10, atol=1e-13)
        wall["IDAS rtol 1e-10 (reference)"] = [time.perf_counter() - t0]
    print(f"compare's time series, {CASE[1]} truth's record ({data.t.size} samples, {data.t[-1] - data.t[0]:.2f} s), "
          f"the demo's model with the effects found ({len(dae.mech.coordinate_names)} coordinates)")
    for label, times in wall.items():
        first = f" (first {times[0]:.3f} s)" if len(times) > 1 else ""
        print(f"  {label:30s} {min(times):8.3f} s{first}")
    labels = list(methods)
    m, i = min(wall[labels[0]]), min(wall[labels[1]])
    print(f"  ratio IDAS / modal (now): {i / m:.1f}x")
    print("  NRMSE modal (now) vs IDAS 1e-7: " + ", ".join(f"{n} {nrmse(res[labels[0]][n], res[labels[1]][n]):.1e}"
                                                            for n in names))
    ref = res.get("IDAS rtol 1e-10 (reference)")
    for label in labels:
        line = ", ".join(f"{n} {fit_percent(res[label][n], data.outputs[n]):.3f} %" for n in data.outputs)
        print(f"  fit, {label}: {line}")
        if ref is not None:
            print(f"  NRMSE against the reference, {label}: "
                  + ", ".join(f"{n} {nrmse(res[label][n], ref[n]):.1e}" for n in names))


if __name__ == "__main__":
    main()
