"""Model reduction of the test bed's sub-model 1 by CMS with MD / MA recovery (thesis Sec 5.2.3, 5.3.2).

Sub-model 1 (Table 5.1) is the axial + torsional model of the ballscrew with the thrust bearing, the
coupling and the rotor; the nut and table form sub-model 2 and act on it through the screw-nut joint
at the moving nut position (Sec 5.2.2.3, Fig 5.8).  This script

1. builds sub-model 1 from the test-bed parameter file (97 DOF; Table 5.1 says 101),
2. reduces it as in Sec 5.3.2 (exterior: motor rotation and θz of the mid-length node; 3 free-interface
   modes + the rigid-body mode = 6 coordinates) and prints Table 5.3 beside the thesis's,
3. plots the frequency error against the number of kept modes (free and fixed interface),
4. plots the MD and MA recovery errors of the static nut displacement against the nut position,
5. couples the reduced sub-model to the table through K_SN at each nut position (no re-reduction)
   and compares the first axial mode with the full model (Table 4.1: 109.5 / 117.7 / 133.8 Hz).

Run ``python examples/model_reduction.py OUTPUT_FOLDER``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.components import BeamModel, DofSelection, assemble_shaft, select_dofs
from bscomp.linear.reduction import ReducedModel, cms_reduce
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.thesis_parts import thesis_sections

PARAMS = load_parameters("fadal_vmc2216_x")


# ============================================================================ model
@dataclass
class SubModel1:
    """Axial + torsional sub-model 1: DOF ``screw.n<k>.w``, ``screw.n<k>.tz`` and ``rotor.phi``."""

    M: np.ndarray
    K: np.ndarray
    names: list
    beam: BeamModel
    sel: DofSelection

    def nut_row(self, z: float) -> sp.csr_matrix:
        """(2, n) interpolation row of (w, θz) at axial position ``z`` (shape functions, Sec 5.2.2.3)."""
        S = self.beam.shape_matrix(z)[[2, 5]][:, self.sel.index]
        return sp.hstack([S, sp.csr_matrix((2, 1))]).tocsr()


def build_submodel1(
    bearing_position: float | None = None, coupling_position: float | None = None,
    d_root: float | None = None,
) -> SubModel1:
    """Sub-model 1 of Table 5.1 from the parameter file (CHOICE entries can be overridden).

    Thrust bearing: axial spring ``bearings.b1_k_axial`` at ``bearing_position``; deep-groove bearing:
    radial only (no axial/torsional term); coupling: torsional spring ``coupling.kT`` between the rotor
    DOF (rotor + J1) and the screw node at ``coupling_position`` carrying J2.
    """
    g = lambda key: get_value(PARAMS, key)  # noqa: E731
    bearing_position = g("bearings.b1_position") if bearing_position is None else bearing_position
    coupling_position = g("coupling.attach_position") if coupling_position is None else coupling_position
    d_root = g("screw.root_diameter") if d_root is None else d_root
    beam = assemble_shaft(
        thesis_sections(d_root=d_root, d_equiv=g("screw.equivalent_diameter")),
        E=g("screw.material.youngs_modulus"), rho=g("screw.material.density"),
        nu=g("screw.material.poissons_ratio"), kappa=g("screw.material.shear_factor"),
    )
    sel = select_dofs(beam, ("w", "tz"))
    z = beam.z_nodes
    n = sel.M.shape[0]
    M = np.zeros((n + 1, n + 1))
    K = np.zeros((n + 1, n + 1))
    M[:n, :n] = sel.M.toarray()
    K[:n, :n] = sel.K.toarray()
    ib = sel.local_index(int(np.argmin(abs(z - bearing_position))), "w")
    K[ib, ib] += g("bearings.b1_k_axial")
    jc = sel.local_index(int(np.argmin(abs(z - coupling_position))), "tz")
    M[jc, jc] += g("coupling.J2")
    M[n, n] = g("rotor.Izz") + g("coupling.J1")
    K[np.ix_([n, jc], [n, jc])] += g("coupling.kT") * np.array([[1.0, -1.0], [-1.0, 1.0]])
    names = [f"screw.n{k}.{d}" for k in range(beam.n_nodes) for d in ("w", "tz")] + ["rotor.phi"]
    return SubModel1(M=M, K=K, names=names, beam=beam, sel=sel)


def frequencies(M, K) -> np.ndarray:
    """Undamped natural frequencies [Hz], ascending."""
    return np.sqrt(np.clip(sla.eigh(K, M, eigvals_only=True), 0.0, None)) / (2 * np.pi)


def centre_anchor(sm: SubModel1, dof: str = "tz") -> str:
    """Name of ``dof`` at the node nearest the screw's mid-length (the Sec 5.3.2 anchor)."""
    z = sm.beam.z_nodes
    return f"screw.n{int(np.argmin(abs(z - z[-1] / 2)))}.{dof}"


