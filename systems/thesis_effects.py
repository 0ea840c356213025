"""The test bed's Ch 5 nonlinear effects (thesis Sec 5.2.2, Table 5.2): guideway friction and screw-nut backlash,
added to a test bed System.

* **Friction** (Eq 5.7, Table 5.2: F_coul = +-2066 N): :class:`~components.coulomb_friction.CoulombFriction`
  between the table and the ground, regularised with ``v_reg`` (default 1e-4 m/s, CHOICE: docs/nonlinear.md,
  "Recommendation for v_reg"). The viscous B of Table 5.2 is *not* added: the test bed already carries it as
  the motor-side B = 0.0321 kg m^2/s (Sec 4.2.1; the same damping seen from the table, THESIS-NOTES).
* **Backlash** (Eq 5.8-5.9, Table 5.2: L = 0.001885 rad on the joint's torsional DOF = L r_g = 3.0 um at the
  table): :class:`~components.backlash.Backlash` between the nut-table joint and the table, closing onto a
  contact of ``contact_stiffness`` (default 1.7e10 N/m, CHOICE: ten times the screw-nut axial stiffness
  k_axial = 1.70e9 N/m of Sec B.6, so the contact is stiff against the interface it is in series with; the
  thesis's dead zone is rigid).

These are the models of ``examples/nonlinear_scenarios.py``, the issue-16 benchmark
(``benchmarks/moving_cases.py``), the CMS-reduced comparisons and the FMU friction checks: one definition.
"""

from __future__ import annotations

import math

from bscomp.components import Backlash, CoulombFriction, Fixed
from bscomp.errors import ModelDefinitionError
from bscomp.kernel.system import System

from .parameters import load_parameters

__all__ = ["with_friction_backlash", "V_REG", "CONTACT_STIFFNESS"]

#: Regularisation velocity of the guideway friction [m/s] (CHOICE, docs/nonlinear.md)
V_REG = 1e-4
#: Contact stiffness of the closed clearance [N/m] (CHOICE: 10 x k_axial of the screw-nut interface, Sec B.6)
CONTACT_STIFFNESS = 1.7e10


def with_friction_backlash(s: System, friction: bool = True, backlash: bool = True, *, v_reg: float = V_REG,
                           contact_stiffness: float = CONTACT_STIFFNESS, params: str = "fadal_vmc2216_x") -> System:
    """Add Table 5.2 guideway friction (component ``friction``) and screw-nut backlash (``backlash``) to a drive
    variant of the test bed (it needs ``table`` and ``table_joint``); returns ``s`` (changed in place)."""
    names = {path.split(".")[0] for path, _ in s.leaves()}
    need = {"table"} | ({"table_joint"} if backlash else set())
    if need - names or (friction and "friction" in names) or (backlash and "backlash" in names):
        raise ModelDefinitionError(
            f"with_friction_backlash: '{s.name}' needs the test bed's {sorted(need)} (a drive variant of "
            f"bscomp.systems.testbed) and no 'friction' / 'backlash' yet; it has {sorted(names)[:12]}...")
    p = load_parameters(params)["friction_backlash"]
    if friction:
        s.add("guide_ground", Fixed())
        s.add("friction", CoulombFriction(F_c_pos=p["F_coul_pos"]["value"], F_c_neg=abs(p["F_coul_neg"]["value"]),
                                          v_reg=v_reg))
        s.connect("friction.flange_a", "guide_ground.flange")
        s.connect("friction.flange_b", "table.flange_b")
    if backlash:
        lead = load_parameters(params)["screw"]["lead"]["value"]
        s.insert("backlash", Backlash(b=p["backlash_L"]["value"] * lead / (2 * math.pi), c=contact_stiffness),
                 between=("table_joint.flange", "table.flange_a"))
    return s
