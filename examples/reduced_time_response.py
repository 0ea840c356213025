"""Thesis Sec 5.3.2 / Fig 5.14-5.15: the full and the CMS-reduced test bed in the time domain.

The Ch 5 scenario -- 0.6 s of the 5 Hz, 4.25 V peak-to-peak square wave (Fig 5.10) into the axial + torsional
test bed with Table 5.2 guideway friction, screw-nut backlash and the nut moving along the screw -- simulated
with the full FE model (98 coordinates) and with its CMS-reduced twin (sub-model 1 reduced to 6 coordinates,
the moving nut attached through MA recovery; ``bscomp.systems.reduced_testbed``), as the thesis compares them
(635 s vs 135 s in Simulink on a Pentium IV). Both with ``simulate(method="modal")``.

Run ``python examples/reduced_time_response.py OUTPUT_FOLDER [--modes P ...]``; writes
``full_vs_reduced.png`` (table velocity and acceleration with a zoom, Fig 5.14/5.15) and prints the errors
(NRMSE against the full model) and the wall times.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import numpy as np

from bscomp import flatten
from bscomp.simulation import simulate
from bscomp.systems.reduced_testbed import reduce_testbed
from bscomp.systems.testbed import testbed
from bscomp.systems.thesis_effects import with_friction_backlash

AMP, F_SQ, T_END, DT = 2.125, 5.0, 0.6, 1e-4
OUTS = ["table.v", "table.a", "rotor.phi", "backlash.f", "sn.z"]


# ============================================================================ model
def square(t):
    """Amplifier command [V] of Fig 5.10."""
    return AMP if (t * F_SQ) % 1.0 < 0.5 else -AMP


def full_drive():
    """The axial + torsional test bed at C, moving nut, Table 5.2 friction (Eq 5.7) and backlash (Eq 5.8)."""
    return with_friction_backlash(testbed("axial_torsional", "C", nut_joint="moving"))


def nrmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)) / np.sqrt(np.mean(np.asarray(b) ** 2)))


# ============================================================================ solve
def run(dae, t):
    """``(outputs, wall of a repeated run [s])``: the first call builds and caches the set-up (and compiles the
    step kernels to C once when a C compiler is on PATH, ``jit=True``)."""
    jit = shutil.which("gcc") is not None or shutil.which("cc") is not None
    simulate(dae, t, inputs={"amp.u": square}, outputs=OUTS, method="modal", jit=jit)
    t0 = time.perf_counter()
    r = simulate(dae, t, inputs={"amp.u": square}, outputs=OUTS, method="modal", jit=jit)
    return {o: r[o] for o in OUTS}, time.perf_counter() - t0


def main(out_dir: str | Path = "reduced_time_response_out", modes=(3, 10)) -> dict:
    """Simulate, compare, plot; returns ``{P: {output: NRMSE}}`` and the walls."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = DT * np.arange(int(round(T_END / DT)) + 1)
    full = full_drive()
    ref, w_full = run(flatten(full), t)
    print(f"full model: {w_full:.3f} s for {T_END} s ({T_END / w_full:.1f}x real time); the nut travels "
          f"{1e3 * np.ptp(ref['sn.z']):.1f} mm")
    results, walls, errs = {}, {"full": w_full}, {}
    for P in modes:
        red, reduction = reduce_testbed(full, P)
        results[P], walls[P] = run(flatten(red), t)
        errs[P] = {o: nrmse(results[P][o], ref[o]) for o in OUTS if o != "sn.z"}
        print(f"reduced P = {P} ({reduction.n_reduced} coordinates {reduction.names}): {walls[P]:.3f} s "
              f"({T_END / walls[P]:.1f}x real time); NRMSE vs full: "
              + ", ".join(f"{o} {e:.2e}" for o, e in errs[P].items()))

    # ---------------------------------------------------------------- post-process: Fig 5.14 / 5.15
    fig, ax = plt.subplots(3, 1, figsize=(9, 9))
    zoom = (t >= 0.12) & (t <= 0.16)
    for a, (o, unit, sel) in zip(ax, (("table.v", "m/s", slice(None)), ("table.a", "m/s²", slice(None)),
                                      ("table.a", "m/s² (zoom)", zoom)), strict=True):
        a.plot(t[sel], ref[o][sel], "k-", lw=1.6, label="full (98 coordinates)")
        for P, style in zip(modes, ("C1--", "C0:"), strict=False):
            a.plot(t[sel], results[P][o][sel], style, lw=1.2, label=f"CMS-reduced, P = {P}")
        a.set_ylabel(f"{o} [{unit}]")
        a.grid(True, alpha=0.3)
    ax[0].legend(loc="upper right")
    ax[-1].set_xlabel("time [s]")
    fig.suptitle("Ch 5 scenario: friction + backlash + moving nut, full vs CMS-reduced (Fig 5.14/5.15)")
    fig.tight_layout()
    fig.savefig(out / "full_vs_reduced.png", dpi=120)
    plt.close(fig)
    return {"errors": errs, "walls": walls}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir", nargs="?", default="reduced_time_response_out", help="folder for the figure")
    ap.add_argument("--modes", type=int, nargs="+", default=[3, 10], help="kept free-interface modes P")
    args = ap.parse_args()
    main(args.out_dir, tuple(args.modes))
