"""The nominal drive of the validation story: a lumped axial + torsional model of the thesis test bed.

Amplifier voltage in; motor angle and speed, table position and table acceleration out. Three
coordinates (rotor angle, screw angle, table position) so that candidate fits run in milliseconds:

::

    amp.u [V] -> amp (K_a) -> kt (K_t) -> motor torque
    rotor --coupling (k_T, d_T)-- screw --lead (r_g)-- axial (k_ax, d_ax) -- nut == table --guide (B)-- ground

The nut is rigidly bolted to the table in the nominal model (the thesis's assumption, Sec 3.5.2.4),
the guideways are rigid and frictionless apart from their viscous coefficient, there is no backlash and
the amplifier is a pure gain (current mode, Eq 4.1). Those are the assumptions Sec 3.5.2.4 blames for
the mismatch with the measured FRFs, and the places where :mod:`bscomp.validate.candidates` inserts
the missing effects.

Values (``systems/data/fadal_vmc2216_x.toml``, thesis sections cited there):

- rotor J_r = 5.98e-3 kg m^2 plus the motor-side jaw J1 = 3.09e-4 (Table 3.1, Sec B.4);
- coupling k_T = 3938 N m/rad (Sec B.4, Eq B.1), loss d_T chosen to give the second mode about 10 %
  damping (Table 4.1 zeta_2);
- screw polar inertia of the Table B.1 sections (steel 7800 kg/m^3, threaded section at d_e) plus the
  screw-side jaw J2 = 3.06e-4 (Table 3.1); lead 10 mm (Table 3.1);
- axial stiffness of screw + bearings + nut lumped to k_ax = 1.357e8 N/m so that the first (axial) mode
  sits at the C-position 117.7 Hz of Table 4.1; d_ax gives it about 6 % (Table 4.1 zeta_1). This is a
  lumped value tuned to Table 4.1, not a thesis number;
- nut 1.49 kg, table 250 kg (Table 3.1), guideway viscous coefficient B = 12 673 N s/m (Table 5.2);
- amplifier K_a = 6.4898 A/V and torque constant K_t = 0.4769 N m/A (Eq 4.1).

Validation interface
--------------------
``validation_drive().validation`` is a :class:`bscomp.kernel.interface.ValidationInterface` (:data:`INTERFACE`
lists the same declarations): input ``amp.u``, outputs :data:`OUTPUTS`, the uncertain parameters and the
insertion points by role.

=================  ==========  =========================================  ===========================================
role               kind        ports / parameters                         candidate effects
=================  ==========  =========================================  ===========================================
``nut_table``      connection  ``nut.flange_b`` -- ``table.flange_a``     bolted-joint compliance (spring + damper)
``table_guide``    attach      ``table.flange_b`` (ground ``ground``)     guideway compliance, guideway friction
``screw_support``  connection  ``lead.flange_b`` -- ``axial.flange_a``    bearing housing (mass + compliance)
``screw_nut``      joint       components ``axial``, ``axial_loss``       backlash with their stiffness and damping
``amplifier``      connection  ``amp.i`` -- ``kt.u``                      D/A + amplifier time delay (Pade)
``coupling``       parameter   ``coupling.c``                             coupling stiffness
``rotor``          rotational  ``rotor.flange_a``                         missing inertia
``table``          attach      ``table.flange_a``                         missing mass
``structure``      all                                                    extra modal damping
=================  ==========  =========================================  ===========================================

Uncertain parameters a user typically marks for re-calibration (:data:`UNCERTAIN`): the table mass, the
coupling stiffness and the guideway viscous coefficient. The lumped axial stiffness is trusted: Sec
3.5.2.2 matched the screw-nut assembly to measurements, and re-scaling it would absorb a nut-table joint
compliance (two springs in series are indistinguishable below the nut's own mode).

Sign convention: motor angle and table position positive in the direction a positive voltage drives them
(thesis Eq 4.2, G_x = r_g / s), as on the FE test bed (:mod:`bscomp.systems.testbed`).

Legacy attributes: ``insertion_points`` (:data:`INSERTION_POINTS`, name -> connection or component),
``uncertain``, ``input`` and ``outputs`` are still set on the system, derived from the interface, for
code that has not moved to ``system.validation`` yet (:mod:`bscomp.validate.candidates`,
:func:`bscomp.validate.diagnose`); new code reads ``system.validation``.
"""

