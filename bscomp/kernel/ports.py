"""Connectors (ports): potential/flow pairs with SI units.

A port kind declares its potential and flow variables. ``connect(a, b)`` makes the potentials of a
connection set equal and the flows sum to zero; components never write that by hand.

===================  ===========================================  ==========================================
kind                 potentials                                   flows
===================  ===========================================  ==========================================
``Flange``           ``s`` [m]                                    ``f`` [N]
``RotFlange``        ``phi`` [rad]                                ``tau`` [N.m]
``Node6``            ``u v w`` [m], ``tx ty tz`` [rad]            ``Fx Fy Fz`` [N], ``Mx My Mz`` [N.m]
``Generalized``      ``q`` (modal/generalized coordinate)         ``Q`` (generalized force)
``RealInput``        ``u`` (causal signal, unit given per port)   --
``RealOutput``       ``y`` (causal signal, unit given per port)   --
===================  ===========================================  ==========================================

z is the screw axis, as in the thesis (Fig 3.5): ``w`` is the axial displacement, ``tz`` the rotation
about the screw axis. A flow is positive when it acts *on the component* through that port
(Modelica convention): a mass obeys ``m a = flange_a.f + flange_b.f``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["PortKind", "FLANGE", "ROT_FLANGE", "NODE6", "GENERALIZED", "REAL_INPUT", "REAL_OUTPUT", "PortSpec",
           "Flange", "RotFlange", "Node6", "Generalized", "RealInput", "RealOutput"]


@dataclass(frozen=True)
class PortKind:
    """A connector type: named potentials and flows with their SI units."""

    name: str
    potentials: tuple[tuple[str, str], ...]
    flows: tuple[tuple[str, str], ...]
    signal: str = ""  # "in" / "out" for causal signal ports, "" for physical ports

    @property
    def is_signal(self) -> bool:
        return bool(self.signal)


FLANGE = PortKind("Flange", (("s", "m"),), (("f", "N"),))
ROT_FLANGE = PortKind("RotFlange", (("phi", "rad"),), (("tau", "N.m"),))
NODE6 = PortKind(
    "Node6",
    (("u", "m"), ("v", "m"), ("w", "m"), ("tx", "rad"), ("ty", "rad"), ("tz", "rad")),
    (("Fx", "N"), ("Fy", "N"), ("Fz", "N"), ("Mx", "N.m"), ("My", "N.m"), ("Mz", "N.m")),
)
GENERALIZED = PortKind("Generalized", (("q", "1"),), (("Q", "1"),))
REAL_INPUT = PortKind("RealInput", (("u", ""),), (), signal="in")
REAL_OUTPUT = PortKind("RealOutput", (("y", ""),), (), signal="out")


@dataclass
class PortSpec:
    """Declaration of a port on a component class (a descriptor).

    Parameters
    ----------
    kind : PortKind
    doc : str
        One-line description.
    optional : bool
        Physical ports: if True an unconnected port is free (its flow is zero, Modelica's default);
        if False leaving it unconnected raises :class:`~bscomp.errors.UnconnectedPortError`.
        Signal inputs: unconnected inputs become inputs of the system (named ``component.port``)
        unless ``default`` is given, in which case they take that constant value.
    unit : str
        Unit of a signal port (``"N"``, ``"V"``, ``"rad/s"``...). Physical ports carry the units of
        their kind.
    default : float or None
        Constant value of an unconnected signal input.
    """

    kind: PortKind
    doc: str = ""
    optional: bool = False
    unit: str = ""
    default: float | None = None
    name: str = field(default="", init=False)

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        return obj._port_instance(self.name)

    def units(self):
        """Units of the potentials of this port (a signal port has its own unit)."""
        if self.kind.is_signal:
            return (self.unit,)
        return tuple(u for _, u in self.kind.potentials)


def Flange(doc: str = "", optional: bool = False) -> PortSpec:
    """Translational flange: position ``s`` [m], force ``f`` [N]."""
    return PortSpec(FLANGE, doc, optional)


def RotFlange(doc: str = "", optional: bool = False) -> PortSpec:
    """Rotational flange: angle ``phi`` [rad], torque ``tau`` [N.m]."""
    return PortSpec(ROT_FLANGE, doc, optional)


def Node6(doc: str = "", optional: bool = True) -> PortSpec:
    """6-DOF node: ``d = (u, v, w, tx, ty, tz)``, ``F = (Fx, Fy, Fz, Mx, My, Mz)``; z is the screw axis."""
    return PortSpec(NODE6, doc, optional)


def Generalized(doc: str = "", optional: bool = True) -> PortSpec:
    """Generalized (e.g. modal) coordinate ``q`` with generalized force ``Q``; units follow the model."""
    return PortSpec(GENERALIZED, doc, optional)


def RealInput(doc: str = "", unit: str = "", default: float | None = None) -> PortSpec:
    """Causal real signal input (``u``)."""
    return PortSpec(REAL_INPUT, doc, True, unit, default)


def RealOutput(doc: str = "", unit: str = "") -> PortSpec:
    """Causal real signal output (``y``)."""
    return PortSpec(REAL_OUTPUT, doc, True, unit)
