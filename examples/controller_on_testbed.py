"""Thesis Ch 4 designs on bscomp's own test-bed model (not the thesis's printed Table 4.1/4.2 values):
P-PI margins of the rigid design at L/C/R, and Table 4.4's discrete plant polynomials A, B at C.

Run: python examples/controller_on_testbed.py OUT_DIR   (writes controller_on_testbed.md there and prints it)

The plant is the modal model of Eq 4.3-4.7 built from our full 6-DOF test bed: J, B, and the first two
axial/torsional modes (frequency, damping, residues) at each nut position (systems/testbed_analysis.py).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from bscomp.control.closed_loop import modal_plant, p_pi_loop
from bscomp.control.design import pi_gains, zoh_polynomials
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.testbed_analysis import drive_parameters
from bscomp.systems.thesis_plants import thesis_modal_plant

THESIS_MARGINS_C = (3.12, 65.3)  # Sec 4.3.2 / Table 4.1 plant at C, K_p = 7000 V/m


def main(out_dir="out/controller_on_testbed"):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p = load_parameters()
    K_a, K_t, H_g = (get_value(p, f"electrical.{k}") for k in ("K_a", "K_t", "H_g"))
    J, B, r_g, Ts = (get_value(p, f"control.{k}") for k in ("J", "B", "r_g", "T_s"))
    K_v, K_i = pi_gains(J, B, K_a, K_t, H_g, wn=2 * np.pi * 50.0, zeta=0.7071)  # Eq 4.12-4.14, thesis J, B
    vel = (K_a, K_t, H_g, K_v, K_i)
    lines = ["| position | plant | f_n1 [Hz] | f_n2 [Hz] | GM [dB] | PM [deg] |", "|---|---|---:|---:|---:|---:|"]
    plants = {}
    for pos in ("L", "C", "R"):
        d = drive_parameters(variant="full", nut_position=pos)
        modes = [(d[f"f{i}"], d[f"zeta{i}"], d[f"Rw{i}"], d[f"Rm{i}"]) for i in (1, 2)]
        plants[pos] = ours = modal_plant(d["J"], d["B"], d["r_g"], modes, name=f"bscomp test bed at {pos}")
        r = p_pi_loop(ours, *vel, K_p=7000.0, Ts=Ts)
        lines.append(f"| {pos} | bscomp | {d['f1']:.2f} | {d['f2']:.2f} | {r.metrics['gm_db']:.2f} | "
                     f"{r.metrics['pm_deg']:.1f} |")
        th = thesis_modal_plant("4.1", pos)
        rt = p_pi_loop(th, *vel, K_p=7000.0, Ts=Ts)
        m = rt.metrics
        lines.append(f"| {pos} | thesis Table 4.1 values | | | {m['gm_db']:.2f} | {m['pm_deg']:.1f} |")
    gm, pm = THESIS_MARGINS_C
    lines.append(f"\nThesis (Sec 4.3.2, flexible model at C): GM {gm} dB, PM {pm} deg.")
    # Table 4.4: ZOH-discretised G_e G_m at C (bellows coupling in the thesis: Table 4.2 plant)
    d = drive_parameters(variant="full", nut_position="C", coupling="bellows")
    modes = [(d["f1"], d["zeta1"], d["Rw1"], d["Rm1"])]
    import control

    Gm = modal_plant(d["J"], d["B"], d["r_g"], modes).sys[1, 0] * (K_a * K_t)  # G_e G_m (Eq 4.30-4.31)
    A, Bz = zoh_polynomials(control.ss(Gm), Ts)
    A_th = [1.0] + list(get_value(p, "control.ppc_A"))
    B_th = list(get_value(p, "control.ppc_B"))
    lines.append("\nTable 4.4 (bellows coupling, nut at C, rigid body + first mode, T_s = 200 µs):\n")
    lines.append("| coefficient | thesis | bscomp |")
    lines.append("|---|---:|---:|")
    for k, (a_t, a_o) in enumerate(zip(A_th, np.atleast_1d(A))):
        lines.append(f"| a{k} | {a_t:.6g} | {a_o:.6g} |")
    for k, (b_t, b_o) in enumerate(zip(B_th, np.atleast_1d(Bz))):
        lines.append(f"| b{k} | {b_t:.6g} | {b_o:.6g} |")
    text = "\n".join(lines)
    (out / "controller_on_testbed.md").write_text(text + "\n")
    print(text)
    return text


if __name__ == "__main__":
    main(*(sys.argv[1:2] or ["out/controller_on_testbed"]))
