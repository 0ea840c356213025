"""Thesis Ch 5 scenarios on the axial + torsional test bed: open-loop square wave with and without
guideway friction and screw-nut backlash (Fig 5.11), nut at C vs R (Fig 5.12), full vs CMS-reduced
model (Fig 5.14/5.15).

Run: python examples/nonlinear_scenarios.py OUT_DIR [T_END]

Friction: Coulomb 2066 N (Table 5.2, Eq 5.7) at the guideway, regularised with v_reg = 1e-4 m/s
(docs/nonlinear.md: error ≤ 1e-3 of the sliding speed); the viscous part is the B = 0.0321 kg m^2/s
already on the motor (the same damping, Sec 4.2.1 / Table 5.2: not applied twice). Backlash: the
Table 5.2 dead zone L = 0.001885 rad on the screw's torsional DOF equals r_g L = 3.0 µm axially; it is
inserted between the nut and the table with a contact stiffness 10x the interface's axial stiffness
(a choice, so that only the gap is added).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import bscomp
from bscomp import System
from bscomp.components import SecondOrderBlock
from bscomp.linear.reduction import reduce_second_order
from bscomp.simulation.dispatch import simulate
from bscomp.systems.testbed import testbed_axial_torsional
from bscomp.systems.thesis_effects import with_friction_backlash


def square_wave(t, pp=4.25, f=5.0):
    """Amplifier command ``amp.u``: the 4.25 V peak-to-peak, 5 Hz square wave (Sec 5.3.1); the model's
    amplifier and torque constant turn it into the motor torque (Eq 4.1)."""
    return 0.5 * pp * (1.0 if (t * f) % 1.0 < 0.5 else -1.0)


def drive(position="C", friction=False, backlash=False) -> System:
    """The Ch 5 model with optional nonlinear effects (section: model; Table 5.2 values,
    :func:`bscomp.systems.thesis_effects.with_friction_backlash`)."""
    return with_friction_backlash(testbed_axial_torsional(nut_position=position), friction=friction, backlash=backlash)


def run(system, t, outputs=("table.v", "table.a", "rotor.w")):
    """Simulate the square-wave response (section: solve)."""
    return simulate(system, t, inputs={"amp.u": square_wave}, outputs=list(outputs), max_num_steps=10**6)


def main(out_dir="out/nonlinear", T_end=0.4):
    from bscomp.plotting import pyplot as _plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = np.arange(0.0, T_end + 1e-12, 1e-4)
    plt = _plt()
    # Fig 5.11: linear vs friction vs friction + backlash, nut at C
    cases = {"linear": drive("C"), "friction": drive("C", friction=True),
             "friction + backlash": drive("C", friction=True, backlash=True)}
    res = {}
    for name, s in cases.items():
        res[name] = run(s, t)
        print(f"  C, {name:<20} {res[name].stats['wall_s']:6.2f} s wall, "
              f"max |v| = {np.max(np.abs(res[name]['table.v'])):.4f} m/s")
    fig, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for name, r in res.items():
        ax[0].plot(t, r["table.v"], label=name)
        ax[1].plot(t, r["table.a"], label=name)
    ax[0].set_ylabel("table velocity [m/s]")
    ax[1].set_ylabel("table acceleration [m/s²]")
    ax[1].set_xlabel("time [s]")
    ax[0].legend(fontsize=8)
    ax[0].set_title("Open-loop 4.25 Vpp 5 Hz square wave, nut at C (cf. Fig 5.11)")
    fig.tight_layout()
    fig.savefig(out / "fig5_11_friction_backlash.png", dpi=120)
    plt.close(fig)
    # Fig 5.12: C vs R with friction and backlash
    rR = run(drive("R", friction=True, backlash=True), t)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t, res["friction + backlash"]["table.a"], label="C")
    ax.plot(t, rR["table.a"], label="R", alpha=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("table acceleration [m/s²]")
    ax.legend()
    ax.set_title("Nut at C vs R (cf. Fig 5.12)")
    fig.tight_layout()
    fig.savefig(out / "fig5_12_position.png", dpi=120)
    plt.close(fig)
    # Fig 5.14/5.15: full vs CMS-reduced (linear model)
    so = bscomp.second_order(drive("C"), inputs=["amp.u"], outputs=["table.a", "table.v"])
    red, info = reduce_second_order(so, boundary=["rotor.phi", "sn.nut.w"], f_cut=2000.0)
    rs = System("reduced")
    rs.add("plant", SecondOrderBlock(red))
    rr = simulate(rs, t, inputs={"plant.amp_u": square_wave}, outputs=["plant.table_a"])
    full = res["linear"]
    err = np.max(np.abs(rr["plant.table_a"] - full["table.a"])) / np.max(np.abs(full["table.a"]))
    print(f"  reduced model: {red.M.shape[0]} coordinates (full {so.n}); table.a max error {err:.2e}; "
          f"wall {rr.stats['wall_s']:.2f} s vs {full.stats['wall_s']:.2f} s")
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t, full["table.a"], label=f"full ({so.n} coordinates)")
    ax.plot(t, rr["plant.table_a"], "--", label=f"CMS reduced ({red.M.shape[0]})")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("table acceleration [m/s²]")
    ax.legend()
    ax.set_title("Full vs reduced model (cf. Fig 5.14/5.15)")
    fig.tight_layout()
    fig.savefig(out / "fig5_14_full_vs_reduced.png", dpi=120)
    plt.close(fig)
    return res


if __name__ == "__main__":
    main(*(sys.argv[1:2] or ["out/nonlinear"]), *(float(a) for a in sys.argv[2:3]))
