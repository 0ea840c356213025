"""The thesis's CMS-reduced test bed (Sec 5.2.3, 5.3.2): sub-model 1 as a superelement, the moving nut on it
through Modal-Acceleration recovery.

Sub-model 1 of Table 5.1 (screw, thrust and floating bearings, coupling, rotor: 97 axial + torsional DOF
here, 101 in the thesis) is reduced by CMS (Eq 5.10-5.14) to ``E + P + 1`` coordinates: the exterior DOF
are the motor rotation (the torque acts there) and the torsion of the screw node nearest mid-length (the
"anchor", Sec 5.3.2), plus ``P`` free-interface normal modes and the rigid-body mode (default ``P = 3``:
6 coordinates, Table 5.3). The superelement (:class:`~components.reduced_substructure.ReducedSubstructure`)
keeps every screw node as a port whose displacement is MA-recovered (Eq 5.18), so the moving screw-nut
joint of Sec 5.2.2.3 (:class:`~components.moving_screw_nut.MovingScrewNut`) attaches to it as to the FE
screw and the nut can travel along it without re-reducing (Sec 5.2.3.3: "components like the ballscrew
can be reduced with fixed exterior DOF, and then the static effects of the reaction forces and inertial
loads can be added on by using the MA recovery").

Everything outside sub-model 1 is the full model's own parts (nut, table, amplifier, motor damping,
and whatever friction, backlash or controllers the full system carries): :func:`reduce_testbed` takes a full
axial + torsional test bed *System* and returns its reduced twin. Damping: the full system's option (modal
ratios of Tables 4.1/4.2), which the kernel applies to the reduced drive's own modes at flattening and every
linear analysis re-derives at its operating point, as for the full model (the MA-coupled pair is not
symmetric: :func:`bscomp.kernel.damping.nonsymmetric_damping`). The thesis's ``C_red = Ψ^T C_model Ψ`` was tried
and not kept: ``C_model`` weights its highest modes by their frequency and the mode-displacement shapes
``Ψ x`` overlap them, which put 42 % damping on a 2.2 kHz mode.

The rotor stays a component of its own (outputs ``rotor.phi``, ``rotor.w`` keep their names): it is part
of sub-model 1 for the reduction (its inertia shapes the free-interface modes) and its inertia, an exterior
DOF's, is taken out of the superelement's mass again (``Ψ`` is the identity on exterior rows, so that is
exact).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.components import ReducedSubstructure
from bscomp.errors import ModelDefinitionError, UsageError
from bscomp.kernel.flattening import flatten
from bscomp.kernel.system import System
from bscomp.linear.linearization import second_order
from bscomp.linear.reduction import ReducedModel, cms_reduce

from .testbed import testbed

__all__ = ["reduce_testbed", "testbed_reduced", "SUBMODEL1", "submodel1_matrices"]

#: Components of sub-model 1 (Table 5.1) that the superelement replaces; the rotor is kept (see module docstring).
SUBMODEL1 = ("screw", "b1", "b2", "coupling", "screw_end")
_BUILD_KEYS = ("coupling", "motor_end", "b1_position", "b2_position", "coupling_position", "root_diameter", "jaw1",
               "params", "n_elements")


def submodel1_matrices(full: System):
    """``(M, K, dof names, sub-model System, its Dae)`` of sub-model 1 with the full system's build choices."""
    args = getattr(full, "build_args", None) or {}
    if args.get("variant") != "axial_torsional":
        raise ModelDefinitionError("reduce_testbed: needs an axial + torsional test bed (testbed('axial_torsional', "
                                   "nut_joint='moving') or a System built from it), got variant "
                                   f"{args.get('variant')!r}")
    sm1 = testbed("submodel1", damping=False, **{k: args[k] for k in _BUILD_KEYS if args.get(k) is not None})
    dae = flatten(sm1)
    so = second_order(dae)
    return so.M.toarray(), so.K.toarray(), list(so.coordinates), sm1, dae


def anchor_dof(sm1: System, anchor="centre") -> str:
    """Name of the anchor DOF: ``"centre"`` = θz of the screw node nearest mid-length (Sec 5.3.2), else a name."""
    if anchor != "centre":
        return str(anchor)
    z = sm1.component("screw").beam_model().z_nodes
    return f"screw.n{int(np.argmin(np.abs(z - z[-1] / 2)))}.tz"


def _check_exterior(ext, names, argument):
    """Each exterior DOF is a coordinate of sub-model 1: else UsageError naming ``argument`` (the closest names)."""
    import difflib

    for name in ext:
        if name not in names:
            close = difflib.get_close_matches(str(name), names, n=3) or names[:3]
            what = "'centre' nor " if argument == "anchor" else ""
            raise UsageError(f"reduce_testbed: {argument} {name!r} is neither {what}a DOF of sub-model 1 "
                             f"(closest: {close}; names are 'component.n<node>.<dof>', e.g. 'screw.n12.tz')")


