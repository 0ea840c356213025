"""Differential fuzz of ``simulate(method="modal")`` on drives it was not built for.

Random grounded chains of 2-4 masses (0.5-50 kg, links 1e4-1e8 N/m log-uniform, 2 % damping per link), one link
a clearance (``Backlash``: 1-100 um log-uniform, contact 1-30x the link's stiffness, undamped or 1e-3 c, sharp
or parabolic corners of 5 % / 20 % of the clearance), Coulomb (random ``v_reg`` 1e-5..1e-3 m/s, viscous terms)
or Stribeck friction to ground on a random mass, driven by a square wave or a sine of 5-60 Hz at 0.5-4x the
friction force on the last mass, 0.2 s on a 0.1 ms grid. Per case: the velocity of the last mass, its
acceleration and the friction force against IDAS at rtol 1e-10, atol 1e-13 (the reference), for ``modal`` at its
defaults and at ``tol`` 1e-4 and for IDAS at its defaults (rtol 1e-6); the worst NRMSE of the three outputs (RMS
error over the reference's peak-to-peak) per case, then the summary docs/nonlinear.md quotes.

    python benchmarks/fuzz_modal.py [FIRST LAST] [--floor F] [--others]    # seeds FIRST..LAST-1 (default 0 80)

``--floor F`` judges a step's force error against its own largest force, at least F x the run's largest
(:data:`bscomp.simulation.modal_kernels.FORCE_FLOOR`; the kept rule is 1: the run's largest alone; 0.1 was
measured and not kept, docs/nonlinear.md).
``--others`` adds ``modal`` with ``jit=True``, ``split`` and ``fixed`` (their errors, walls and failures).
``--compare`` adds IDAS at rtol 1e-7, atol 1e-10 (what ``compare`` simulated a nonlinear model with until
2026-12-07; it runs ``modal`` at ``tol`` 1e-4 now) and counts the chains where each modal run is less accurate.
"""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

from bscomp import System
from bscomp.components import Backlash, CoulombFriction, Damper, Fixed, Force, Mass, Spring, StribeckFriction
from bscomp.kernel.flattening import flatten
from bscomp.simulation import SimulationError, modal_driver, modal_kernels, simulate


def chain(rng):
    """A random chain (module docstring): ``(System, friction force F_c, index of the last mass)``."""
    n = int(rng.integers(2, 5))
    s = System("fuzz_chain")
    s.add("wall", Fixed())
    ms, ks = rng.uniform(0.5, 50, n), 10 ** rng.uniform(4, 8, n)
    clearance = int(rng.integers(1, n))
    prev = "wall.flange"
    for i in range(n):
        s.add(f"m{i}", Mass(m=ms[i]))
        if i == clearance:
            b = 10 ** rng.uniform(-6, -4)
            c = ks[i] * 10 ** rng.uniform(0, 1.5)
            s.add(f"k{i}", Backlash(b=b, c=c, d=float(rng.choice([0.0, 1e-3 * c])),
                                    eps=float(rng.choice([0.0, 0.05 * b, 0.2 * b]))))
        else:
            s.add(f"k{i}", Spring(c=ks[i]))
        s.add(f"d{i}", Damper(d=float(0.04 * np.sqrt(ks[i] * ms[i]))))
        for a, bb in ((prev, f"k{i}.flange_a"), (f"k{i}.flange_b", f"m{i}.flange_a"), (prev, f"d{i}.flange_a"),
                      (f"d{i}.flange_b", f"m{i}.flange_a")):
            s.connect(a, bb)
        prev = f"m{i}.flange_b"
    at = int(rng.integers(0, n))
    s.add("ground", Fixed())
    F_c = float(rng.uniform(1, 200))
    if rng.random() < 0.5:
        s.add("fr", CoulombFriction(F_c_pos=F_c, F_c_neg=F_c * rng.uniform(0.7, 1.3), d_pos=rng.uniform(0, 100),
                                    d_neg=rng.uniform(0, 100), v_reg=10 ** rng.uniform(-5, -3)))
    else:
        s.add("fr", StribeckFriction(F_s_pos=1.3 * F_c, F_s_neg=1.3 * F_c, F_c_pos=F_c, F_c_neg=F_c))
    s.connect("ground.flange", "fr.flange_a")
    s.connect("fr.flange_b", f"m{at}.flange_a")
    s.add("F", Force())
    s.connect("F.flange", prev)
    return s, F_c, n - 1