def ksn_axial_torsional() -> np.ndarray:
    """2x2 (w, θz) block of K_SN from the Eq 3.45 coefficients (k_zz, k_ztz, k_tztz)."""
    c = get_value(PARAMS, "screw_nut.K_SN_coefficients")
    return get_value(PARAMS, "screw_nut.k_ball") * np.array([[c[2], c[10]], [c[10], c[5]]])


def coupled_first_axial(sm: SubModel1, red: ReducedModel, z_nut: float) -> tuple[float, float, float]:
    """First axial mode [Hz] of sub-model 1 + K_SN + table mass at ``z_nut``: (full, reduced MA, reduced MD).

    The reduced model is not rebuilt: :meth:`ReducedModel.port` gives the position-dependent matrices;
    the MA algebraic loop ``f = -K_SN (C_x x + C_a x'' + D f - u)`` is solved for ``f`` in closed form.
    """
    Ksn = ksn_axial_torsional()
    mt = get_value(PARAMS, "table.mass") + get_value(PARAMS, "nut.mass")
    e1 = np.array([1.0, 0.0])
    R = sm.nut_row(z_nut).toarray()
    n, m = sm.M.shape[0], red.n_reduced
    Rf = np.hstack([R, -e1[:, None]])
    Mf = np.zeros((n + 1, n + 1))
    Mf[:n, :n], Mf[n, n] = sm.M, mt
    Kf = np.zeros((n + 1, n + 1))
    Kf[:n, :n] = sm.K
    Kf += Rf.T @ Ksn @ Rf
    port = red.port(R)
    S = np.linalg.solve(np.eye(2) + Ksn @ port.D, Ksn)
    Mc = np.zeros((m + 1, m + 1))
    Kc = np.zeros((m + 1, m + 1))
    Mc[:m, :m] = red.M + port.B @ S @ port.C_a
    Mc[m, :m] = -e1 @ S @ port.C_a
    Mc[m, m] = mt
    Kc[:m, :m] = red.K + port.B @ S @ port.C_x
    Kc[:m, m] = -port.B @ S @ e1
    Kc[m, :m] = -e1 @ S @ port.C_x
    Kc[m, m] = e1 @ S @ e1
    f_ma = np.sort(np.sqrt(np.clip(sla.eigvals(Kc, Mc).real, 0.0, None)) / (2 * np.pi))
    Rr = np.hstack([port.C_md, -e1[:, None]])
    Mm = np.zeros((m + 1, m + 1))
    Mm[:m, :m], Mm[m, m] = red.M, mt
    Km = np.zeros((m + 1, m + 1))
    Km[:m, :m] = red.K
    Km += Rr.T @ Ksn @ Rr
    # index 0 is the ~11.5 Hz table-on-K_SN mode (rounded, nearly singular 2x2 K_SN); 1 is axial
    return float(frequencies(Mf, Kf)[1]), float(f_ma[1]), float(frequencies(Mm, Km)[1])


def static_recovery_errors(sm: SubModel1, red: ReducedModel, z_nut: float) -> dict:
    """Relative MD and MA errors of the nut displacement under a static axial force / torque at z_nut.

    The motor rotation is held (servo-locked) so that the torsion has a static solution.
    """
    motor = sm.names.index("rotor.phi")
    free = np.arange(sm.M.shape[0]) != motor
    R = sm.nut_row(z_nut)
    out = {}
    for k, label in ((0, "axial"), (1, "torsion")):
        F = R.T @ np.eye(2)[k]
        d = np.zeros(sm.M.shape[0])
        d[free] = np.linalg.solve(sm.K[np.ix_(free, free)], F[free])
        x = np.zeros(red.n_reduced)
        x[1:] = np.linalg.solve(red.K[1:, 1:], red.force(F)[1:])  # reduced coordinate 0 is the motor
        y = (R @ d)[k]
        out[f"{label}_MD"] = abs(red.recover(x, method="MD", at=R)[k] - y) / abs(y)
        out[f"{label}_MA"] = abs(red.recover(x, f=F, at=R)[k] - y) / abs(y)
    return out


