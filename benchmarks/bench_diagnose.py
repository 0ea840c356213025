"""Diagnose benchmark: one whole ``diagnose`` and the model evaluations it is made of, new engine vs old.

1. ``diagnose`` of 1 FRF file (2 pairs, 300 points) + one 0.6 s time series at 5 kHz (4 channels):
   on ``testbed_axial_torsional`` (the bundled truth cases of ``systems/data/truths/axial_torsional``,
   98 coordinates) -- goal <= 60 s -- and on ``validation_drive`` (the bundled demo data,
   ``systems/data/validation``) -- goal <= 15 s. Wall clock of the whole call, and what it found.
2. One evaluation of the FE test bed with Table 5.2 guideway friction (the kind a fit repeats hundreds of
   times): the shared engine :class:`bscomp.simulation.compiled.CompiledModel` (modal coordinates, exact ZOH, Newton
   on the friction law) against the old private engine (``benchmarks/_old_evaluate.py``, moved out of the
   library; 3-stage Radau on the full 196-state DAE, ``fast_newton`` per step) -- which is timed on the
   first 0.02 s and extrapolated, since a whole run did not finish in 900 s -- and against
   ``bscomp.simulate`` (IDAS, rtol 1e-6).
   Also one FRF evaluation (2 pairs x 300 frequencies): CompiledModel (modal, truncated + residual
   flexibility) against the old ``FrfEvaluator`` (a dense 196x196 solve per frequency).

BLAS pinned to one thread (as diagnose does itself). Run: ``python benchmarks/bench_diagnose.py [--quick]``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from importlib import resources  # noqa: E402

import numpy as np  # noqa: E402

from bscomp.components import Fixed  # noqa: E402
from bscomp.components.coulomb_friction import CoulombFriction  # noqa: E402
from bscomp.kernel.flattening import flatten  # noqa: E402
from bscomp.simulation.compiled import CompiledModel  # noqa: E402
from bscomp.systems import get  # noqa: E402
from bscomp.validate.diagnostics import diagnose  # noqa: E402
from bscomp.validate.measurements import load_all  # noqa: E402

OUTS = ["rotor.phi", "rotor.w", "table.s", "table.a"]


def _truth_files(model, case):
    root = resources.files("bscomp.systems") / "data" / "truths" / model / case
    return [str(root / "frf.csv"), str(root / "time.csv")], json.loads((root / "truth.json").read_text())


def bench_diagnose(cases):
    rows = []
    for case in cases:
        files, truth = _truth_files("axial_torsional", case)
        t0 = time.perf_counter()
        d = diagnose("testbed_axial_torsional", load_all(files), max_effects=2)
        wall = time.perf_counter() - t0
        found = ", ".join(f"{a.name} {a.values}" for a in d.accepted) or "nothing"
        rows.append(("testbed_axial_torsional", case, wall, d.stats["evaluations"], found, truth["hidden"]))
    data = resources.files("bscomp.systems") / "data" / "validation"
    t0 = time.perf_counter()
    d = diagnose("validation_drive", load_all([str(data / "frf.csv"), str(data / "time.csv")]), max_effects=2)
    rows.append(("validation_drive", "demo data", time.perf_counter() - t0, d.stats["evaluations"],
                 ", ".join(f"{a.name}" for a in d.accepted) or "nothing", "nut-table joint + guideway friction"))
    print("\n1. diagnose (FRF file + 0.6 s time series at 5 kHz), wall clock")
    for model, case, wall, nev, found, hidden in rows:
        goal = 60 if model.startswith("testbed") else 15
        print(f"  {model:<24} {case:<15} {wall:7.1f} s  (goal <= {goal} s: {'met' if wall <= goal else 'NOT met'}); "
              f"{nev} evaluations; found: {found}")
        print(f"  {'':<24} {'':<15} truth: {hidden}")


def _friction_bed():
    """The FE test bed (axial + torsional) with Table 5.2's guideway friction (2066 N) between table and ground."""
    s = get("testbed_axial_torsional")
    s.add("friction", CoulombFriction(F_c=2066.0, v_reg=5e-4))
    s.add("gnd", Fixed())
    s.connect("friction.flange_a", "gnd.flange")
    s.connect("friction.flange_b", "table.flange_b")
    return s


