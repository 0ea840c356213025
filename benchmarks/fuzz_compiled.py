"""Differential fuzz of the compiled evaluator's time series (``CompiledModel.simulate``, what ``diagnose`` and
calibration rank candidates with) on drives it was not built for.

The random chains of ``benchmarks/fuzz_modal.py`` (2-4 masses, one link a clearance with a 1-30x stiffer contact,
Coulomb or Stribeck friction to ground), driven by a square wave of 5-60 Hz at 0.5-4x the friction force on the
last mass, held per 0.1 ms sample (what a measured input is), 0.2 s. Per case: the last mass's velocity and
acceleration against IDAS at rtol 1e-10, atol 1e-13 on the same held input (the reference), the worst NRMSE
(RMS error over the reference's peak-to-peak), the sub-steps used and the wall time; then the median, the count
above 1e-2 and the worst.

    python benchmarks/fuzz_compiled.py [FIRST LAST]      # seeds FIRST..LAST-1 (default 0 30)

``--native``: instead, the sample compiled to C (``bscomp.simulation.compiled_hot``, every shape compiled at its
first run) against the virtual machine on the same chains -- equal to the bit, or the first sample that differs
and by how much (``docs/validation.md``, "Engine": 4 of 80 differed until the C compiler's SLP vectorizer was
turned off).

    python benchmarks/fuzz_compiled.py --native [FIRST LAST]
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from unittest import mock

import numpy as np
from fuzz_modal import chain, nrmse

from bscomp.kernel.flattening import flatten
from bscomp.simulation import compiled_hot, simulate
from bscomp.simulation.compiled import CompiledModel

DT, T_END = 1e-4, 0.2


def draw(seed):
    """``(system, t, u, outputs)`` of one seed: the chain, the sample times, the held square wave, the last mass's
    velocity and acceleration."""
    rng = np.random.default_rng(seed)
    system, F_c, last = chain(rng)
    amp, f = F_c * rng.uniform(0.5, 4), rng.uniform(5, 60)
    rng.random()                                  # fuzz_modal's square-or-sine draw: always the square wave here
    t = np.round(np.arange(int(round(T_END / DT)) + 1) * DT, 12)
    u = amp * np.sign(np.sin(2 * np.pi * f * t) + 1e-12)
    return system, t, u, [f"m{last}.v", f"m{last}.a"]


def case(seed):
    """``(worst NRMSE, sub-steps used, wall [s])`` of one seed (module docstring)."""
    system, t, u, outs = draw(seed)

    def held(tt):                                 # the sample's value until the next sample
        return u[min(int(np.floor(tt / DT + 1e-9)), u.size - 1)]

    ref = simulate(flatten(system), t, inputs={"F.f": held}, outputs=outs, rtol=1e-10, atol=1e-13,
                   max_num_steps=10**7)
    cm = CompiledModel(system, ["F.f"], outs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        y = cm.simulate({}, t, {"F.f": u})
        wall = time.perf_counter() - t0
    return max(nrmse(y[o], np.asarray(ref[o])) for o in outs), cm.stats.get("n_sub_used", 4), wall


def native_case(seed):
    """``(first differing sample or None, worst difference over the outputs' scale, compiled?)``: the compiled sample
    against the virtual machine on one seed's chain (``--native``)."""
    system, t, u, outs = draw(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with mock.patch.dict(os.environ, {"BSCOMP_NATIVE_STEPS": "0"}):
            ref = CompiledModel(system, ["F.f"], outs).simulate({}, t, {"F.f": u})
        with mock.patch.object(compiled_hot, "HOT_WORK", 0.0), mock.patch.object(compiled_hot, "BACKGROUND", False):
            cm = CompiledModel(system, ["F.f"], outs)
            got = cm.simulate({}, t, {"F.f": u})
    first, worst = None, 0.0
    for o in outs:
        a, b = np.asarray(ref[o]), np.asarray(got[o])
        k = np.flatnonzero(a != b)
        if k.size:
            first = int(k[0]) if first is None else min(first, int(k[0]))
            worst = max(worst, float(np.max(np.abs(a - b)) / max(np.max(np.abs(a)), 1e-300)))
    return first, worst, bool(cm.stats["native_steps"])


def main_native(first=0, last=30):
    differ = 0
    for seed in range(first, last):
        k, worst, compiled = native_case(seed)
        differ += k is not None
        said = "equal to the bit" if k is None else f"differ from sample {k} on, by {worst:.1e} of the scale"
        print(f"seed {seed:3d}: {'compiled' if compiled else 'NOT compiled'}, {said}", flush=True)
    print(f"\n{last - first} chains: {differ} differ from the virtual machine")


def main(first=0, last=30):
    errs = []
    for seed in range(first, last):
        e, n_sub, wall = case(seed)
        errs.append(e)
        print(f"seed {seed:3d}: worst NRMSE {e:.1e}, {n_sub} sub-steps, {wall:.2f} s", flush=True)
    errs = np.array(errs)
    print(f"\n{errs.size} cases: median {np.median(errs):.1e}, above 1e-2 in {int(np.sum(errs > 1e-2))}, worst "
          f"{errs.max():.1e} (seed {first + int(np.argmax(errs))})")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--native"]
    (main_native if "--native" in sys.argv else main)(*[int(a) for a in args[:2]])
