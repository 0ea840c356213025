"""The test bed's FRF with Table 5.2 guideway friction at a real amplitude: stepped sine and describing function
against the linear FRF.

``bscomp.frf`` linearizes the model at rest, where the regularised friction (Eq 5.7, F_c = 2066 N) acts as a
very steep viscous slope: its FRF is the one of a *stuck* table. A stepped-sine test on the machine (or
``bscomp.stepped_sine`` on the model) drives the amplifier at a chosen voltage; below the breakaway force the
table stays stuck and the two agree, above it the table slides through part of each period and the low-frequency
response changes by an order of magnitude. This script takes both on the axial + torsional test bed at C
(``testbed_axial_torsional`` with ``with_friction_backlash(..., backlash=False)``), amplifier input ``amp.u`` to
the motor speed and the table acceleration, at 0.2 V and 2 V. ``bscomp.describing_frf`` estimates the same
with one harmonic in milliseconds (dashed): equal where the motion is near-sinusoidal, within ~20 % where
stick-slip distorts it; with ``harmonics=5`` (the odd orders up to 9 balanced) within ~2 % there.

Run ``python examples/stepped_sine.py [OUTPUT_FOLDER]`` (default ``out/stepped_sine``); writes
``stepped_sine.png`` (magnitude, phase and distortion) and ``stepped_sine.csv`` per amplitude, and prints the
ratio to the linear FRF, the describing function's difference and the wall times (~5 s).
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

import bscomp
from bscomp.errors import ModelLimitationWarning
from bscomp.files import atomic_path
from bscomp.systems import get
from bscomp.systems.thesis_effects import with_friction_backlash

FREQS = np.geomspace(10.0, 500.0, 16)
DENSE = np.geomspace(10.0, 500.0, 200)        # the describing function costs milliseconds per frequency
AMPLITUDES = (0.2, 2.0)          # amplifier command [V]
OUTS = ["rotor.w", "table.a"]


def main(out_dir="out/stepped_sine"):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    dae = bscomp.flatten(with_friction_backlash(get("testbed_axial_torsional"), backlash=False))
    with warnings.catch_warnings():                    # the point of this script: frf linearizes the friction
        warnings.simplefilter("ignore", ModelLimitationWarning)
        lin = bscomp.frf(dae, "amp.u", OUTS, FREQS)
        lin_dense = bscomp.frf(dae, "amp.u", OUTS, DENSE)
    runs, desc = {}, {}
    for A in AMPLITUDES:
        t0 = time.perf_counter()
        runs[A] = bscomp.stepped_sine(dae, "amp.u", OUTS, FREQS, A, jit=True)
        runs[A].to_csv(out / f"stepped_sine_{A:g}V.csv")
        t1 = time.perf_counter()
        df = bscomp.describing_frf(dae, "amp.u", OUTS, FREQS, A)
        t2 = time.perf_counter()
        df5 = bscomp.describing_frf(dae, "amp.u", OUTS, FREQS, A, harmonics=5)
        t3 = time.perf_counter()
        desc[A] = bscomp.describing_frf(dae, "amp.u", OUTS, DENSE, A)
        print(f"{A:g} V: stepped sine {t1 - t0:.1f} s, describing function {1e3 * (t2 - t1):.0f} ms (5 odd "
              f"harmonics {1e3 * (t3 - t2):.0f} ms) for {len(FREQS)} frequencies")
        for j, o in enumerate(OUTS):
            ratio = np.abs(runs[A].H[:, j, 0] / lin.H[:, j, 0])
            print(f"  |H| / |H_linear| {o:8s}", " ".join(f"{r:6.2f}" for r in ratio))
            err = np.abs(df.H[:, j, 0] / runs[A].H[:, j, 0] - 1)
            print(f"  |H_df / H_ss - 1| {o:7s}", " ".join(f"{e:6.3f}" for e in err))
            err5 = np.abs(df5.H[:, j, 0] / runs[A].H[:, j, 0] - 1)
            print(f"  5 harmonics       {o:7s}", " ".join(f"{e:6.3f}" for e in err5))
    _plot(lin_dense, runs, desc, out / "stepped_sine.png")
    return lin, runs, desc


def _plot(lin, runs, desc, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(3, len(OUTS), figsize=(11, 8), sharex=True)
    for j, o in enumerate(OUTS):
        ax[0, j].loglog(DENSE, np.abs(lin.H[:, j, 0]), "k-", label="frf (linearized at rest: table stuck)")
        ax[1, j].semilogx(DENSE, np.degrees(np.unwrap(np.angle(lin.H[:, j, 0]))), "k-")
        for (A, r), c in zip(runs.items(), ("C0", "C1"), strict=False):
            ax[0, j].loglog(FREQS, np.abs(r.H[:, j, 0]), "o", color=c, ms=4, label=f"stepped sine, {A:g} V")
            ax[1, j].semilogx(FREQS, np.degrees(np.unwrap(np.angle(r.H[:, j, 0]))), "o", color=c, ms=4)
            ax[2, j].semilogx(FREQS, 100 * r.distortion[:, j], "o-", color=c, ms=4)
            d = desc[A].H[:, j, 0]
            ax[0, j].loglog(DENSE, np.abs(d), "--", color=c, label=f"describing function, {A:g} V")
            ax[1, j].semilogx(DENSE, np.degrees(np.unwrap(np.angle(d))), "--", color=c)
        ax[0, j].set_title(f"amp.u -> {o}")
        ax[0, j].set_ylabel("|H| [SI / V]")
        ax[1, j].set_ylabel("phase [deg]")
        ax[2, j].set_ylabel("distortion [%]")
        ax[2, j].set_xlabel("frequency [Hz]")
        for a in ax[:, j]:
            a.grid(True, which="both", alpha=0.3)
    ax[0, 0].legend(fontsize=8)
    fig.suptitle("Test bed with Table 5.2 guideway friction: FRF at a real amplitude vs the linearized FRF")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    print(f"wrote {path}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