from __future__ import annotations

import math

from bscomp import System
from bscomp.components import (
    CurrentAmplifier,
    Damper,
    Fixed,
    Gain,
    IdealLeadScrew,
    Inertia,
    Mass,
    Spring,
    Torque,
    TorsionalDamper,
    TorsionalSpring,
)
from bscomp.kernel.interface import InsertionPoint, UncertainParameter, ValidationInterface
from bscomp.systems.parameters import get_value, load_parameters

__all__ = ["validation_drive", "interface", "INTERFACE", "INSERTION_POINTS", "UNCERTAIN", "INPUT", "OUTPUTS"]


# lumped values tuned to Table 4.1 (first mode F1 = 117.7 Hz at 6 %, coupling mode damped ~10 %)
F1 = 117.7
"""First elastic mode [Hz] the lumped values are tuned to (Table 4.1, C-position, 117.69 Hz): the reference
frequency of the ``structure`` insertion point (stiffness-proportional extra damping)."""
K_AXIAL = 1.357e8
D_AXIAL = 1.2e4
D_COUPLING = 0.5


def interface() -> ValidationInterface:
    """The declared validation interface of the drive (a new object on every call; module docstring)."""
    return ValidationInterface(
        inputs=["amp.u"],
        outputs=["rotor.phi", "rotor.w", "table.s", "table.a"],
        uncertain=[UncertainParameter("table.m", 0.2, "Table 3.1: CAD estimate (Sec B.3)"),
                   UncertainParameter("coupling.c", 0.2, "Sec B.4 (Eq B.1): from the 805 Hz mode of the coupling "
                                                         "measured alone"),
                   UncertainParameter("guide.d", 0.3, "Table 5.2")],
        points=[
            InsertionPoint("nut_table", "connection", ("nut.flange_b", "table.flange_a"),
                           doc="bolted joint between nut and table"),
            InsertionPoint("table_guide", "attach", ("table.flange_b",), ground="ground.flange",
                           doc="the table on its guideways"),
            InsertionPoint("screw_support", "connection", ("lead.flange_b", "axial.flange_a"),
                           doc="housing in series with the axial support"),
            InsertionPoint("screw_nut", "joint", ("axial", "axial_loss"), parameters=("axial.c", "axial_loss.d"),
                           doc="the components replaced by a backlash element with the same stiffness and "
                               "damping"),
            InsertionPoint("amplifier", "connection", ("amp.i", "kt.u"), doc="amplifier current -> torque constant"),
            InsertionPoint("rotor", "rotational", ("rotor.flange_a",), doc="motor rotor"),
            InsertionPoint("table", "attach", ("table.flange_a",), doc="the table (added mass)"),
            InsertionPoint("coupling", "parameter", parameters=("coupling.c",), doc="coupling stiffness"),
            InsertionPoint("structure", "all", doc="damping of every mode", frequency=F1),
        ],
        ground="ground.flange",
        notes="motor angle and table position positive in the direction a positive voltage drives them "
              "(table.s = r_g rotor.phi at low frequency, Eq 4.2)")


INTERFACE = interface()
"""The declarations of :func:`interface` (read-only reference; systems get their own copy)."""

INPUT = INTERFACE.inputs[0]
"""The system input: amplifier command voltage [V] (legacy; ``system.validation.inputs``)."""

OUTPUTS = list(INTERFACE.outputs)
"""Measured outputs: motor angle [rad], motor speed [rad/s], table position [m] and acceleration [m/s^2]."""

UNCERTAIN = [u.name for u in INTERFACE.uncertain]
"""Parameters that are estimates rather than measurements (Appendix B), re-calibrated before diagnosis."""

INSERTION_POINTS = {
    "nut_table": INTERFACE.points["nut_table"].ports,
    "table_guide": ("table.flange_b", "guide.flange_a"),
    "lead_axial": INTERFACE.points["screw_support"].ports,
    "screw_nut": INTERFACE.points["screw_nut"].ports[0],
    "amplifier": INTERFACE.points["amplifier"].ports,
    "table": "table",
    "rotor": "rotor",
}
"""Legacy form of the insertion points (name -> connection or component) read by
:mod:`bscomp.validate.candidates` until it reads ``system.validation``."""