def nrmse(a, b):
    span = np.ptp(b)
    return float(np.sqrt(np.mean((a - b) ** 2)) / span) if span > 0 else float(np.max(np.abs(a - b)))


RUNS = [("modal", {"method": "modal"}), ("modal tol 1e-4", {"method": "modal", "modal_options": {"tol": 1e-4}}),
        ("idas", {"max_num_steps": 10**7})]
OTHERS = [("modal jit", {"method": "modal", "jit": True}), ("split", {"method": "split"}),
          ("fixed", {"method": "fixed"})]
COMPARE = [("idas rtol 1e-7", {"rtol": 1e-7, "atol": 1e-10, "max_num_steps": 10**7})]


def case(seed, t, runs=RUNS):
    """``(errors, walls)`` of one seed: worst NRMSE and wall time of each run (nan: it raised SimulationError)."""
    rng = np.random.default_rng(seed)
    system, F_c, last = chain(rng)
    amp, f = F_c * rng.uniform(0.5, 4), rng.uniform(5, 60)
    if rng.random() < 0.5:
        def u(tt):
            return amp * np.sign(np.sin(2 * np.pi * f * tt) + 1e-12)
    else:
        def u(tt):
            return amp * np.sin(2 * np.pi * f * tt)
    dae = flatten(system)
    outs = [f"m{last}.v", f"m{last}.a", "fr.f"]
    ref = simulate(dae, t, inputs={"F.f": u}, outputs=outs, rtol=1e-10, atol=1e-13, max_num_steps=10**7)
    errs, walls = [], []
    for _, kw in runs:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            try:
                r = simulate(dae, t, inputs={"F.f": u}, outputs=outs, **kw)
            except SimulationError:
                r = None
            walls.append(time.perf_counter() - t0)
        errs.append(np.nan if r is None else max(nrmse(r[o], ref[o]) for o in outs))
    return errs, walls


def main(first=0, last=80, others=False, compare=False):
    t = np.linspace(0.0, 0.2, 2001)
    runs = RUNS + (OTHERS if others else []) + (COMPARE if compare else [])
    names = [n for n, _ in runs]
    E, W = [], []
    for seed in range(first, last):
        errs, walls = case(seed, t, runs)
        E.append(errs)
        W.append(walls)
        print(f"seed {seed:3d}: worst NRMSE " + ", ".join(f"{n} {e:.1e} ({w:.2f} s)" for n, e, w in
                                                          zip(names, errs, walls, strict=True)), flush=True)
    E, W = np.array(E), np.array(W)
    em, ei = E[:, 0], E[:, 2]
    print(f"\n{len(E)} cases: modal (defaults) less accurate than IDAS (defaults) in {int(np.sum(em > ei))}, "
          f">3x in {int(np.sum(em > 3 * ei))}, >10x in {int(np.sum(em > 10 * ei))}; geometric mean of modal / "
          f"IDAS error {np.exp(np.mean(np.log(em / ei))):.2f}")
    for i, n in enumerate(names):
        ok = ~np.isnan(E[:, i])
        print(f"  {n:<16} median {np.median(E[ok, i]):.1e}, above 1e-2 in {int(np.sum(E[ok, i] > 1e-2))}, raised "
              f"SimulationError in {int(np.sum(~ok))}; wall sum {W[:, i].sum():.1f} s")
    if compare:
        ec = E[:, names.index("idas rtol 1e-7")]
        for i in (0, 1):
            em = E[:, i]
            print(f"  {names[i]} against idas rtol 1e-7: less accurate in {int(np.sum(em > ec))}, >3x in "
                  f"{int(np.sum(em > 3 * ec))}, >10x in {int(np.sum(em > 10 * ec))}; geometric mean of the ratio "
                  f"{np.exp(np.mean(np.log(em / ec))):.2f}")


if __name__ == "__main__":
    if "--floor" in sys.argv:
        i = sys.argv.index("--floor")
        modal_kernels.FORCE_FLOOR = modal_driver.FORCE_FLOOR = float(sys.argv[i + 1])
        del sys.argv[i:i + 2]
    others, compare = "--others" in sys.argv, "--compare" in sys.argv
    main(*[int(a) for a in sys.argv[1:3] if not a.startswith("--")], others=others, compare=compare)
