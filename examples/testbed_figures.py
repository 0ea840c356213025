"""Figures of the thesis test bed: Fig 4.2 FRFs, Fig 4.12/4.13 mode shapes, Fig 3.27/3.28 and Table 4.1
frequencies against the nut position, and the Appendix C cross-coupling study.

FRFs are modal sums (thesis Eq 4.3-4.7) over every mode of :func:`bscomp.linear.modal.modes` -- residues
``R_k`` and damping from the model -- checked against the direct sparse solve of
:meth:`bscomp.linear.SecondOrderModel.frf` at a few frequencies (the printed "max rel. difference").

Run: python examples/testbed_figures.py OUT_DIR [--quick]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from bscomp import second_order
from bscomp.linear.modal import modes
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.testbed import nut_positions, testbed
from bscomp.systems.testbed_analysis import DRIVE_INPUTS, DRIVE_OUTPUTS, drive_parameters, free_free_modes


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


# ---- solve ----------------------------------------------------------------------------------------------
def modal_frf(md, freqs):
    """``H[f, out, in]`` of displacement outputs by the modal sum of Eq 4.3 (rigid mode: ``R / (s^2 + d s)``)."""
    s = 2j * np.pi * np.asarray(freqs, float)[:, None]
    w = md.omega[None, :]
    z = np.where(md.rigid_body, 0.0, np.nan_to_num(md.damping))[None, :]
    d = np.where(md.rigid_body, md.decay_rates, 2 * z[0] * md.omega)[None, :]
    den = s**2 + d * s + w**2
    return np.einsum("fk,kji->fji", 1.0 / den, md.residues)


def check_frf(so, md, freqs):
    """Max relative difference between the modal sum and the direct solve at ``freqs``."""
    H_direct = so.frf(freqs)
    H_modal = modal_frf(md, freqs)
    return float(np.max(np.abs(H_modal - H_direct)) / np.max(np.abs(H_direct)))


# ---- figures --------------------------------------------------------------------------------------------
def fig_4_2(out: Path):
    """Magnitudes of tau -> omega, tau -> x, F_d -> omega, F_d -> x at L, C, R (0-300 Hz)."""
    plt = _plt()
    f = np.linspace(0.5, 300.0, 1200)
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    labels = {(0, 0): ("tau", "omega", "rad/s/(N m)"), (1, 0): ("tau", "x", "m/(N m)"),
              (0, 1): ("F_d", "omega", "rad/s/N"), (1, 1): ("F_d", "x", "m/N")}
    errs = []
    for pos in "LCR":
        so = second_order(testbed("full", nut_position=pos, drive_input="torque"), inputs=DRIVE_INPUTS,
                          outputs=DRIVE_OUTPUTS)     # Fig 4.2 is drawn from the motor torque
        md = modes(so, damping="projection")
        errs.append(check_frf(so, md, np.array([20.0, 118.0, 270.0])))
        H = modal_frf(md, f)
        for (j, i), (inp, outp, unit) in labels.items():
            h = H[:, j, i] * (2j * np.pi * f if outp == "omega" else 1.0)
            ax = axes[j, i]
            ax.semilogy(f, np.abs(h), label=f"{pos}-Position")
            ax.set_title(f"{inp} -> {outp}")
            ax.set_ylabel(f"|H| [{unit}]")
    for ax in axes.ravel():
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    fig.suptitle("Test bed (full 6-DOF model): FRFs between the drive inputs and outputs (thesis Fig 4.2)")
    fig.tight_layout()
    fig.savefig(out / "fig4_2_frfs.png", dpi=120)
    plt.close(fig)
    print(f"  fig4_2_frfs.png (modal sum vs direct solve: max rel. difference {max(errs):.1e})")


def fig_4_12_4_13(out: Path):
    """Axial shape of mode 1 and torsional shape of mode 2 along the screw (C-Position)."""
    plt = _plt()
    system = testbed("full", nut_position="C")
    d = drive_parameters(system)
    md = d["modes"]
    screw = system.component("screw")
    x = screw.z_nodes
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for ax, key, field, what in ((axes[0], "mode1", "w", "axial displacement w"),
                                 (axes[1], "mode2", "tz", "rotation theta_z")):
        k = d[key]
        phi = md.shapes[:, k]
        idx = [md.coordinates.index(f"screw.n{i}.{field}") for i in range(len(x))]
        y = phi[idx]
        extra = phi[md.coordinates.index("sn.nut.w" if field == "w" else "rotor.phi")]
        scale = max(np.max(np.abs(y)), abs(extra)) or 1.0
        ax.plot(x * 1e3, y / scale, "o-", ms=3, label="screw nodes")
        if field == "w":
            xn = screw.points["nut"]
            ax.plot([xn * 1e3], [extra / scale], "s", ms=9, label="nut + table (z only)")
            ax.axvline(screw.points["b1"] * 1e3, color="k", ls=":", label="thrust bearing b1")
        else:
            ax.plot([x[-1] * 1e3 + 40], [extra / scale], "s", ms=9,
                    label="rotor (+J1), drawn 40 mm past the screw end")
        ax.set_ylabel(f"{what} [normalised]")
        ax.set_title(f"mode {key[-1]}: {md.frequencies[k]:.1f} Hz "
                     f"({'Fig 4.12, axial' if field == 'w' else 'Fig 4.13, torsional'})")
        ax.grid(True, alpha=0.3)
        ax.legend()
    axes[1].set_xlabel("x along the screw [mm] (0 = free end of section A; motor at the F end)")
    fig.tight_layout()
    fig.savefig(out / "fig4_12_4_13_mode_shapes.png", dpi=120)
    plt.close(fig)
    print("  fig4_12_4_13_mode_shapes.png")


def fig_position(out: Path, quick: bool):
    """Natural frequencies against the nut position: free-free screw+nut (Fig 3.27/3.28, Tables 3.2/3.3)
    and the full drive (Table 4.1)."""
    plt = _plt()
    P = load_parameters()
    ref = lambda k: get_value(P, f"reference_results.{k}")  # noqa: E731
    pos = nut_positions()
    n = 6 if quick else 15
    xs = np.linspace(0.0925, 0.7725, n)
    ff = [free_free_modes(float(x)) for x in xs]
    xd = np.linspace(pos["L"] - 0.06, pos["R"] + 0.06, n)
    dr = [drive_parameters(nut_position=float(x), damping=False) for x in xd]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    x123 = np.array([pos[p] for p in "123"]) * 1e3
    axes[0].plot(xs * 1e3, [r["axial"] for r in ff], "o-", label="bscomp")
    axes[0].plot(x123, ref("free_free_axial_simulated"), "kx", ms=9, label="thesis simulation (Table 3.2)")
    axes[0].plot(x123, ref("free_free_axial_measured"), "r+", ms=11, label="thesis measurement")
    axes[0].set_title("free-free screw + nut: 1st axial mode")
    axes[1].plot(xs * 1e3, [r["torsional"] for r in ff], "o-", label="bscomp")
    axes[1].plot(x123, ref("free_free_torsional_simulated"), "kx", ms=9, label="thesis simulation (Table 3.3)")
    axes[1].plot(x123, ref("free_free_torsional_measured"), "r+", ms=11, label="thesis measurement")
    axes[1].set_title("free-free screw + nut: 1st torsional mode")
    xlcr = np.array([pos[p] for p in "LCR"]) * 1e3
    axes[2].plot(xd * 1e3, [r["f1"] for r in dr], "o-", label="f_n1 (axial)")
    axes[2].plot(xd * 1e3, [r["f2"] for r in dr], "s-", label="f_n2 (coupling torsion)")
    axes[2].plot(xlcr, ref("table41_fn1"), "kx", ms=9, label="Table 4.1")
    axes[2].plot(xlcr, ref("table41_fn2"), "kx", ms=9)
    axes[2].set_title("full drive: the two modes of Fig 4.2")
    for ax in axes:
        ax.set_xlabel("nut centre x [mm]")
        ax.set_ylabel("natural frequency [Hz]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Position-dependent dynamics (thesis Fig 3.27/3.28, Tables 3.2/3.3/4.1); positions 1/2/3 and "
                 "L/C/R are toml CHOICEs")
    fig.tight_layout()
    fig.savefig(out / "fig3_27_3_28_frequencies_vs_position.png", dpi=120)
    plt.close(fig)
    print("  fig3_27_3_28_frequencies_vs_position.png")


def fig_appendix_c(out: Path):
    """App C: K_SN with (Case B, Eq 3.45) and without (Case A, Eq 3.46) the bending cross-coupling terms,
    table+nut on four roller slides (Table C.1); pitch 10 mm and 45 mm."""
    plt = _plt()
    outputs = ["table.s0.u", "table.s0.v", "table.s0.w"]
    f = np.linspace(1.0, 2000.0, 4000)
    res = {}
    for pitch in (None, 0.045):
        for case, ksn in (("A", "axial_torsional"), ("B", "full")):
            so = second_order(testbed("appendix_c", ksn=ksn, pitch=pitch, damping=False, drive_input="torque"),
                              inputs=["motor.tau"], outputs=outputs)
            md = modes(so, damping="projection")
            # light uniform damping for the plot only (App C gives none): 2 % on every elastic mode
            md.damping = np.where(md.rigid_body, np.nan, 0.02)
            res[(pitch, case)] = (md, modal_frf(md, f))
    fig, axes = plt.subplots(2, 2, figsize=(13, 8))
    md_a, md_b = res[(None, "A")][0], res[(None, "B")][0]
    n = 30
    axes[0, 0].plot(np.arange(1, n + 1), md_a.frequencies[:n], "o", label="Case A (Eq 3.46)")
    axes[0, 0].plot(np.arange(1, n + 1), md_b.frequencies[:n], "x", label="Case B (Eq 3.45)")
    md_a45, md_b45 = res[(0.045, "A")][0], res[(0.045, "B")][0]
    axes[0, 0].plot(np.arange(1, n + 1), md_a45.frequencies[:n], "s", mfc="none", label="Case A, pitch 45 mm")
    axes[0, 0].plot(np.arange(1, n + 1), md_b45.frequencies[:n], "+", label="Case B, pitch 45 mm")
    axes[0, 0].set_xlabel("mode number")
    axes[0, 0].set_ylabel("natural frequency [Hz]")
    axes[0, 0].set_title("natural frequencies (thesis: mode 9 ~659 Hz, mode 19 ~1470 Hz)")
    for (j, k), comp in zip(((0, 1), (1, 0), (1, 1)), ("u (vertical x)", "v (lateral y)", "w (feed z)"), strict=True):
        ax = axes[j, k]
        idx = ((j, k) != (0, 1)) + ((j, k) == (1, 1))
        for (pitch, case), (_, H) in res.items():
            if pitch is None:
                ax.semilogy(f, np.abs(H[:, idx, 0]), label=f"Case {case}")
        ax.set_title(f"motor torque -> table corner slide s0, {comp}")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("|H| [m/(N m)]")
    for ax in axes.ravel():
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Appendix C: bending cross-coupling terms of K_SN (table+nut on roller slides, Table C.1; "
                 "2 % damping for display)")
    fig.tight_layout()
    fig.savefig(out / "appendix_c_cross_coupling.png", dpi=120)
    plt.close(fig)
    band = (f > 300) & (f < 2000)
    gain = [float(np.max(np.abs(res[(None, "B")][1][band, i, 0])) / np.max(np.abs(res[(None, "A")][1][band, i, 0])))
            for i in range(3)]
    print(f"  appendix_c_cross_coupling.png (peak |tau -> corner u, v, w| 300-2000 Hz, Case B / Case A: "
          f"{gain[0]:.2f}, {gain[1]:.2f}, {gain[2]:.2f})")
    return {"frequencies_A": md_a.frequencies[:n].tolist(), "frequencies_B": md_b.frequencies[:n].tolist(),
            "peak_ratio_B_over_A": gain}


def main(out_dir, quick: bool = False):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    fig_4_2(out)
    fig_4_12_4_13(out)
    fig_position(out, quick)
    summary = fig_appendix_c(out)
    print(f"figures written to {out} in {time.perf_counter() - t0:.1f} s")
    return summary


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir")
    ap.add_argument("--quick", action="store_true", help="fewer positions")
    a = ap.parse_args()
    main(a.out_dir, quick=a.quick)
