"""A small ballscrew drive for the demo and tests: motor rotor, coupling, screw inertia, ideal lead
screw, nut-table axial compliance and the table.

Values are the thesis test bed's lumped quantities (Table 3.1, Sec 4.2.1, Appendix B), used only to
give realistic numbers; the FE test bed lives in ``systems/testbed.py``:

- rotor inertia J_r = 5.98e-3 kg m^2 (Table 3.1), coupling k_T = 3938 N m/rad (Sec B.4),
- screw polar inertia 1.197e-3 kg m^2 (Table B.1 sections, steel 7800 kg/m^3), lead 10 mm (Table 3.1),
- table mass 250 kg (Table 3.1), axial stiffness of screw + nut + bearings lumped to 1.0e8 N/m
  (order of the series stiffness of Table 3.1's nut 1.70e9 N/m, bearing 2.70e8 N/m and screw EA/L; a
  demo value, not a thesis number), guideway viscous damping 12 673 N s/m (Table 5.2).
"""

from bscomp import System
from bscomp.components import (
    Damper,
    Fixed,
    IdealLeadScrew,
    Inertia,
    Mass,
    Spring,
    Torque,
    TorsionalDamper,
    TorsionalSpring,
)


def small_drive(k_axial: float = 1.0e8, k_T: float = 3938.0) -> System:
    """Rotor -- coupling -- screw -- lead screw -- axial spring -- table, torque input ``motor.tau``."""
    s = System("small_drive")
    s.description = "4-DOF lumped drive: rotor, coupling, screw, axial compliance, table"
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=5.98e-3 + 3.09e-4))
    s.add("coupling", TorsionalSpring(c=k_T))
    s.add("coupling_loss", TorsionalDamper(d=0.05))
    s.add("screw", Inertia(J=1.197e-3 + 3.06e-4))
    s.add("lead", IdealLeadScrew(lead=0.010))
    s.add("axial", Spring(c=k_axial))
    s.add("axial_loss", Damper(d=2.0e4))
    s.add("table", Mass(m=250.0))
    s.add("ground", Fixed())
    s.add("guide", Damper(d=12673.0))
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("rotor.flange_b", "coupling.flange_a")
    s.connect("coupling.flange_b", "screw.flange_a")
    s.connect("coupling_loss.flange_a", "rotor.flange_b")
    s.connect("coupling_loss.flange_b", "screw.flange_a")
    s.connect("screw.flange_b", "lead.flange_a")
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial.flange_b", "table.flange_a")
    s.connect("axial_loss.flange_a", "lead.flange_b")
    s.connect("axial_loss.flange_b", "table.flange_a")
    s.connect("table.flange_b", "guide.flange_a")
    s.connect("guide.flange_b", "ground.flange")
    s.sources = {"rotor.J": "Table 3.1 + Sec B.4 (J1)", "coupling.c": "Sec B.4", "table.m": "Table 3.1",
                 "lead.lead": "Table 3.1", "guide.d": "Table 5.2", "axial.c": "demo value (see docstring)"}
    return s
