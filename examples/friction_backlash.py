"""Friction and backlash (thesis Sec 5.2.2.1-5.2.2.2): regularised models against exact references.

1. A mass on a spring with Coulomb friction (Eq 5.7), released from rest, simulated with the
   regularised :class:`CoulombFriction` for several ``v_reg`` and compared with the exact
   piecewise-analytic solution (amplitude loss 2 F_c/k per half period, stick at the first turning
   point inside |x| <= F_s/k).
2. The dead-zone hysteresis loop of :class:`Backlash` (Eq 5.8-5.9, Fig 5.5): a slow 1 Hz oscillation
   driven through the clearance into a mass on a viscous guide; the loop width is the backlash b.

Run ``python examples/friction_backlash.py OUT_DIR``; writes ``coulomb_oscillator.png`` and
``backlash_loop.png`` and prints the measured errors.
"""

import math
import sys
from pathlib import Path

import numpy as np

from bscomp import System
from bscomp.components import Backlash, CoulombFriction, Damper, Fixed, Mass, Spring
from bscomp.simulation.dispatch import simulate

M, K, F_C, X0 = 1.0, 1.0e4, 10.0, 10.5e-3  # omega = 100 rad/s; stick band |x| <= 1 mm
B, A = 1.0e-3, 5.0e-3  # backlash and drive amplitude [m]


# ---- model ------------------------------------------------------------------------------------------
def coulomb_oscillator(v_reg):
    s = System("coulomb_oscillator")
    s.add("wall", Fixed())
    s.add("k", Spring(c=K))
    s.add("m", Mass(m=M))
    s.add("fr", CoulombFriction(F_c=F_C, v_reg=v_reg))
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("wall.flange", "fr.flange_a")
    s.connect("fr.flange_b", "m.flange_b")
    return s


def coulomb_exact(t, x0=X0, m=M, k=K, F=F_C):
    """Exact solution: half cosines about +-F/k, turning points shrinking by 2F/k, stick in |x| <= F/k."""
    w = math.sqrt(k / m)
    x = np.empty_like(t)
    tn, xn = 0.0, x0
    while abs(k * xn) > F:
        c = math.copysign(F / k, xn)
        seg = (t >= tn) & (t <= tn + math.pi / w)
        x[seg] = c + (xn - c) * np.cos(w * (t[seg] - tn))
        xn, tn = 2 * c - xn, tn + math.pi / w
    x[t > tn] = xn
    return x, xn, tn


def backlash_rig():
    """Heavy 1 Hz oscillator -> backlash -> 1 kg output on a viscous guide."""
    M_in = 1.0e4
    s = System("backlash_loop")
    s.add("wall", Fixed())
    s.add("k_in", Spring(c=M_in * (2 * math.pi) ** 2))
    s.add("inp", Mass(m=M_in))
    s.add("bl", Backlash(b=B, c=1e8, d=1e4))
    s.add("out", Mass(m=1.0))
    s.add("guide", Damper(d=1e3))
    s.connect("wall.flange", "k_in.flange_a")
    s.connect("k_in.flange_b", "inp.flange_a")
    s.connect("inp.flange_b", "bl.flange_a")
    s.connect("bl.flange_b", "out.flange_a")
    s.connect("out.flange_b", "guide.flange_b")
    s.connect("wall.flange", "guide.flange_a")
    return s


def loop_width(x_in, x_out):
    v = np.gradient(x_in)
    level = 0.5 * (x_out.max() + x_out.min())

    def branch(mask):
        o = np.argsort(x_out[mask])
        return np.interp(level, x_out[mask][o], x_in[mask][o])

    return branch(v > 0) - branch(v < 0)


# ---- solve and post-process ------------------------------------------------------------------------
def main(out_dir="."):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    half = math.pi * math.sqrt(M / K)
    dt = 2.0**-12  # exactly uniform grid (power of two)
    t = dt * np.arange(int(7 * half / dt) + 1)
    x_ex, x_stick, t_stick = coulomb_exact(t)

    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(t * 1e3, x_ex * 1e3, "k", lw=2.5, label="exact (piecewise analytic)")
    print(f"Coulomb oscillator: x0 = {X0 * 1e3} mm, stick at {x_stick * 1e3:.3f} mm "
          f"after {t_stick * 1e3:.1f} ms")
    for v_reg in (1e-2, 1e-3, 1e-4):
        r = simulate(coulomb_oscillator(v_reg), t, x0={"m.s": X0}, outputs=["m.s"])
        err = r["m.s"] - x_ex
        stuck = t > t_stick + 0.2 * half
        print(f"  v_reg = {v_reg:7.0e} m/s: max |x - x_exact| = {np.max(np.abs(err[~stuck])) * 1e6:7.2f} um "
              f"while sliding, stick-position error at t_end = {abs(err[-1]) * 1e6:7.2f} um")
        ax[0].plot(t * 1e3, r["m.s"] * 1e3, "--", label=f"regularised, v_reg = {v_reg:g} m/s")
        ax[1].semilogy(t * 1e3, np.abs(err) * 1e6 + 1e-6, label=f"v_reg = {v_reg:g} m/s")
    ax[0].axhspan(-F_C / K * 1e3, F_C / K * 1e3, color="0.9", label="stick band |x| <= F_s/k")
    ax[0].set_ylabel("x [mm]")
    ax[0].legend(fontsize=8)
    ax[1].set_ylabel("|x - x_exact| [um]")
    ax[1].set_xlabel("t [ms]")
    ax[1].legend(fontsize=8)
    fig.suptitle("Mass-spring with Coulomb friction (Eq 5.7): tanh regularisation vs exact")
    fig.tight_layout()
    fig.savefig(out / "coulomb_oscillator.png", dpi=120)
    plt.close(fig)

    tb = np.linspace(0.0, 2.0, 2001)
    r = simulate(backlash_rig(), tb, x0={"inp.s": A, "out.s": A - B / 2}, outputs=["inp.s", "out.s"])
    sel = tb >= 1.0
    width = loop_width(r["inp.s"][sel], r["out.s"][sel])
    print(f"Backlash loop: width {width * 1e3:.5f} mm for b = {B * 1e3} mm "
          f"(error {100 * (width / B - 1):+.3f} %)")
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(r["inp.s"][sel] * 1e3, r["out.s"][sel] * 1e3, label="simulated (second cycle)")
    xi = np.linspace(-A, A, 3)
    for sgn in (-1, 1):
        ax.plot(xi * 1e3, (xi + sgn * B / 2) * 1e3, "k:", lw=1)
    ax.set_xlabel("input position [mm]")
    ax.set_ylabel("output position [mm]")
    ax.set_title(f"Backlash hysteresis (Eq 5.8-5.9): width {width * 1e3:.4f} mm, b = {B * 1e3} mm")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "backlash_loop.png", dpi=120)
    plt.close(fig)
    return {"loop_width": width}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
