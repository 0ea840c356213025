"""FMU benchmark: the exported FE test bed run by FMPy (CVode) against ``bscomp.simulate``.

1. **Nominals.** 20 ms of the +-2.125 V, 50 Hz square wave (the test's case) through FMPy at ``rtol`` 1e-8,
   the FMU exported with CasADi's state nominals (1, ``nominal=1.0``) and with bscomp's (1e-3, the default):
   wall time (best of ``--repeat``), derivative calls (FMPy's call log, a separate run) and the relative
   errors against ``simulate(method="lti")`` (exact for the linear drive, zero-order-held input).
2. **Thesis scenario** (``--thesis``): 0.6 s of the +-2.125 V, 5 Hz square wave of Sec 5.3.1 through FMPy at
   ``rtol`` 1e-8 with bscomp's nominals, against ``simulate(method="lti")``: wall times and errors.

Relative error = max |y_fmu - y_ref| / max |y_ref| on the 0.1 ms grid, the edge instants left out (as in
``tests/bscomp/test_fmu.py``). BLAS is pinned to one thread unless OMP_NUM_THREADS is set. Needs FMPy and gcc.

Run: python benchmarks/bench_fmu.py [--thesis] [--repeat 3]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from bscomp.fmu import export_fmu  # noqa: E402
from bscomp.simulation import simulate  # noqa: E402
from bscomp.systems import get  # noqa: E402

DT, AMP = 1e-4, 2.125
OUT = ["table.a", "table.s", "rotor.w"]


def square(f):
    return lambda t: AMP if (t * f) % 1.0 < 0.5 else -AMP


def fmpy_input(f, T):
    """Piecewise-constant square wave for FMPy: duplicated time stamps at the edges (input events)."""
    wave, rows = square(f), []
    for k, e in enumerate(np.arange(0.0, T + 1e-12, 0.5 / f)):
        if k:
            rows.append((e, wave(e - 1e-9)))
        rows.append((e, wave(e + 1e-9)))
    return np.array(rows, dtype=[("time", float), ("amp.u", float)])


def rel_errors(res, ref, t, f):
    tf = res["time"]
    edges = np.arange(0.0, t[-1] + 1e-12, 0.5 / f)
    keep = np.min(np.abs(tf[:, None] - edges[None, :]), axis=1) > DT / 2
    return {o: float(np.max(np.abs(res[o] - np.interp(tf, t, ref[o]))[keep]) / np.max(np.abs(ref[o]))) for o in OUT}


def run_fmpy(path, f, T, rtol, count=False):
    """(result, wall [s], derivative calls or None)."""
    import fmpy

    calls = [0]

    def logger(msg):
        calls[0] += "GetContinuousStateDerivatives" in msg

    t0 = time.perf_counter()
    res = fmpy.simulate_fmu(str(path), stop_time=T, relative_tolerance=rtol, output_interval=DT,
                            input=fmpy_input(f, T), output=OUT, record_events=False,
                            fmi_call_logger=logger if count else None)
    return res, time.perf_counter() - t0, (calls[0] if count else None)


def reference(f, T):
    t = DT * np.arange(int(round(T / DT)) + 1)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")            # lti linearizes the amplifier's (inactive) current limit
        ref = simulate(get("testbed_axial_torsional"), t, inputs={"amp.u": square(f)}, outputs=OUT, method="lti")
    return t, ref, time.perf_counter() - t0


def fmt(err):
    return "  ".join(f"{o} {e:.1e}" for o, e in err.items())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--thesis", action="store_true", help="also run the 0.6 s, 5 Hz thesis scenario (minutes)")
    ap.add_argument("--repeat", type=int, default=3, help="best of REPEAT wall times (default 3)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        fmus = {}
        for label, nominal in (("nominal 1 (CasADi)", 1.0), ("nominal 1e-3 (bscomp)", None)):
            fmus[label] = export_fmu("testbed_axial_torsional", Path(tmp) / f"tb{len(fmus)}.fmu", inputs=["amp.u"],
                                     outputs=OUT, nominal=nominal)
        f, T = 50.0, 0.02
        t, ref, w_ref = reference(f, T)
        print(f"1. test bed, 50 Hz square wave, {T * 1e3:.0f} ms, FMPy rtol 1e-8 (lti reference: {w_ref:.2f} s)")
        for label, path in fmus.items():
            walls = [run_fmpy(path, f, T, 1e-8)[1] for _ in range(args.repeat)]
            res, _, calls = run_fmpy(path, f, T, 1e-8, count=True)
            print(f"   {label:22s} wall {min(walls):6.2f} s ({min(walls) / (T * 1e3):.3f} s per simulated ms), "
                  f"{calls} derivative calls; {fmt(rel_errors(res, ref, t, f))}")
        if args.thesis:
            f, T = 5.0, 0.6
            t, ref, w_ref = reference(f, T)
            res, wall, _ = run_fmpy(fmus["nominal 1e-3 (bscomp)"], f, T, 1e-8)
            print(f"2. thesis scenario, 5 Hz square wave, {T:.1f} s: FMPy rtol 1e-8 {wall:.1f} s, simulate(lti) "
                  f"{w_ref:.2f} s (ratio {wall / w_ref:.0f}); {fmt(rel_errors(res, ref, t, f))}")


if __name__ == "__main__":
    main()
