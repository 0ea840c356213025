"""Compare the FE model with FRFs measured at two amplifier voltages: how much of the error is the amplitude.

The "measurements" come from the independent FE truth of ``bscomp.systems.truths`` (case ``friction``: another
mesh, mis-set table mass and coupling, arc-tangent guideway friction with F_c = 1151 N), taken the way a test
engineer would: a stepped sine on ``amp.u`` at 0.2 V and at 2 V, 14 frequencies 10-200 Hz, the fundamental of
``rotor.w`` and ``table.a``. Each file states its excitation (``# excitation amp.u: 0.2``, written by
``SteppedSine.to_csv``; a measured file says ``# excitation amp.u: 200 mV``). The model is the
axial + torsional test bed with Table 5.2 friction (tanh, F_c = 2066 N). ``compare`` reports the small-signal
model (friction reduced to its viscous part: a table sliding freely) and the model at the measured amplitude by
the describing function; the report's overlay plots draw both. Before any model, the two files are compared
with each other (``Comparison.amplitude``): they differ beyond noise, so the drive is amplitude-dependent.

Run ``python examples/compare_at_amplitude.py [OUTPUT_FOLDER]`` (default ``out/compare_at_amplitude``); writes
``frf_0.2V.csv``, ``frf_2V.csv`` and ``report/index.html``, prints both summaries (~15 s).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import bscomp
from bscomp.systems import testbed_axial_torsional
from bscomp.systems.thesis_effects import with_friction_backlash
from bscomp.systems.truths import truth_system
from bscomp.validate import compare, load, write_report

FREQS = np.geomspace(10.0, 200.0, 14)
VOLTS = (0.2, 2.0)


def model():
    """The user's model: the FE test bed with the thesis's guideway friction (Table 5.2)."""
    return with_friction_backlash(testbed_axial_torsional(), backlash=False)


def measure(out):
    """Stepped-sine FRFs of the truth at each voltage, written as measurement files stating the excitation."""
    truth, info = truth_system("friction", nut_joint="point")
    paths = []
    for volts in VOLTS:
        t0 = time.perf_counter()
        ss = bscomp.stepped_sine(truth, "amp.u", ["rotor.w", "table.a"], FREQS, volts, jit=True)
        ss.name = f"truth '{info['case']}', stepped sine at {volts:g} V"
        path = out / f"frf_{volts:g}V.csv"
        ss.to_csv(path, units={"amp.u": "V"})               # with '# excitation amp.u: <volts>' (SI)
        paths.append(path)
        print(f"measured {path.name} on the truth ({info['hidden']['friction']['F_c']:.0f} N friction) in "
              f"{time.perf_counter() - t0:.1f} s; largest distortion {100 * ss.distortion.max():.0f} %")
    return paths


def main(out_dir="out/compare_at_amplitude"):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    c = compare(model, [load(p) for p in measure(out)])
    print(c.summary())
    print(f"report: {write_report(c, out / 'report')}")
    return c


if __name__ == "__main__":
    main(*sys.argv[1:2])
