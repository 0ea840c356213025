"""Thesis Chapter 4 controller designs, reproduced: P-PI on the rigid and flexible drive, notch, RST.

Run ``python examples/controller_design.py OUTDIR``; writes the figures (PNG), ``chapter4.json`` and
prints a thesis-vs-bscomp table (the one in docs/thesis-reproduction.md).

Sections: model (plants from Eq 4.2, Tables 4.1/4.2 and the bscomp ``small_drive``), design
(Eq 4.12, 4.18-4.21, 4.24-4.38), analysis (margins, bandwidth, step and disturbance responses).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bscomp.components import Force
from bscomp.control.closed_loop import (
    p_pi_loop,
    plant_from_system,
    rigid_plant,
    rst_loop,
    velocity_loop,
)
from bscomp.control.design import notch, pi_gains, ppc_polynomials, rst_design, split_polynomial
from bscomp.control.loop_analysis import (
    plot_bode_comparison,
    plot_disturbance_comparison,
    plot_sensitivity_comparison,
    plot_step_comparison,
)
from bscomp.systems import small_drive
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.thesis_plants import thesis_modal_plant


def main(outdir: str | Path = "controller_design_out") -> dict:
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    p = load_parameters()
    K_a, K_t, H_g = (get_value(p, f"electrical.{k}") for k in ("K_a", "K_t", "H_g"))
    J, B, r_g, Ts = (get_value(p, f"control.{k}") for k in ("J", "B", "r_g", "T_s"))

    # ---- model ----------------------------------------------------------------------------------
    rigid = rigid_plant(J, B, r_g, name="rigid (Eq 4.2)")
    flex_c = thesis_modal_plant("4.1", "C")
    bellows_l = thesis_modal_plant("4.2", "L")
    bellows_c = thesis_modal_plant("4.2", "C")
    sd = small_drive()
    sd.add("Fd", Force())
    sd.connect("Fd.flange", "table.flange_b")
    small = plant_from_system(sd, F_d="Fd.f", name="bscomp small_drive")

    # ---- design ---------------------------------------------------------------------------------
    K_v, K_i = pi_gains(J, B, K_a, K_t, H_g, wn=2 * 3.141592653589793 * 50.0, zeta=0.7071)  # Eq 4.12-4.14
    vel = (K_a, K_t, H_g, K_v, K_i)
    nf = notch(0.0855, 753.98, 0.5, Ts)  # Table 4.3
    A = [1.0] + list(get_value(p, "control.ppc_A"))  # Table 4.4
    Bz = get_value(p, "control.ppc_B")
    B_plus, _ = split_polynomial(Bz, near=[0.535])  # Eq 4.32
    pp = ppc_polynomials(1.0, 565.49, 1.0, 0.7071, 763.43, Ts, B_plus=B_plus)  # Eq 4.35-4.38
    rst = rst_design(A, Bz, pp.A_c, pp.A_o, B_plus=B_plus, R_d=[1, -1], S_d=[1, 1], Ts=Ts)  # Eq 4.24-4.29

    # ---- analysis -------------------------------------------------------------------------------
    v = velocity_loop(rigid, *vel)
    r_rigid = p_pi_loop(rigid, *vel, K_p=7000.0, Ts=Ts)
    r_flex = p_pi_loop(flex_c, *vel, K_p=7000.0, Ts=Ts)
    r_small = p_pi_loop(small, *vel, K_p=7000.0, Ts=Ts)
    n_without = p_pi_loop(bellows_l, *vel, K_p=5000.0, Ts=Ts)
    n_with = p_pi_loop(bellows_l, *vel, K_p=5000.0, Ts=Ts, notch=nf)
    n_with_c = p_pi_loop(bellows_c, *vel, K_p=5000.0, Ts=Ts, notch=nf)
    r_rst = rst_loop(bellows_c, rst, K_a, K_t)
    s_without = p_pi_loop(small, *vel, K_p=5000.0, Ts=Ts)
    s_with = p_pi_loop(small, *vel, K_p=5000.0, Ts=Ts, notch=nf)

    plot_step_comparison([v], out / "fig4_4_velocity_step.png", "Velocity loop, rigid drive (Fig 4.4)")
    plot_sensitivity_comparison([v], out / "fig4_5_velocity_sensitivity.png", "Velocity loop (Fig 4.5)")
    plot_bode_comparison([r_rigid], out / "fig4_6_rigid_open_loop.png", "P-PI position loop, rigid (Fig 4.6)")
    plot_step_comparison([r_rigid], out / "fig4_7_rigid_step.png", "P-PI position loop, rigid (Fig 4.7)")
    plot_bode_comparison([r_rigid, r_flex, r_small], out / "fig4_9_flexible_open_loop.png",
                         "Rigid design on flexible plants (Fig 4.9)")
    plot_step_comparison([r_rigid, r_flex, r_small], out / "fig4_10_flexible_step.png",
                         "Rigid design on flexible plants (Fig 4.10)")
    plot_bode_comparison([n_without, n_with, s_without, s_with], out / "fig4_16_notch_open_loop.png",
                         "K_p = 5000 V/m with and without notch (Fig 4.16)")
    plot_step_comparison([n_without, n_with, s_without, s_with], out / "fig4_17_notch_step.png",
                         "Notch filter, step (Fig 4.17)")
    plot_sensitivity_comparison([n_without, n_with], out / "fig4_18_notch_sensitivity.png",
                                "Notch filter (Fig 4.18)")
    plot_bode_comparison([r_rst], out / "fig4_22_rst_open_loop.png", "RST position loop (Fig 4.22)")
    plot_step_comparison([n_with_c, r_rst], out / "fig4_23_rst_step.png", "RST vs P-PI + notch (Fig 4.23)")
    plot_sensitivity_comparison([n_with_c, r_rst], out / "fig4_24_rst_sensitivity.png",
                                "RST vs P-PI + notch (Fig 4.24)")
    plot_disturbance_comparison([n_with_c, r_rst], out / "fig4_25_rst_disturbance.png",
                                "Unit step disturbance (Fig 4.25)")

    loops = {"velocity": v, "rigid": r_rigid, "flexible_C": r_flex, "small_drive": r_small,
             "notch_L_without": n_without, "notch_L_with": n_with, "notch_C_with": n_with_c, "rst_C": r_rst,
             "small_drive_K5000": s_without, "small_drive_K5000_notch": s_with}
    summary = {
        "pi_gains": {"K_v": K_v, "K_i": K_i},
        "notch": {k: getattr(nf, k) for k in ("n1", "n2", "d1", "d2", "K_N")},
        "ppc": pp.coefficients,
        "rst": {"r": list(rst.r), "s": list(rst.s), "t0": rst.t0},
        "loops": {k: lp.to_dict() for k, lp in loops.items()},
    }
    (out / "chapter4.json").write_text(json.dumps(summary, indent=2, default=float))
    for lp in loops.values():
        print(lp.table())
    return summary


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", nargs="?", default="controller_design_out")
    main(ap.parse_args().outdir)
