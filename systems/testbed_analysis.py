"""Reproduction quantities of the test bed (thesis Sec 3.5.2, Tables 3.2/3.3, 4.1/4.2, 5.3, Eq 4.2).

Small functions over :func:`bscomp.linear.modal.modes` that pick the modes the thesis tabulates by their
*character* (share of kinetic energy in the axial ``w``, torsional ``tz``/``phi`` or bending fields),
not by index: in the 6-DOF model, screw bending modes interleave with the drive modes.
"""

from __future__ import annotations

import numpy as np

from bscomp import second_order
from bscomp.linear.modal import modes

from .testbed import testbed

__all__ = ["field_fractions", "drive_parameters", "free_free_modes", "submodel1_frequencies",
           "DRIVE_INPUTS", "DRIVE_OUTPUTS"]

#: Inputs and outputs of Fig 4.1 / 4.2: motor torque tau and table disturbance F_d; motor angle (its
#: rate is omega) and table position x. ``motor.tau`` is an input of a drive built with
#: ``drive_input="torque"``; the default build's input is the amplifier voltage ``amp.u`` (tau = K_a K_t u).
DRIVE_INPUTS = ["motor.tau", "Fd.f"]
DRIVE_OUTPUTS = ["rotor.phi", "table.s"]


def field_fractions(md, M) -> dict:
    """Kinetic-energy share of every mode per coordinate field: ``{"w": (m,), "tz": ..., "bending": ...}``.

    ``tz`` includes the rotor/jaw angles (``phi``), ``w`` the table position (``s``).
    """
    M = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
    field = np.array([c.rsplit(".", 1)[-1] for c in md.coordinates])
    groups = {"w": np.isin(field, ("w", "s")), "tz": np.isin(field, ("tz", "phi"))}
    groups["bending"] = ~(groups["w"] | groups["tz"])
    X = md.shapes
    total = np.einsum("ik,ij,jk->k", X, M, X)
    total = np.where(total > 0, total, 1.0)
    out = {}
    for name, sel in groups.items():
        Ms = np.where(np.outer(sel, sel), M, 0.0)
        out[name] = np.einsum("ik,ij,jk->k", X, Ms, X) / total
    return out


def drive_parameters(system=None, **build) -> dict:
    """J at the motor (Eq 4.2) and the modal parameters of Table 4.1/4.2 for one build of the drive.

    Parameters
    ----------
    system : bscomp.System, optional
        A drive variant of :func:`~bscomp.systems.testbed.testbed`; else built from ``build``
        (keyword arguments of ``testbed``, default the full model with the torque input). A system with the
        amplifier-voltage input ``amp.u`` is analysed from ``amp.u`` and its residues divided by
        K_a K_t, so the numbers are per N m of motor torque either way (Table 4.1).

    Returns
    -------
    dict
        ``J`` [kg m^2] (rigid-body modal mass at the motor angle), ``B`` [kg m^2/s], ``f1``, ``f2`` [Hz],
        ``zeta1``, ``zeta2``, residues ``Rw1``, ``Rw2`` (tau -> motor angle, Eq 4.5 with s),
        ``Rm1``, ``Rm2`` (tau -> table x, Eq 4.7), ``Rd1``, ``Rd2`` (F_d -> motor angle, Eq 4.6), all in
        the thesis's sign convention, which the test bed's table axis follows (table advancing for a
        positive motor angle, F_d positive along the table axis), ``r_g`` (table advance per motor
        radian of the rigid-body mode, > 0) and ``modes`` (the :class:`~bscomp.linear.modal.Modes`).
    """
    if system is None:
        build.setdefault("variant", "full")
        build.setdefault("drive_input", "torque")
        system = testbed(**build)
    tau, gain = _torque_input(system)
    so = second_order(system, inputs=[tau, DRIVE_INPUTS[1]], outputs=DRIVE_OUTPUTS)
    md = modes(so, damping="projection")
    frac = field_fractions(md, so.M)
    el = np.flatnonzero(~md.rigid_body)
    drive = [k for k in el if frac["bending"][k] < 0.5][:2]
    r = int(np.flatnonzero(md.rigid_body)[0])
    R = md.residues.copy()
    R[:, :, 0] /= gain                  # per N m of torque (amp.u input: tau = K_a K_t u)
    out = {"J": md.reflected_inertia("rotor.phi"), "B": md.reflected_damping("rotor.phi"), "modes": md,
           "r_g": R[r, 1, 0] / R[r, 0, 0]}
    for i, k in enumerate(drive, start=1):
        out[f"f{i}"] = float(md.frequencies[k])
        out[f"zeta{i}"] = float(md.damping[k])
        out[f"Rw{i}"] = float(R[k, 0, 0])
        out[f"Rm{i}"] = float(R[k, 1, 0])
        out[f"Rd{i}"] = float(R[k, 0, 1])
        out[f"mode{i}"] = int(k)
    return out


def _torque_input(system) -> tuple:
    """(input name, input -> torque gain): ``("motor.tau", 1)`` or ``("amp.u", K_a K_t)``."""
    names = {p for p, _ in system.leaves()}
    if "amp" in names and "kt" in names:
        return "amp.u", float(system.get("amp.K_a")) * float(system.get("kt.k"))
    return DRIVE_INPUTS[0], 1.0


def free_free_modes(nut_position="2", **build) -> dict:
    """First axial and first torsional elastic mode [Hz] of the free-free screw + nut (Tables 3.2/3.3).

    ``nut_position=None`` gives the free-free screw alone (Sec 3.5.2.1).
    """
    if nut_position is None:
        system = testbed("free_screw", **build)
    else:
        system = testbed("screw_nut", nut_position=nut_position, **build)
    so = second_order(system, inputs=[], outputs=[])
    md = modes(so, damping="projection")
    frac = field_fractions(md, so.M)
    el = ~md.rigid_body
    ax = np.flatnonzero(el & (frac["w"] > 0.5))
    tor = np.flatnonzero(el & (frac["tz"] > 0.5))
    return {"axial": float(md.frequencies[ax[0]]), "torsional": float(md.frequencies[tor[0]]),
            "n_rigid": int(md.rigid_body.sum()), "modes": md}


def submodel1_frequencies(n: int = 3, **build) -> np.ndarray:
    """The first ``n`` elastic frequencies [Hz] of sub-model 1 (Table 5.3, full sub-model)."""
    so = second_order(testbed("submodel1", damping=False, **build), inputs=[], outputs=[])
    md = modes(so, damping="projection")
    return md.frequencies[~md.rigid_body][:n]
