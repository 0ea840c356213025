"""What fits by the describing function return on FRFs measured at a sine amplitude: measured, not assumed.

``calibrate`` and ``diagnose`` compare an FRF file that states its amplitude with the model at that amplitude:
the describing function of its friction and backlash elements (``CompiledModel.frf(amplitude=)``, =
``bscomp.describing_frf`` to 1e-5). This script measures what fits by it return on data they did not make:
stepped-sine FRFs (time integration, every harmonic) of two FE truths of ``bscomp.systems.truths`` (another mesh
of section C, table mass and coupling mis-set), 14 frequencies 10-200 Hz, ``rotor.w`` and ``table.a`` per ``amp.u``:

* ``coulomb``: the truth ``control`` plus the model's own friction law (tanh Coulomb, ``v_reg`` 1e-4 m/s),
  F_c = 1500 N, at 0.5 V and 2 V; fitted: F_c, ``table.m``, ``coupling.k_T`` (model: the test bed with the
  same law at Table 5.2's 2066 N).
* ``atan``: the truth ``friction`` (arc-tangent friction, F_c 1151 N, v_s 2.2e-5 m/s, its own viscous part) at
  0.2 V and 2 V; fitted: F_c, an added viscous ``d``, ``v_reg`` and the same two parameters.

Least squares on dB magnitude and phase / 10 deg (``scipy.optimize.least_squares``). With ``--diagnose`` it
also runs ``diagnose`` on the ``atan`` files (FRFs alone, and the 2 V file beside the truth's bundled
square-wave record), as the library does (the describing function at the files' amplitudes) and with the
evaluator forced to the small-signal FRF, as before.

    python benchmarks/fit_at_amplitude.py [--diagnose] [--harmonics H]     (~1 min; --diagnose ~6 min more)

``--harmonics H`` fits with the odd orders up to ``2H - 1`` balanced (``CompiledModel.frf(harmonics=H)``).

Stepped-sine files are cached in ``benchmarks/.cache/fit_at_amplitude``. Results: ``docs/measurements.md``,
"Fitting FRFs measured at an amplitude".
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

import bscomp  # noqa: E402
from bscomp.components import CoulombFriction, Fixed  # noqa: E402
from bscomp.errors import ModelLimitationWarning  # noqa: E402
from bscomp.simulation.compiled import CompiledModel  # noqa: E402
from bscomp.systems import testbed_axial_torsional  # noqa: E402
from bscomp.systems.truths import truth_system  # noqa: E402
from bscomp.validate import load  # noqa: E402

CACHE = Path(__file__).resolve().parent / ".cache" / "fit_at_amplitude"
FREQS = np.geomspace(10.0, 200.0, 14)
OUTS = ["rotor.w", "table.a"]
PAIRS = [("amp.u", o) for o in OUTS]
F_C_COULOMB = 1500.0


def _with_friction(s, **kw):
    s.add("guide_ground_fit", Fixed())
    s.add("fr", CoulombFriction(**kw))
    s.connect("guide_ground_fit.flange", "fr.flange_a")
    s.connect("fr.flange_b", "table.flange_b")
    return s


def truth(case):
    """(System, info) of a truth: ``coulomb`` (truth ``control`` + tanh friction) or ``atan`` (truth ``friction``)."""
    if case == "coulomb":
        s, info = truth_system("control", nut_joint="point")
        return _with_friction(s, F_c_pos=F_C_COULOMB, F_c_neg=F_C_COULOMB), info
    return truth_system("friction", nut_joint="point")


def measured(case, volts):
    """The stepped-sine FRF files of a truth (cached), loaded with the nut position as their condition."""
    s, info = truth(case)
    CACHE.mkdir(parents=True, exist_ok=True)
    out = []
    for v in volts:
        path = CACHE / f"{case}_{v:g}V.csv"
        if not path.exists():
            t0 = time.perf_counter()
            ss = bscomp.stepped_sine(s, "amp.u", OUTS, FREQS, v, jit=True)
            ss.to_csv(path, units={"amp.u": "V"})
            print(f"  measured {path.name} in {time.perf_counter() - t0:.1f} s; table.a distortion up to "
                  f"{100 * ss.distortion[:, 1].max():.0f} %")
        d = load(path)
        d.conditions["nut_position"] = info["nut_position"]
        out.append(d)
    return out, info


HARMONICS = int(sys.argv[sys.argv.index("--harmonics") + 1]) if "--harmonics" in sys.argv else 1


def fit(case, volts, names, start):
    """Least squares of ``names`` (log space) on the files at ``volts``: (values, rms of the residual)."""
    data, info = measured(case, volts)
    s = _with_friction(testbed_axial_torsional(nut_position=info["nut_position"]),
                       **{k.split(".")[1]: v for k, v in start.items() if k.startswith("fr.")})
    cm = CompiledModel(s, ["amp.u"], OUTS, free=["table.m", "coupling.k_T"])
    x0 = np.log([start[n] if n in start else float(s.get(n)) for n in names])

    def res(x):
        v = dict(zip(names, np.exp(x), strict=True))
        for a, b in (("fr.F_c_pos", "fr.F_c_neg"), ("fr.d_pos", "fr.d_neg")):
            if a in v:
                v[b] = v[a]
        r = []
        for d in data:
            H = cm.frf(v, d.freqs, PAIRS, amplitude=d.excitation, harmonics=HARMONICS)
            for pq in PAIRS:
                q = H[pq] / d.H[pq]
                r += [20 * np.log10(np.abs(q)), np.angle(q, deg=True) / 10]
        return np.concatenate(r)

    sol = least_squares(res, x0, diff_step=1e-3)
    return dict(zip(names, np.exp(sol.x), strict=True)), float(np.sqrt(np.mean(res(x0) ** 2))), \
        float(np.sqrt(np.mean(sol.fun ** 2))), info


def calibrations():
    print(f"calibration by the describing function ({HARMONICS} odd harmonic(s)) on stepped-sine FRFs (relative "
          "error against the truth):")
    rows = []
    for volts in ((2.0,), (0.5,), (0.5, 2.0)):
        t0 = time.perf_counter()
        v, r0, r1, info = fit("coulomb", volts, ["fr.F_c_pos", "table.m", "coupling.k_T"],
                              {"fr.F_c_pos": 2066.0, "fr.F_c_neg": 2066.0})
        m_t, k_t = info["misset"]["table.m"]["truth"], info["misset"]["coupling.k_T"]["truth"]
        rows.append(("coulomb", volts, v["fr.F_c_pos"] / F_C_COULOMB - 1, v["table.m"] / m_t - 1,
                     v["coupling.k_T"] / k_t - 1))
        print(f"  coulomb at {volts} V: F_c {v['fr.F_c_pos']:.0f} N ({rows[-1][2]:+.1%}), table.m "
              f"{v['table.m']:.1f} kg ({rows[-1][3]:+.1%}), k_T {v['coupling.k_T']:.0f} ({rows[-1][4]:+.1%}); "
              f"residual rms {r0:.2f} -> {r1:.2f} ({time.perf_counter() - t0:.1f} s)", flush=True)
    for volts in ((2.0,), (0.2, 2.0)):
        t0 = time.perf_counter()
        v, r0, r1, info = fit("atan", volts, ["fr.F_c_pos", "fr.d_pos", "fr.v_reg", "table.m", "coupling.k_T"],
                              {"fr.F_c_pos": 1000.0, "fr.F_c_neg": 1000.0, "fr.d_pos": 1000.0, "fr.d_neg": 1000.0,
                               "fr.v_reg": 1e-4})
        h = info["hidden"]["friction"]
        m_t, k_t = info["misset"]["table.m"]["truth"], info["misset"]["coupling.k_T"]["truth"]
        print(f"  atan at {volts} V: F_c {v['fr.F_c_pos']:.0f} N ({v['fr.F_c_pos'] / h['F_c'] - 1:+.1%}), d "
              f"{v['fr.d_pos']:.0f} N s/m (truth {h['d']:.0f}), v_reg {v['fr.v_reg']:.2g} m/s (truth v_s "
              f"{h['v_s']:.2g}), table.m {v['table.m'] / m_t - 1:+.1%}, k_T {v['coupling.k_T'] / k_t - 1:+.1%}; "
              f"residual rms {r0:.2f} -> {r1:.2f} ({time.perf_counter() - t0:.1f} s)", flush=True)
    return rows


def diagnoses():
    """diagnose on the atan truth's files as the library does (the describing function at the files' amplitudes)
    and with its evaluator forced to the small-signal FRF (as before 2026-12-04): FRFs alone, and the 2 V file
    beside the truth's bundled square-wave record."""
    from importlib import resources

    from bscomp.validate import evaluation
    from bscomp.validate.diagnostics import diagnose
    from bscomp.validate.measurements import load_all

    data, info = measured("atan", (0.2, 2.0))
    root = resources.files("bscomp.systems") / "data" / "truths" / "axial_torsional" / "friction"
    (record,) = load_all([str(root / "time.csv")])
    print(f"diagnose on the 'friction' truth's stepped-sine FRFs (hidden: {info['hidden']}):")
    original = evaluation.Evaluator.outputs

    def small_signal(self, overrides, hooks=None, only_frf=False, fitted_only=False):
        saved = [getattr(d, "excitation", None) for d in self.datasets]
        try:
            for d in self.datasets:
                if hasattr(d, "excitation"):
                    d.excitation = {}
            return original(self, overrides, hooks, only_frf, fitted_only)
        finally:
            for d, e in zip(self.datasets, saved, strict=True):
                if e is not None:
                    d.excitation = e

    for what, ds in (("0.2 V and 2 V", data), ("2 V + square-wave record", [data[1], record])):
        for label, patch in ((f"at the amplitude, {HARMONICS} odd harmonic(s) (the library)", None),
                             ("small-signal (before)", small_signal)):
            evaluation.Evaluator.outputs = patch or original
            t0 = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ModelLimitationWarning)
                    dg = diagnose("testbed_axial_torsional", ds, max_effects=2, harmonics=HARMONICS)
            finally:
                evaluation.Evaluator.outputs = original
            acc = [(a.name, {k: round(v, 4) for k, v in a.values.items()}) for a in dg.accepted]
            print(f"  {what}, {label}: accepted {acc}, unconfirmed {[u.name for u in dg.unconfirmed]}; staircase "
                  f"{[(n, round(e, 1)) for n, e in dg.staircase]}; {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    calibrations()
    if "--diagnose" in sys.argv:
        diagnoses()
