"""A drive's validation interface: what users measure, what is uncertain, where effects may be missing.

A system declares it once (``system.validation = ValidationInterface(...)``, usually in its build function
in ``systems/``); :func:`bscomp.validate.compare`, :func:`bscomp.validate.diagnose` and the candidate
effects read it instead of guessing component names.

* ``inputs`` / ``outputs``: the channels a user measures (amplifier voltage in; motor angle and speed,
  table position and acceleration out), by dotted name.
* ``uncertain``: parameters that are estimates rather than measurements, each with a relative spread
  (re-calibration bounds ``v0 / (1 + spread)`` .. ``v0 (1 + spread)``) and the source of the estimate.
* ``points``: **insertion points by role** (:data:`ROLES`). A candidate effect asks for its role; a
  role the drive does not declare makes the candidate *not applicable* (listed as skipped, with the
  reason), never an error and never silence.

Kinds of insertion point
------------------------
``connection``
    ``ports = (a, b)``: a translational (or signal) connection the effect cuts and bridges (a joint in
    series, a delay in a signal line).
``attach``
    ``ports = (node,)``: a translational flange the effect attaches to (a sub-assembly on a spring, a
    friction force to ground, an added mass).
``rotational``
    ``ports = (flange,)``: a rotational flange (an added inertia).
``support``
    ``ports = (screw_port, bearing)``: a screw support whose grounded bearing becomes a housing mass on a
    fastener spring (axial DOF of the bearing node).
``parameter``
    ``parameters = (name, ...)``: the effect re-scales or scans these parameters (coupling stiffness).
``joint``
    ``ports = (a, b)`` between which the screw--nut axial clearance acts, ``parameters`` naming the
    axial stiffness of the joint (a dead zone in contact with that stiffness).
``all``
    the whole structure (extra damping of every mode); ``frequency`` [Hz] names the reference mode
    ``f_1`` a stiffness-proportional effect is stated at (the first elastic mode of the nominal drive).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from bscomp.errors import BscompError, UnknownNameError

__all__ = ["ValidationInterface", "InsertionPoint", "UncertainParameter", "NotApplicable", "ROLES"]

#: role -> what it is (the places thesis Sec 3.5.2.3-3.5.2.4 blames for the mismatch with measurements)
ROLES = {
    "screw_nut": "the screw--nut joint (axial clearance, backlash)",
    "nut_table": "the bolted joint between nut and table (table-side compliance)",
    "table_guide": "the table on its guideways (friction, guideway compliance)",
    "screw_support": "the screw's thrust support (bearing housing on its fasteners)",
    "coupling": "the motor--screw coupling (stiffness)",
    "amplifier": "the signal line from the D/A converter and amplifier to the motor torque (delay)",
    "rotor": "the motor rotor (missing inertia)",
    "table": "the table (missing mass)",
    "structure": "the whole structure (extra modal damping)",
}


class NotApplicable(BscompError):
    """A candidate effect has no insertion point of its role in this drive (reported as skipped)."""


@dataclass(frozen=True)
class InsertionPoint:
    """Where an effect of one role goes (see the module docstring for the kinds)."""

    role: str
    kind: str
    ports: tuple = ()
    parameters: tuple = ()
    ground: str | None = None
    doc: str = ""
    frequency: float | None = None

    def __post_init__(self):
        if self.role not in ROLES:
            raise UnknownNameError(f"insertion point role {self.role!r} is not one of {sorted(ROLES)}")
        kinds = ("connection", "attach", "rotational", "support", "parameter", "joint", "all")
        if self.kind not in kinds:
            raise UnknownNameError(f"insertion point {self.role!r}: kind {self.kind!r} is not one of {kinds}")


@dataclass(frozen=True)
class UncertainParameter:
    """A parameter re-calibrated before diagnosis: relative ``spread`` and the ``source`` of its value."""

    name: str
    spread: float = 0.2
    source: str = ""

    def bounds(self, v0: float) -> tuple:
        f = 1.0 + float(self.spread)
        return (v0 / f, v0 * f)


@dataclass
class ValidationInterface:
    """Inputs, outputs, uncertain parameters and insertion points of a drive (module docstring).

    Parameters
    ----------
    inputs, outputs : list of str
        Measured channels by dotted name (``"amp.u"``, ``"table.a"``).
    uncertain : list of UncertainParameter (or (name, spread, source) tuples, or names)
    points : list or dict of InsertionPoint
    ground : str, optional
        A fixed translational flange effects may attach to (friction to ground); candidates add their own
        :class:`~components.fixed.Fixed` when absent.
    notes : str
        Conventions (signs, units) in words, shown in reports.
    """

    inputs: list
    outputs: list
    uncertain: list = field(default_factory=list)
    points: dict = field(default_factory=dict)
    ground: str | None = None
    notes: str = ""

    def __post_init__(self):
        self.inputs, self.outputs = list(self.inputs), list(self.outputs)
        unc = []
        for u in self.uncertain:
            if isinstance(u, UncertainParameter):
                unc.append(u)
            elif isinstance(u, str):
                unc.append(UncertainParameter(u))
            else:
                unc.append(UncertainParameter(*u))
        self.uncertain = unc
        pts = self.points.values() if isinstance(self.points, dict) else self.points
        self.points = {p.role: p for p in pts}

    def point(self, role: str) -> InsertionPoint:
        """The insertion point of ``role``, or :class:`NotApplicable` naming what the drive declares."""
        if role not in self.points:
            raise NotApplicable(f"the drive declares no '{role}' insertion point ({ROLES.get(role, role)}); "
                                f"it declares {sorted(self.points)}")
        return self.points[role]

    def spreads(self) -> dict:
        """``{name: spread}`` of the uncertain parameters."""
        return {u.name: u.spread for u in self.uncertain}

    def describe(self) -> str:
        lines = [f"inputs: {', '.join(self.inputs)}", f"outputs: {', '.join(self.outputs)}",
                 "uncertain: " + (", ".join(f"{u.name} +-{100 * u.spread:.0f} % ({u.source})" if u.source else
                                           f"{u.name} +-{100 * u.spread:.0f} %" for u in self.uncertain) or "none"),
                 "insertion points:"]
        for p in self.points.values():
            where = ", ".join(p.ports or p.parameters)
            lines.append(f"  {p.role:<14} {p.kind:<10} {where}" + (f"  ({p.doc})" if p.doc else ""))
        if self.notes:
            lines.append(f"conventions: {self.notes}")
        return "\n".join(lines)


def interface_of(system) -> ValidationInterface | None:
    """The system's declared :class:`ValidationInterface` (``system.validation``), or None."""
    return getattr(system, "validation", None)
