"""1 s of the thesis's open-loop square-wave scenario (Sec 5.3.1: 5 Hz, 4.25 V peak-to-peak) on the
axial + torsional test-bed model (Ch 5, 98 coordinates, 196 states): our simulators vs scipy's
solve_ivp (BDF) on the same linear equations, in one run (issue: nonlinear simulation, item 6).

Runs, all recording table acceleration, motor speed and table position on a 0.1 ms grid:

* ``lti full``       simulate(method="lti"): exact zero-order-hold stepping of the linearized model
                     (the reference; linear models only)
* ``idas full``      simulate(), IDAS on the flattened (nonlinear) DAE, BDF order <= 2
* ``fixed full``     simulate(method="fixed"): fixed-step L-stable SDIRK3 on the nonlinear DAE, h = 0.1 ms
* ``* reduced``      the same on the CMS-reduced model (Sec 5.2.3, modes <= 2 kHz + boundary DOF) in a
                     SecondOrderBlock; ``fixed+jit`` compiles the step with the C compiler: ``cold`` includes
                     compiling (fresh cache), ``warm`` is a second call
* ``solve_ivp BDF``  baseline: x' = A x + B u of the full linearized model, integrated piecewise between
                     the square-wave switches (rtol 1e-6, atol 1e-9, sparse Jacobian)

Errors: max |y - y_ref| / max |y_ref| against ``lti full`` for table acceleration (a) and position (s);
for reduced runs also the acceleration error against the reduced model's own exact solution (``lti
reduced``), which separates the integrator's error from the reduction's. Wall times include input
evaluation, consistent initialisation and output evaluation (each simulate() call end to end, after one
untimed call per model builds the shared CasADi functions); runs under 2 s are the best of 3.
``--nonlinear`` runs instead the Ch 5 scenario WITH Table 5.2 friction and backlash
(examples/nonlinear_scenarios.py ``drive(friction=True, backlash=True)``, 198 states): ``split``
(experimental partitioned exponential integrator, re-linearized per regime of the laws; ``cold`` = the first
run from this start point, building its regimes and Functions, ``warm`` = a repeated run that reuses them;
substeps 1 and 2) and ``fixed`` against IDAS at default tolerances, printing wall time, real-time factor and
max |y - y_idas| / max |y_idas| for table position, table velocity and motor speed; ``--reference`` adds IDAS
at rtol 1e-8 as the reference (minutes for 1 s).
``--moving`` runs issue 16's table instead (``moving()``: friction + backlash, nut frozen or moving, 0.6 s, the new
``method="modal"`` beside IDAS and scikit-sundae's IDA on the same equations, errors against IDAS at rtol 1e-9;
then 2x/4x the step, the screw mesh 24-188 elements, the 6-DOF test bed, the modally reduced model and a
friction-force sweep through ``params=``).
Run: python benchmarks/bench_simulation.py [T_end] [--no-scipy] [--nonlinear [--reference]]
     python benchmarks/bench_simulation.py --moving [table steps mesh six reduced params] [--reference]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

import bscomp  # noqa: E402
from bscomp import System  # noqa: E402
from bscomp.components import SecondOrderBlock  # noqa: E402
from bscomp.linear.reduction import reduce_second_order  # noqa: E402
from bscomp.simulation.dispatch import simulate  # noqa: E402
from bscomp.systems.testbed import testbed_axial_torsional  # noqa: E402

K_A, K_T = 6.4898, 0.4769          # Eq 4.1
U_PP, F_SQ = 4.25, 5.0             # Sec 5.3.1: 4.25 V peak-to-peak, 5 Hz
OUTS = ["table.a", "rotor.w", "table.s"]


def voltage(t):
    """Amplifier command amp.u [V]: the 4.25 V peak-to-peak, 5 Hz square wave."""
    return 0.5 * U_PP * (1.0 if (t * F_SQ) % 1.0 < 0.5 else -1.0)


def torque(t):
    """The same command as motor torque [N m] (Eq 4.1: tau = K_a K_t u)."""
    return K_A * K_T * voltage(t)


def main(T_end: float = 1.0, scipy_baseline: bool = True):
    t = np.arange(0.0, T_end + 1e-12, 1e-4)
    rows = {}

    def run(name, fn, repeat=1):
        walls = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            y = fn()
            walls.append(time.perf_counter() - t0)
        wall = min(walls)
        rows[name] = (wall, y)
        print(f"  {name:<26} {wall:8.3f} s wall", flush=True)

    dae = bscomp.flatten(testbed_axial_torsional(drive_input="torque"))     # the scipy baseline takes the torque
    so = bscomp.second_order(dae, inputs=["motor.tau"], outputs=OUTS)
    red, info = reduce_second_order(so, boundary=["rotor.phi", "sn.nut.w"], f_cut=2000.0)
    rs = System("reduced")
    rs.add("plant", SecondOrderBlock(red))
    rdae = bscomp.flatten(rs)
    routs = ["plant.table_a", "plant.rotor_w", "plant.table_s"]
    full = dict(dae=dae, outs=OUTS, u="motor.tau")
    redu = dict(dae=rdae, outs=routs, u="plant.motor_tau")
    # one untimed call per model builds the CasADi functions every method shares (Jacobians, outputs)
    _sim(**full, t=t[:3], method="lti")
    _sim(**redu, t=t[:3], method="lti")
    run("lti full", lambda: _sim(**full, t=t, method="lti"), repeat=3)
    run("idas full", lambda: _sim(**full, t=t, method="idas"))
    run("fixed full", lambda: _sim(**full, t=t, method="fixed"))
    run("lti reduced", lambda: _sim(**redu, t=t, method="lti"), repeat=3)
    run("idas reduced", lambda: _sim(**redu, t=t, method="idas"), repeat=3)
    run("fixed reduced", lambda: _sim(**redu, t=t, method="fixed"), repeat=3)
    with tempfile.TemporaryDirectory() as cache:
        os.environ["BSCOMP_CACHE_DIR"] = cache
        run("fixed+jit reduced (cold)", lambda: _sim(**redu, t=t, method="fixed", jit=True))
        run("fixed+jit reduced (warm)", lambda: _sim(**redu, t=t, method="fixed", jit=True), repeat=3)
        del os.environ["BSCOMP_CACHE_DIR"]
    if scipy_baseline:
        run("solve_ivp BDF full", lambda: _scipy(so, t))
    ref = rows["lti full"][1]
    ref_red = rows["lti reduced"][1]
    print(f"\nmodel: {dae.nx} states full, {red.M.shape[0]} coordinates reduced "
          f"(modes up to {info.mode_frequencies.max():.0f} Hz); simulated {T_end} s; 0.1 ms grid")
    t_bdf = rows["solve_ivp BDF full"][0] if scipy_baseline else np.nan
    print(f"{'run':<26} {'wall [s]':>9} {'x real time':>12} {'vs BDF':>8} {'a error':>9} {'s error':>9} "
          f"{'a err vs own ZOH':>17}")
    for name, (wall, y) in rows.items():
        ea, es = (np.max(np.abs(y[i] - ref[i])) / np.max(np.abs(ref[i])) for i in (0, 2))
        own = (f"{np.max(np.abs(y[0] - ref_red[0])) / np.max(np.abs(ref_red[0])):17.2e}" if "reduced" in name
               else f"{'':>17}")
        print(f"{name:<26} {wall:>9.3f} {T_end / wall:>12.2f} {t_bdf / wall:>8.1f} {ea:>9.2e} {es:>9.2e} {own}")


def nonlinear(T_end: float = 1.0, reference: bool = False):
    """split / fixed / IDAS on the test bed with Table 5.2 friction and backlash (see the module docstring)."""
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "examples"))
    from nonlinear_scenarios import drive

    dae = bscomp.flatten(drive("C", friction=True, backlash=True))
    t = np.arange(0.0, T_end + 1e-12, 1e-4)
    outs = ["table.s", "table.v", "rotor.w"]
    _sim(dae, outs, "amp.u", t[:3], "idas")  # builds the Jacobians and outputs every method shares

    def cold_split(**kw):
        dae._cache.pop("split_models", None)  # the split set-up (regimes, expm, eig, Functions) is cached per start
        return _sim(dae, outs, "amp.u", t, "split", **kw)

    runs = {}
    cases = [("idas rtol 1e-8 (ref)", None, dict(method="idas", rtol=1e-8, atol=1e-11), 1)] if reference else []
    cases += [("idas default", None, dict(method="idas"), 1),
              ("split (cold)", lambda: cold_split(), None, 3),
              ("split (warm)", None, dict(method="split"), 3),
              ("split substeps=2 (cold)", lambda: cold_split(substeps=2), None, 1),
              ("fixed", None, dict(method="fixed"), 1)]
    for name, fn, kw, repeat in cases:
        walls = []
        try:
            for _ in range(repeat):
                t0 = time.perf_counter()
                y = fn() if fn is not None else _sim(dae, outs, "amp.u", t, **kw)
                walls.append(time.perf_counter() - t0)
        except bscomp.simulation.SimulationError as exc:
            print(f"  {name}: failed: {str(exc)[:160]}")
            continue
        runs[name] = (min(walls), y)
        print(f"  {name:<24} {runs[name][0]:8.3f} s wall" + (f" (best of {repeat})" if repeat > 1 else ""), flush=True)
    refs = ["idas rtol 1e-8 (ref)", "idas default"] if reference else ["idas default"]
    for ref_name in refs:
        ref = runs[ref_name][1]
        print(f"\nfriction + backlash, {dae.nx} states, {T_end} s, 0.1 ms grid; errors max |y - y_ref| / max |y_ref| "
              f"vs {ref_name}")
        print(f"{'run':<24} {'wall [s]':>9} {'x real time':>12} " + " ".join(f"{o + ' err':>12}" for o in outs))
        for name, (wall, y) in runs.items():
            errs = " ".join(f"{np.max(np.abs(y[i] - ref[i])) / np.max(np.abs(ref[i])):>12.2e}"
                            for i in range(len(outs)))
            print(f"{name:<24} {wall:>9.3f} {T_end / wall:>12.2f} {errs}")


def _sim(dae, outs, u, t, method, **kw):
    command = voltage if u == "amp.u" else torque
    r = simulate(dae, t, inputs={u: command}, outputs=outs, method=method, max_num_steps=10**6, progress=False,
                 **kw)
    return [r[o] for o in outs]


def _scipy(so, t):
    """Baseline: the same linear equations x' = A x + B u through scipy's BDF, restarted at switches."""
    n = so.n
    M = so.M.toarray()
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ so.K.toarray(), -Minv @ so.C.toarray()]])
    B = np.vstack([np.zeros((n, 1)), Minv @ so.B.toarray()])
    As = sp.csr_matrix(A)
    Cq, Cv, Ca = so.Cq.toarray(), so.Cv.toarray(), so.Ca.toarray()
    switches = np.arange(0.0, t[-1] + 1e-12, 0.5 / F_SQ)
    switches = np.append(switches, t[-1]) if switches[-1] < t[-1] else switches
    x = np.zeros(2 * n)
    Y = np.zeros((Cq.shape[0], len(t)))
    for k in range(len(switches) - 1):
        t0, t1 = switches[k], switches[k + 1]
        u = torque(0.5 * (t0 + t1))
        sel = (t >= t0 - 1e-12) & (t <= t1 + 1e-12)
        sol = solve_ivp(lambda _, y, u=u: As @ y + B[:, 0] * u, (t0, t1), x, method="BDF",
                        t_eval=np.clip(t[sel], t0, t1), rtol=1e-6, atol=1e-9, jac=As)
        X = sol.y
        xd = A @ X + B * u
        Y[:, sel] = Cq @ X[:n] + Cv @ X[n:] + Ca @ xd[n:]
        x = X[:, -1]
    return list(Y)


def moving(reference_again=False, parts=("table", "steps", "mesh", "six", "reduced", "params")):
    """Issue 16: friction + backlash with the nut frozen at C or moving, 0.6 s (benchmarks/moving_cases.py).

    ``modal`` runs are ``simulate(method="modal", jit=True)``: *cold* = a fresh Dae-level set-up (modal parts,
    laws, kernels loaded from the on-disk C cache), *warm* = a repeated run; the one-time compilation of a
    model shape is reported separately (a fresh cache directory). Errors: NRMSE against IDAS at rtol 1e-9,
    atol 1e-12 on the same equations (cached in benchmarks/.cache with the time it took)."""
    import moving_cases as mc

    t = mc.grid()
    T = t[-1]
    rows = []

    def row(case, name, res, wall, cpu, ref):
        errs = {o: mc.nrmse(res[o], ref[o]) for o in mc.OUTS}
        rows.append((case, name, wall, cpu, errs))
        print(f"  {case:<8} {name:<34} {wall:8.3f} s wall {cpu:8.3f} s cpu  RTF {T / wall:7.2f}  "
              + " ".join(f"{o} {e:.1e}" for o, e in errs.items()), flush=True)

    def modal_runs(case, dae, ref, label="modal", **kw):
        def run():
            r = simulate(dae, t, inputs={"amp.u": mc.square}, outputs=mc.OUTS, method="modal", jit=True, **kw)
            return {o: r[o] for o in mc.OUTS}, r.stats

        with tempfile.TemporaryDirectory() as fresh:          # the one-time compilation of this shape
            os.environ["BSCOMP_CACHE_DIR"] = fresh
            mc.forget(dae)
            (_, _), w_first, _ = mc.timed(run)
            del os.environ["BSCOMP_CACHE_DIR"]
        mc.forget(dae)
        run()                                                  # fills the default on-disk cache
        cold = []
        for _ in range(3):
            mc.forget(dae)
            cold.append(mc.timed(run))
        (y, stats), w, c = min(cold, key=lambda x: x[1])
        row(case, f"{label} cold (compiled once: {w_first:.1f} s)", y, w, c, ref)
        (y, stats), w, c = mc.timed(run, repeat=3)
        row(case, f"{label} warm", y, w, c, ref)
        print(f"           modal parts {stats['modal_parts']} ({stats['modal_part_s']:.3f} s), chunks "
              f"{stats['chunks']}, batches {stats['batches']}, sub-steps {stats['substeps']}, switches "
              f"{stats['switches']}")
        return y

    if "table" in parts or "steps" in parts:
        for case, joint in (("frozen", "point"), ("moving", "moving")):
            dae = mc.drive(joint)
            simulate(dae, t[:3], inputs={"amp.u": mc.square}, outputs=mc.OUTS)   # shared Jacobians, outputs
            ref, w_ref = mc.reference(dae, case, t, reference_again)
            print(f"  {case}: {dae.nx} states; reference IDAS rtol 1e-9 took {w_ref:.0f} s", flush=True)
            if "table" in parts:
                modal_runs(case, dae, ref)
                (r, w, c) = mc.timed(lambda dae=dae: simulate(dae, t, inputs={"amp.u": mc.square}, outputs=mc.OUTS,
                                                               max_num_steps=10**7))
                row(case, "idas rtol 1e-6", r, w, c, ref)
                if case == "frozen":                         # split: only frozen (moving: 0.02 s took 259 s)
                    def split(dae=dae):
                        dae._cache.pop("split_models", None)
                        r = simulate(dae, t, inputs={"amp.u": mc.square}, outputs=mc.OUTS, method="split")
                        return {o: r[o] for o in mc.OUTS}

                    y, w, c = min((mc.timed(split) for _ in range(2)), key=lambda x: x[1])
                    row(case, "split cold", y, w, c, ref)
                sd = mc.sundae(dae, t)
                if sd is None:
                    print("           scikit-sundae not installed: its IDA baseline skipped")
                else:
                    row(case, "scikit-sundae IDA rtol 1e-6", sd[0], sd[1], sd[1], ref)
            if "steps" in parts:
                for mult in (2, 4):
                    tk = t[::mult]
                    r = simulate(dae, tk, inputs={"amp.u": mc.square}, outputs=mc.OUTS, method="modal", jit=True)
                    errs = {o: mc.nrmse(r[o], ref[o][::mult]) for o in mc.OUTS}
                    print(f"  {case:<8} modal at {mult}x the step ({mult * mc.DT * 1e3:.1f} ms): "
                          + " ".join(f"{o} {e:.1e}" for o, e in errs.items()), flush=True)
    if "mesh" in parts:
        walls = []
        for n in (24, 47, 94, 188):
            dae = mc.drive("moving", n_elements=n)
            def run(dae=dae):
                return simulate(dae, t, inputs={"amp.u": mc.square}, outputs=mc.OUTS, method="modal", jit=True)

            run()
            mc.forget(dae)
            _, w_cold, _ = mc.timed(run)
            _, w_warm, _ = mc.timed(run, repeat=2)
            walls.append((n, dae.nx, w_cold / T, w_warm / T))
            print(f"  mesh {n:4d} elements ({dae.nx} states): {w_cold / T:.3f} s cold, {w_warm / T:.3f} s warm per "
                  "simulated second", flush=True)
        n, _, wc, ww = (np.array(c, float) for c in zip(*walls, strict=True))
        print(f"  growth exponent (wall ~ elements^p, least squares on log-log): cold p = "
              f"{np.polyfit(np.log(n), np.log(wc), 1)[0]:.2f}, warm p = {np.polyfit(np.log(n), np.log(ww), 1)[0]:.2f}")
    if "six" in parts:
        dae = mc.six_dof("moving")
        ref6, w6 = mc.reference(dae, "six", t)                    # IDAS rtol 1e-9 on 582 states: ~18 min, cached
        print(f"  6-DOF: {dae.nx} states; reference IDAS rtol 1e-9 took {w6:.0f} s")
        modal_runs("6-DOF", dae, ref6, label="modal")
    if "reduced" in parts:
        dae = mc.drive("moving")
        ref, _ = mc.reference(dae, "moving", t)
        modal_runs("f_keep", dae, ref, label="modal, modes <= 2 kHz kept", modal_options={"f_keep": 2000.0})
        for P in (3, 10):                      # the thesis's CMS-reduced model (Sec 5.2.3 / 5.3.2): P = 3
            red = mc.reduced(P)
            simulate(red, t[:3], inputs={"amp.u": mc.square}, outputs=mc.OUTS)
            print(f"  CMS P={P}: {red.nx} states, {red.nz} algebraic; errors below against the FULL model's reference "
                  "(reduction + integration)", flush=True)
            y = modal_runs(f"CMS P={P}", red, ref)
            if P == 3:                         # IDAS rtol 1e-9 on P = 10 (modes to 8.8 kHz) did not end in 20 min
                ref_r, w_r = mc.reference(red, f"reduced{P}", t)
                print(f"           modal against IDAS rtol 1e-9 on the same reduced equations ({w_r:.0f} s): "
                      + " ".join(f"{o} {mc.nrmse(y[o], ref_r[o]):.1e}" for o in mc.OUTS), flush=True)
                (r, w, c) = mc.timed(lambda red=red: simulate(red, t, inputs={"amp.u": mc.square}, outputs=mc.OUTS,
                                                               max_num_steps=10**7))
                row(f"CMS P={P}", "idas rtol 1e-6 (vs the full reference)", r, w, c, ref)
                sd = mc.sundae(red, t)
                if sd is not None:
                    row(f"CMS P={P}", "scikit-sundae IDA rtol 1e-6", sd[0], sd[1], sd[1], ref)
        u = np.array([mc.square(0.5 * (a + b)) for a, b in zip(t[:-1], t[1:], strict=True)])   # an input array
        for label, dae, fk in (("full, all modes", flatten_testbed_moving(), None),
                               ("full, modes <= 2 kHz", flatten_testbed_moving(), 2000.0),
                               ("CMS P=3", mc.reduced(3, effects=False), None)):
            def run(dae=dae, fk=fk):
                return simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a", "sn.z"], method="modal", jit=True,
                                modal_options={"f_keep": fk})

            run()
            cold = []
            for _ in range(3):
                mc.forget(dae)
                cold.append(mc.timed(run)[1])
            _, ww, _ = mc.timed(run, repeat=5)
            wc = min(cold)
            print(f"  moving nut only (no friction, backlash), {label}: {wc:.4f} s cold (RTF {T / wc:.1f}), "
                  f"{ww:.4f} s warm (RTF {T / ww:.1f})", flush=True)
    if "params" in parts:
        params_sweep(t)
    return rows


def params_sweep(t):
    """A sweep of the Table 5.2 friction force (5 values, +-25 %) on the moving-nut test bed with friction and
    backlash, ``simulate(method="modal", jit=True)``: ``params=`` on the flattened Dae (its modal damping kept,
    the compiled laws reused) against the baseline of flattening the System with each override."""
    import moving_cases as mc

    from bscomp.kernel.flattening import flatten
    from bscomp.systems.thesis_effects import with_friction_backlash

    system = with_friction_backlash(testbed_axial_torsional(nut_joint="moving"))
    dae = flatten(system)
    simulate(dae, t, inputs={"amp.u": mc.square}, outputs=mc.OUTS, method="modal", jit=True)   # compiled once
    walls = {"params= on the Dae": [], "flatten(System.with_parameters) per value": []}
    for f in (0.75, 0.9, 1.1, 1.25, 1.0):
        over = {"friction.F_c_pos": 2066.0 * f, "friction.F_c_neg": 2066.0 * f}
        t0 = time.perf_counter()
        a = simulate(dae, t, inputs={"amp.u": mc.square}, outputs=["table.a"], method="modal", jit=True, params=over)
        walls["params= on the Dae"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        b = simulate(flatten(system.with_parameters(over)), t, inputs={"amp.u": mc.square}, outputs=["table.a"],
                     method="modal", jit=True)
        walls["flatten(System.with_parameters) per value"].append(time.perf_counter() - t0)
        assert np.allclose(a["table.a"], b["table.a"], rtol=0, atol=1e-9 * np.abs(b["table.a"]).max())
    for k, w in walls.items():
        print(f"  friction sweep, {k:<42} {np.mean(w):7.3f} s per value")
    r = np.mean(walls["flatten(System.with_parameters) per value"]) / np.mean(walls["params= on the Dae"])
    print(f"  ratio {r:.1f}x (same table.a to 1e-9)")


def flatten_testbed_moving():
    from bscomp.kernel.flattening import flatten

    return flatten(testbed_axial_torsional(nut_joint="moving"))


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if "--moving" in sys.argv:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        moving("--reference" in sys.argv, tuple(args) or ("table", "steps", "mesh", "six", "reduced", "params"))
    elif "--nonlinear" in sys.argv:
        nonlinear(float(args[0]) if args else 1.0, reference="--reference" in sys.argv)
    else:
        main(float(args[0]) if args else 1.0, scipy_baseline="--no-scipy" not in sys.argv)