# ============================================================================ main
def main(out_dir: str | Path = "model_reduction_out") -> dict:
    """Run the study and write ``*.png`` figures to ``out_dir``; returns the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    # ---------------------------------------------------------------- model and Table 5.3
    sm = build_submodel1()
    f_full = frequencies(sm.M, sm.K)
    anchor = centre_anchor(sm, "tz")
    red = cms_reduce(sm.M, sm.K, ["rotor.phi", anchor], 3, dof_names=sm.names)
    f_red = red.natural_frequencies()
    thesis_full = get_value(PARAMS, "reference_results.table53_full")
    thesis_red = get_value(PARAMS, "reference_results.table53_reduced")
    print(f"sub-model 1: {sm.M.shape[0]} DOF (Table 5.1: 101); reduced: {red.n_reduced} {red.names}")
    print(f"{'mode':>4} {'full':>9} {'reduced':>9} {'err %':>7} | {'thesis full':>11} {'thesis red':>10} "
          f"{'err %':>6} | {'gap full %':>10}")
    table = []
    for k in range(3):
        row = (f_full[k + 1], f_red[k + 1], 100 * (f_red[k + 1] / f_full[k + 1] - 1), thesis_full[k],
               thesis_red[k], 100 * (thesis_red[k] / thesis_full[k] - 1),
               100 * (f_full[k + 1] / thesis_full[k] - 1))
        table.append(row)
        print(f"{k + 1:>4} {row[0]:9.2f} {row[1]:9.2f} {row[2]:7.3f} | {row[3]:11.2f} {row[4]:10.2f} "
              f"{row[5]:6.3f} | {row[6]:10.2f}")

    # ---------------------------------------------------------------- error vs number of modes
    P_list = np.arange(0, 16)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    conv = {}
    for a, interface in zip(ax, ("free", "fixed")):
        errs = []
        for p in P_list:
            fr = cms_reduce(sm.M, sm.K, ["rotor.phi", anchor], int(p), interface=interface,
                            dof_names=sm.names).natural_frequencies()
            e = np.full(3, np.nan)
            k = min(3, fr.size - 1)
            e[:k] = 100 * np.abs(fr[1:k + 1] / f_full[1:k + 1] - 1)
            errs.append(e)
        errs = np.array(errs)
        conv[interface] = errs
        for j in range(3):
            a.semilogy(P_list, np.maximum(errs[:, j], 1e-6), "o-", label=f"mode {j + 1} ({f_full[j + 1]:.0f} Hz)")
        a.axhline(1.0, color="k", lw=0.8, ls="--")
        a.set_title(f"{interface}-interface modes")
        a.set_xlabel("kept elastic modes P")
        a.grid(True, which="both", alpha=0.3)
    ax[0].set_ylabel("|f_red / f_full - 1| [%] (floored at 1e-6)")
    ax[0].legend()
    fig.suptitle("Sub-model 1, exterior DOF: motor rotation + mid-screw θz (Sec 5.3.2)")
    fig.tight_layout()
    fig.savefig(out / "frequency_error_vs_modes.png", dpi=120)
    plt.close(fig)

    # ---------------------------------------------------------------- MD vs MA vs nut position
    z_L, z_R = get_value(PARAMS, "table.nut_position_L"), get_value(PARAMS, "table.nut_position_R")
    zs = np.linspace(z_L, z_R, 41)
    rec = {}
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for a, adof in zip(ax, ("tz", "w")):
        r_ = cms_reduce(sm.M, sm.K, ["rotor.phi", centre_anchor(sm, adof)], 3, dof_names=sm.names)
        errs = [static_recovery_errors(sm, r_, z) for z in zs]
        rec[adof] = errs
        for key, style in (("axial_MD", "C0-"), ("torsion_MD", "C1-"), ("axial_MA", "C0:"), ("torsion_MA", "C1:")):
            a.semilogy(zs, np.maximum([e[key] for e in errs], 1e-16), style, label=key.replace("_", " "))
        a.axvline(sm.beam.z_nodes[int(np.argmin(abs(sm.beam.z_nodes - sm.beam.z_nodes[-1] / 2)))],
                  color="k", lw=0.8, ls="--")
        a.set_title(f"anchor = mid-screw {adof}")
        a.set_xlabel("nut position x [m] (L ... R)")
        a.grid(True, which="both", alpha=0.3)
    ax[0].set_ylabel("relative error of static nut displacement")
    ax[0].legend(fontsize=8)
    fig.suptitle("MD vs MA recovery, static nut load, motor held (Eq 5.11 vs 5.18)")
    fig.tight_layout()
    fig.savefig(out / "md_vs_ma_vs_nut_position.png", dpi=120)
    plt.close(fig)

    # ---------------------------------------------------------------- moving nut, coupled first axial mode
    zc = np.linspace(z_L, z_R, 15)
    coupled = np.array([coupled_first_axial(sm, red, z) for z in zc])
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(zc, coupled[:, 0], "k-", lw=2, label="full (97 DOF)")
    ax.plot(zc, coupled[:, 1], "C0o", label="reduced (6) + MA port")
    ax.plot(zc, coupled[:, 2], "C3s", label="reduced (6) + MD")
    ax.plot([z_L, get_value(PARAMS, "table.nut_position_C"), z_R],
            get_value(PARAMS, "reference_results.table41_fn1"), "g^", ms=9, label="thesis Table 4.1")
    ax.set_xlabel("nut position x [m]")
    ax.set_ylabel("first axial mode [Hz]")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "coupled_axial_mode_vs_nut_position.png", dpi=120)
    plt.close(fig)
    for z, (ff, fa, fm) in zip(zc[[0, 7, 14]], coupled[[0, 7, 14]]):
        print(f"nut x = {z:.4f} m: coupled axial mode full {ff:.2f} Hz, MA {fa:.2f} Hz, MD {fm:.2f} Hz")

    return {"f_full": f_full, "f_red": f_red, "table53": table, "convergence": conv,
            "recovery": rec, "coupled": coupled, "z_coupled": zc}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir", nargs="?", default="model_reduction_out", help="folder for the figures")
    main(ap.parse_args().out_dir)
