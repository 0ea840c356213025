"""Local viscous losses the model lacks: a dashpot at the screw's thrust support, one across the coupling.

The thesis damps its test bed modally (Tables 4.1/4.2: 6 % on the axial screw-nut mode, 10 % on the coupling's
torsion, 6 % assumed for the rest; Eq A.10-A.15). A real drive loses energy at places -- the preloaded angular-contact
pair, the coupling's elastomer insert -- and a loss at a place damps every mode by how much that place moves in it,
so the higher axial modes in which the bearing works are damped far more than the first. :class:`ExtraDamping` adds
one ratio to every mode and cannot follow that (docs/validation.md, "The damping truth"); these two candidates put
the loss where it is:

``support_damping``
    role ``screw_support``, kind ``support`` (the FE drive's grounded thrust bearing): the bearing's axial viscous
    damping ``c`` [N s/m] (its ``c_axial``, between the screw node and the frame). Prior median 1e4 N s/m -- about
    1 % of critical on the test bed's first axial mode (~120 Hz, a 3e8 N/m bearing) -- bounds 1e2-1e6.
``coupling_damping``
    role ``coupling``, kind ``parameter``: the coupling component's torsional viscous damping ``d`` [N m s/rad]
    (its ``d``, across the insert; applicable where the component named by the point's parameter has one).
    Prior median 0.05 N m s/rad -- about 1 % of critical on the test bed's coupling mode (k_T 3938 N m/rad,
    ~270 Hz) -- bounds 1e-4-10.

Both act on the model's existing components (no new coordinate), so the drive's modal damping is unchanged.
"""

from __future__ import annotations

from bscomp.components._joint6 import PartialJoint6
from bscomp.errors import UnknownNameError
from bscomp.kernel.interface import NotApplicable
from bscomp.validate.candidates.base import Candidate, CandidateParameter

__all__ = ["SupportDamping", "CouplingDamping"]


class _AddedDashpot(Candidate):
    """A dashpot added to an existing component's damping parameter: ``_edit`` returns that parameter and its own
    value (``{"parameter", "base"}``); the one free parameter is added to it."""

    def _overrides(self, values, state):
        return {state["parameter"]: state["base"] + values[self.parameters[0].name]}


class SupportDamping(_AddedDashpot):
    """Axial viscous loss at the screw's thrust support (module docstring)."""

    def __init__(self):
        super().__init__(
            name="support_damping", title="axial damping at the thrust bearing", role="screw_support",
            parameters=[CandidateParameter("c", "N.s/m", 1e2, 1e6, 1e4, 1.5, "axial viscous damping of the bearing")],
            signature="the axial modes damped more than modelled, the higher ones (where the bearing moves) most; "
                      "their frequencies unchanged",
            group="support_damping", kinds=("support",))

    def _edit(self, e, point, vi, for_engine):
        bearing = point.ports[1]
        comp = e.s.component(bearing)
        if not isinstance(comp, PartialJoint6) or not comp.grounded or "c_axial" not in comp.parameters():
            raise NotApplicable(f"{self.name}: the 'screw_support' point names '{bearing}', which is not a grounded "
                                f"6-DOF bearing with an axial damping 'c_axial' ({type(comp).__name__})")
        return {"parameter": f"{bearing}.c_axial", "base": float(e.s.get(f"{bearing}.c_axial"))}


class CouplingDamping(_AddedDashpot):
    """Torsional viscous loss across the coupling's insert (module docstring)."""

    def __init__(self):
        super().__init__(
            name="coupling_damping", title="torsional damping in the coupling", role="coupling",
            parameters=[CandidateParameter("d", "N.m.s/rad", 1e-4, 10.0, 0.05, 1.5,
                                           "torsional viscous damping across the coupling")],
            signature="the coupling (torsion) mode damped more than modelled at an unchanged frequency; the "
                      "motor-speed FRF shows it most",
            group="coupling_damping", kinds=("parameter",))

    def _edit(self, e, point, vi, for_engine):
        comp = point.parameters[0].rsplit(".", 1)[0]
        try:
            base = float(e.s.get(f"{comp}.d"))
        except UnknownNameError:
            raise NotApplicable(f"{self.name}: the coupling '{comp}' has no torsional damping parameter 'd' "
                                "(a coupling.Coupling has one)") from None
        return {"parameter": f"{comp}.d", "base": base}