def bench_evaluation(t_old: float = 0.02):
    from _old_evaluate import FrfEvaluator, TimeSimulator

    from bscomp.simulation.dispatch import simulate

    s = _friction_bed()
    dt = 2e-4
    t = np.arange(0, 0.6, dt)
    u = 2.125 * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)
    t0 = time.perf_counter()
    cm = CompiledModel(s, ["amp.u"], OUTS)
    t_build = time.perf_counter() - t0
    cm.simulate({}, t, {"amp.u": u})                                   # compiles the step once
    t0 = time.perf_counter()
    n = 5
    for k in range(n):
        cm.simulate({"friction.F_c_pos": 2000.0 + k, "friction.F_c_neg": 2000.0 + k}, t, {"amp.u": u})
    t_new = (time.perf_counter() - t0) / n
    dae = flatten(s)
    ts = TimeSimulator(dae, dt, OUTS)
    nt = int(round(t_old / dt)) + 1
    t0 = time.perf_counter()
    U = np.vstack([u[:nt] if n == "amp.u" else np.zeros(nt) for n in dae.u_names])
    ts.run(U, dae.p0)
    t_old_run = time.perf_counter() - t0
    t_old_full = t_old_run * (t.size / nt)
    t0 = time.perf_counter()
    simulate(s, t, inputs={"amp.u": u}, outputs=OUTS, rtol=1e-6)
    t_idas = time.perf_counter() - t0
    print("\n2. one time-series evaluation, FE test bed + Table 5.2 friction, 0.6 s at 5 kHz")
    print(f"  CompiledModel (shared engine)      {t_new:8.3f} s per evaluation (set-up {t_build:.2f} s once)")
    print(f"  old private Radau (_evaluate)      {t_old_run:8.3f} s for the first {t_old:g} s -> ~{t_old_full:.0f} s "
          f"for 0.6 s  (ratio old/new ~{t_old_full / t_new:.0f}x)")
    print(f"  bscomp.simulate (IDAS rtol 1e-6)   {t_idas:8.3f} s  (ratio IDAS/new {t_idas / t_new:.0f}x)")
    f = np.logspace(np.log10(2), 3, 300)
    pairs = [("amp.u", "rotor.w"), ("amp.u", "table.a")]
    lin = s.linear_equivalent()
    cm_l = CompiledModel(lin, ["amp.u"], ["rotor.w", "table.a"])
    cm_l.frf({}, f, pairs)
    t0 = time.perf_counter()
    for k in range(20):
        cm_l.frf({"table.m": 250.0 + k}, f, pairs)
    t_fnew = (time.perf_counter() - t0) / 20
    dl = flatten(lin)
    fe = FrfEvaluator(dl, pairs)
    t0 = time.perf_counter()
    fe(f, dl.p0)
    t_fold = time.perf_counter() - t0
    print("\n3. one FRF evaluation (2 pairs x 300 frequencies), FE test bed")
    print(f"  CompiledModel (modal)              {t_fnew * 1e3:8.1f} ms")
    print(f"  old FrfEvaluator (dense solves)    {t_fold * 1e3:8.1f} ms  (ratio old/new {t_fold / t_fnew:.0f}x)")


def _thesis_bed():
    """The thesis's Ch 5 drive: Table 5.2 guideway friction and the 1.7e10 N/m screw-nut backlash."""
    from bscomp.systems.testbed import testbed
    from bscomp.systems.thesis_effects import with_friction_backlash

    return with_friction_backlash(testbed("axial_torsional", "C"))