def _screw_polar_inertia(params) -> float:
    """Polar inertia of the Table B.1 sections [kg m^2] (threaded section C at the equivalent diameter)."""
    rho = get_value(params, "screw.material.density")
    J = 0.0
    for sec in "ABCDEF":
        do = get_value(params, f"screw.sections.{sec}.outer_diameter")
        if sec == "C":
            do = get_value(params, "screw.equivalent_diameter")
        di = get_value(params, f"screw.sections.{sec}.inner_diameter")
        L = get_value(params, f"screw.sections.{sec}.length")
        J += rho * math.pi * L * (do**4 - di**4) / 32.0
    return J


def validation_drive(k_axial: float = K_AXIAL) -> System:
    """Lumped axial + torsional test-bed drive (3 DOF) for validation and diagnosis, amplifier voltage in.

    The nominal drive of the validation story (module docstring): input ``amp.u`` [V].

    Parameters
    ----------
    k_axial : float
        Lumped axial stiffness of screw, bearings and nut [N/m].

    Returns
    -------
    System
        With ``validation`` (:func:`interface`) and, derived from it for older code, the legacy
        ``insertion_points``, ``uncertain``, ``input`` and ``outputs`` attributes.
    """
    P = load_parameters("fadal_vmc2216_x")
    J_rotor = get_value(P, "rotor.Izz")
    s = System("validation_drive")
    s.description = "lumped axial+torsional test-bed drive (3 DOF) for validation and diagnosis"
    s.add("amp", CurrentAmplifier(K_a=get_value(P, "electrical.K_a")))
    s.add("kt", Gain(k=get_value(P, "electrical.K_t")))
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J_rotor + get_value(P, "coupling.J1")))
    s.add("coupling", TorsionalSpring(c=get_value(P, "coupling.kT")))
    s.add("coupling_loss", TorsionalDamper(d=D_COUPLING))
    s.add("screw", Inertia(J=_screw_polar_inertia(P) + get_value(P, "coupling.J2")))
    s.add("lead", IdealLeadScrew(lead=get_value(P, "screw.lead")))
    s.add("axial", Spring(c=k_axial))
    s.add("axial_loss", Damper(d=D_AXIAL))
    s.add("nut", Mass(m=get_value(P, "nut.mass")))
    s.add("table", Mass(m=get_value(P, "table.mass")))
    s.add("guide", Damper(d=get_value(P, "guideways.viscous_coefficient")))
    s.add("ground", Fixed())
    s.connect("amp.i", "kt.u")
    s.connect("kt.y", "motor.tau")
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("rotor.flange_b", "coupling.flange_a")
    s.connect("coupling.flange_b", "screw.flange_a")
    s.connect("coupling_loss.flange_a", "rotor.flange_b")
    s.connect("coupling_loss.flange_b", "screw.flange_a")
    s.connect("screw.flange_b", "lead.flange_a")
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial_loss.flange_a", "axial.flange_a")
    s.connect("axial.flange_b", "nut.flange_a")
    s.connect("axial_loss.flange_b", "nut.flange_a")
    s.connect("nut.flange_b", "table.flange_a")
    s.connect("table.flange_b", "guide.flange_a")
    s.connect("guide.flange_b", "ground.flange")
    s.sources = {
        "amp.K_a": "Eq 4.1", "kt.k": "Eq 4.1", "rotor.J": "Table 3.1 (J_r) + Sec B.4 (J1)",
        "coupling.c": "Sec B.4 (Eq B.1)", "coupling_loss.d": "tuned: ~10 % on the coupling mode (Table 4.1)",
        "screw.J": "Table B.1 sections, rho = 7800 kg/m^3 (Sec B.1) + J2 (Table 3.1)",
        "lead.lead": "Table 3.1", "axial.c": "lumped, tuned to f1 = 117.7 Hz (Table 4.1, C-position)",
        "axial_loss.d": "tuned: ~6 % on the first mode (Table 4.1)", "nut.m": "Table 3.1",
        "table.m": "Table 3.1 (CAD estimate, Sec B.3)", "guide.d": "Table 5.2",
    }
    s.validation = interface()
    # legacy aliases (bscomp.validate.candidates / diagnose read these until they read s.validation)
    s.insertion_points = dict(INSERTION_POINTS)
    s.uncertain = [u.name for u in s.validation.uncertain]
    s.input = s.validation.inputs[0]
    s.outputs = list(s.validation.outputs)
    return s