def reduce_testbed(full: System, n_modes: int = 3, *, anchor="centre", interface: str = "free",
                   exterior=None) -> tuple[System, ReducedModel]:
    """The CMS-reduced twin of a full axial + torsional test bed with the moving nut (Sec 5.2.3).

    Parameters
    ----------
    full : System
        ``testbed("axial_torsional", nut_joint="moving", ...)``, possibly with friction, backlash, sensors or
        controllers added; its sub-model 1 (:data:`SUBMODEL1` + the rotor) is reduced, the rest kept.
    n_modes : int
        Free-interface normal modes ``P`` kept (Eq 5.12; the thesis: 3).
    anchor : str
        Second exterior DOF: ``"centre"`` (θz of the mid-length node, Sec 5.3.2) or a DOF name.
    interface : {"free", "fixed"}
        Normal modes of the free structure (the thesis's choice) or Craig-Bampton fixed-interface modes.
    exterior : sequence of str, optional
        All exterior DOF names instead of ``("rotor.phi", anchor)``.

    Returns
    -------
    (System, ReducedModel)
        The reduced system (same inputs, outputs and validation interface) and the reduction (frequencies,
        ``Ψ``, recovery matrices).
    """
    if not any(hasattr(c, "moving_interface") for _, c in full.leaves()):
        raise ModelDefinitionError("reduce_testbed: the full system needs the moving screw-nut joint 'sn' "
                                   "(testbed(..., nut_joint='moving')): a point joint is baked into the screw")
    M1, K1, names, sm1, sub_dae = submodel1_matrices(full)
    ext = list(exterior) if exterior is not None else ["rotor.phi", anchor_dof(sm1, anchor)]
    _check_exterior(ext, names, "exterior" if exterior is not None else "anchor")
    red = cms_reduce(M1, K1, ext, n_modes, interface=interface, dof_names=names)
    M_r = red.M.copy()
    if "rotor.phi" in red.names:                               # the kept rotor adds its inertia back
        k = red.names.index("rotor.phi")
        M_r[k, k] -= float(full.component("rotor").J)
    se = ReducedSubstructure.from_reduction(red, M1, K1, names, beam=sm1.component("screw").beam_model(), M_r=M_r)
    s = full.copy()
    s.name = full.name + "_reduced"
    s.description = (f"{getattr(full, 'description', full.name)}; sub-model 1 CMS-reduced to {red.n_reduced} "
                     f"coordinates {red.names} (Sec 5.2.3, MA recovery)")
    boundary = [(a, b) for a, b in full.connections()
                if (a.split(".")[0] in SUBMODEL1) != (b.split(".")[0] in SUBMODEL1)]
    for name in SUBMODEL1:
        s.remove(name)
    s.add("sm1", se)
    sub_ports = sub_dae.mech
    for a, b in boundary:
        inner, outer = (a, b) if a.split(".")[0] in SUBMODEL1 else (b, a)
        s.connect(_superelement_port(se, sub_ports, inner), outer)
    s.damping = getattr(full, "damping", None)        # the kernel applies it to the reduced drive's own modes
    s.sources = dict(getattr(full, "sources", {}) or {})
    s.sources["sm1"] = (f"Sec 5.2.3 / Eq 5.10-5.18: CMS of sub-model 1 (Table 5.1), exterior {ext}, {n_modes} "
                        f"{interface}-interface modes; MA-recovered node ports")
    s.build_args = dict(getattr(full, "build_args", {}) or {}, reduced=dict(n_modes=n_modes, exterior=ext,
                                                                            interface=interface))
    return s, red


def _superelement_port(se, sub_mech, port: str) -> str:
    """The superelement port standing for a sub-model-1 port (by the coordinate its potentials are)."""
    T = sp.csr_matrix(sub_mech.T)
    hits = set()
    for key, row in sub_mech.port_coordinates.items():
        if key.rsplit(".", 1)[0] != port:
            continue
        r = T.getrow(row)
        if r.nnz == 1 and np.isclose(r.data[0], 1.0):          # the potential is one reduced coordinate
            coord = sub_mech.coordinate_names[r.indices[0]]
            hits.add(coord.rsplit(".", 1)[0].replace(".", "_"))
    hits &= set(se.ports())
    if len(hits) != 1:
        raise ModelDefinitionError(f"reduce_testbed: cannot map port '{port}' of sub-model 1 to one superelement "
                                   f"port (candidates {sorted(hits)})")
    return f"sm1.{hits.pop()}"


def testbed_reduced(n_modes: int = 3, anchor="centre", interface: str = "free", **testbed_args) -> System:
    """CMS-reduced axial + torsional test bed with the moving nut (Sec 5.2.3/5.3.2: 6 + 2 coordinates)."""
    testbed_args.setdefault("nut_joint", "moving")
    s, _ = reduce_testbed(testbed("axial_torsional", **testbed_args), n_modes, anchor=anchor, interface=interface)
    return s