def bench_inner_calls(repeat: int = 5):
    """The two inner loops a fit repeats, each against what it replaced (same results): the time series with
    several samples per mapaccum call against one (``compiled_time.BLOCK_INSTRUCTIONS = 0``), both in CasADi's
    virtual machine, and the same sample compiled to C (``bscomp.simulation.compiled_hot``, here compiled at the first
    run into a fresh cache, its compilation timed apart) -- with friction, and with friction and the 1.7e10 N/m
    screw-nut clearance the time series cuts out (16 sub-steps per sample); and the harmonic balance at an amplitude
    (three odd orders) with the Newton's exact Jacobian against forward differences."""
    import tempfile
    from unittest import mock

    import bscomp.simulation.compiled_hot as ch
    import bscomp.simulation.compiled_time as ct
    from bscomp.simulation.harmonic_balance import HarmonicBalance

    s = _friction_bed()
    t = np.arange(0, 0.3, 2e-4)
    u = 2.125 * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)

    def series(system, block, native=False):
        old = ct.BLOCK_INSTRUCTIONS, ch.HOT_WORK, ch.BACKGROUND
        ct.BLOCK_INSTRUCTIONS, ch.HOT_WORK, ch.BACKGROUND = block, 0.0, False    # compiled in the first run
        try:
            with tempfile.TemporaryDirectory() as fresh, mock.patch.dict(
                    os.environ, {"BSCOMP_NATIVE_STEPS": "1" if native else "0", "BSCOMP_CACHE_DIR": fresh}):
                cm = CompiledModel(system, ["amp.u"], OUTS)
                t0 = time.perf_counter()
                y = cm.simulate({}, t, {"amp.u": u})
                first = time.perf_counter() - t0
                t0 = time.perf_counter()
                for k in range(repeat):
                    cm.simulate({"friction.F_c_pos": 2000.0 + k, "friction.F_c_neg": 2000.0 + k}, t, {"amp.u": u})
                return y, (time.perf_counter() - t0) / repeat, first, cm.stats["n_sub_used"]
        finally:
            ct.BLOCK_INSTRUCTIONS, ch.HOT_WORK, ch.BACKGROUND = old

    def differ(a, b):
        return max(float(np.max(np.abs(a[o] - b[o])) / np.max(np.abs(b[o]))) for o in OUTS)

    print("\n4. the inner loops (same results, old way first)")
    y1, w1, _, _ = series(s, 0)
    yb, wb, _, _ = series(s, ct.BLOCK_INSTRUCTIONS)
    print(f"  time series, 0.3 s at 5 kHz, friction: one sample a call {w1 * 1e3:7.1f} ms, blocks "
          f"{wb * 1e3:7.1f} ms  (ratio {w1 / wb:.2f}x; outputs differ by {differ(yb, y1):.1e})")
    for label, system in (("friction", s), ("friction + clearance", _thesis_bed())):
        yb, wb, _, n_sub = series(system, ct.BLOCK_INSTRUCTIONS)
        yn, wn, first, _ = series(system, ct.BLOCK_INSTRUCTIONS, native=True)
        print(f"  time series, 0.3 s at 5 kHz, {label} ({n_sub} sub-steps): virtual machine {wb * 1e3:7.1f} ms, "
              f"compiled {wn * 1e3:7.1f} ms (ratio {wb / wn:.2f}x; first run with the compilation {first:.2f} s; "
              f"outputs differ by {differ(yn, yb):.1e})")
    cm = CompiledModel(s, ["amp.u"], ["rotor.w", "table.a"])
    f = np.logspace(np.log10(5), np.log10(200), 60)

    def describing(exact, amp):
        HarmonicBalance.exact = exact
        try:
            t0 = time.perf_counter()
            H = cm.frf({}, f, [("amp.u", "table.a")], amplitude={"amp.u": amp}, harmonics=3)[("amp.u", "table.a")]
            return H, time.perf_counter() - t0
        finally:
            HarmonicBalance.exact = True

    for amp in (0.5, 2.0):
        Hd, wd = describing(False, amp)
        He, we = describing(True, amp)
        dH = float(np.max(np.abs(He - Hd)) / np.max(np.abs(Hd)))
        print(f"  FRF at {amp:g} V, 3 odd orders, 60 frequencies: differenced Jacobian {wd:6.2f} s, exact {we:6.2f} s  "
              f"(ratio {wd / we:.2f}x; FRFs differ by {dH:.1e})")


def main(quick: bool = False):
    bench_inner_calls()
    bench_evaluation()
    bench_diagnose(["control", "joint"] if quick else ["control", "joint", "friction", "backlash", "delay",
                                                       "joint_friction"])


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two diagnose cases only")
    main(**vars(ap.parse_args()))
