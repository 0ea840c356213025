"""Nonlinear effects (time series only): guideway friction (Eq 5.6/5.7), a friction torque at the motor (Eq 5.7 for
a torque: bearings, seals, the nut) and screw-nut backlash (Eq 5.8/5.9)."""

from __future__ import annotations

from bscomp.components import (
    Backlash,
    CoulombFriction,
    Fixed,
    FixedRotational,
    RotationalFriction,
    Spring,
    StribeckFriction,
)
from bscomp.kernel.interface import NotApplicable
from bscomp.validate.candidates._edits import between, connected, insert_series
from bscomp.validate.candidates.base import Candidate, CandidateParameter
from bscomp.validate.candidates.hooks import DetachedBodyDamping

__all__ = ["GuidewayFriction", "StribeckGuidewayFriction", "RotorFriction", "ScrewNutBacklash", "CompliantBacklash",
           "V_REG", "W_REG"]


V_REG = 1e-4
"""Regularisation velocity [m/s] of the friction candidates: the ``CoulombFriction`` component's default and the
thesis bed's (``systems/thesis_effects.py``); its rule, about 1e-3 of the slowest sliding speed of interest, gives
~4e-5 on the test bed. It was 5e-4 (no documented source) until 2026-12-05: the friction truths then ended at 5.9 /
10.1 instead of 1.1 / 1.4; the candidates' sticking slope F_c / v_reg was 7x / 13x below the truths' (2/pi) F_c / v_s
+ d on the axial+torsional friction / joint + friction truths (docs/validation.md)."""


W_REG = 1e-2
"""Regularisation speed [rad/s] of the friction-torque candidate: ``RotationalFriction``'s default. Its sticking
slope at the test bed's rotor, ``T_c / W_REG`` = 50 N m s/rad for 0.5 N m, is that of the guideway candidates'
(``F_c / V_REG r_g^2`` = 52 N m s/rad for the Table 5.2 friction over r_g = 1.59 mm/rad)."""


def _symmetric(element: str, values: dict, names) -> dict:
    """``{element.x_pos, element.x_neg: values[x]}`` for each name ``x`` of a friction law given in ``values``."""
    return {f"{element}.{n}_{side}": values[n] for n in names if n in values for side in ("pos", "neg")}


def _to_ground(e, ground: str, port: str, base: str, cls, **values) -> dict:
    """Friction ``cls`` (``values``) added from ``ground`` to ``port``; the edit state ``{"friction": name}``."""
    name = e.add(e.unique(base), cls, **values)
    e.connect(f"{name}.flange_a", ground)
    e.connect(f"{name}.flange_b", port)
    return {"friction": name}


def _ground(e, point, vi) -> str:
    g = point.ground or (vi.ground if vi is not None else None)
    if g is not None:
        return g
    return e.add(e.unique("effect_ground"), Fixed) + ".flange"


class GuidewayFriction(Candidate):
    """Coulomb + viscous friction at the guideways (thesis Eq 5.7, Table 5.2: 2066 N, B v) between the
    ``table_guide`` node and the ground: ``F_c`` and a viscous coefficient ``d`` *added* to the drive's
    own ``B`` (which stays where it is, on the table or the motor)."""

    def __init__(self):
        super().__init__(
            name="guideway_friction", title="Coulomb + viscous friction at the guideways", role="table_guide",
            parameters=[CandidateParameter("F_c", "N", 10.0, 2e4, 1000.0, 1.5, "Coulomb force"),
                        CandidateParameter("d", "N.s/m", 1.0, 1e5, 1000.0, 1.5, "added viscous coefficient")],
            signature="residual correlates with sign(table velocity): the model moves too far and too fast, "
                      "errors jump at every velocity reversal and the table position drifts",
            nonlinear=True, group="guideway_friction", kinds=("attach", "connection"))

    slope_at_rest = "friction stuck: F_c / v_reg"

    def _edit(self, e, point, vi, for_engine):
        return _to_ground(e, _ground(e, point, vi), point.ports[0], "friction", CoulombFriction, F_c_pos=1000.0,
                          F_c_neg=1000.0, v_reg=V_REG)

    def _overrides(self, values, state):
        return _symmetric(state["friction"], values, ("F_c", "d"))


class StribeckGuidewayFriction(GuidewayFriction):
    """Stribeck friction at the guideways (Eq 5.6): a static term ``F_s`` decaying over ``v1 = 5 mm/s``
    above the Coulomb level ``F_c``; same place and group as :class:`GuidewayFriction`."""

    def __init__(self):
        Candidate.__init__(
            self, name="guideway_stribeck", title="Stribeck friction at the guideways", role="table_guide",
            parameters=[CandidateParameter("F_c", "N", 10.0, 2e4, 1000.0, 1.5, "Coulomb force"),
                        CandidateParameter("F_s", "N", 1.0, 2e4, 300.0, 1.5,
                                           "static term F_stat of Eq 5.6 (decays over v1 = 5 mm/s)")],
            signature="as Coulomb friction, plus extra force at low sliding speed (a breakaway jerk after "
                      "each reversal)",
            nonlinear=True, group="guideway_friction", kinds=("attach", "connection"))

    def _edit(self, e, point, vi, for_engine):
        return _to_ground(e, _ground(e, point, vi), point.ports[0], "friction", StribeckFriction, F_s_pos=300.0,
                          F_s_neg=300.0, F_c_pos=1000.0, F_c_neg=1000.0, v1_pos=5e-3, v1_neg=5e-3, v2_pos=V_REG,
                          v2_neg=V_REG, v_reg=V_REG)

    def _overrides(self, values, state):
        return _symmetric(state["friction"], values, ("F_c", "F_s"))


class RotorFriction(Candidate):
    """Coulomb + viscous friction torque on the motor shaft (Eq 5.7 for a torque): the bearings, seals and the
    preloaded nut, lumped at the ``rotor`` point, between a new :class:`FixedRotational` and the rotor's flange --
    ``T_c`` and a viscous coefficient ``d`` added to the drive's own.

    A motor torque ripple (cogging, which no candidate has) acts at the same place and over a short stroke drags alike:
    beside the defaults the candidate took 2 of 18 drawn ripples (``docs/validation.md``, "Friction that is not at
    the guideways"), so it is :attr:`~bscomp.validate.candidates.base.Candidate.ripple_alike` -- not accepted while
    the residual it leaves repeats with the motor angle.
    The thesis keeps friction at the guideways only (Sec 5.2.2.1); at low frequency a torque ``T_c`` at the motor
    and a force ``T_c / r_g`` on the table are the same, and only the drive's compliance between them (which side
    stops first at a reversal) tells them apart."""

    def __init__(self):
        super().__init__(
            name="rotor_friction", title="Coulomb + viscous friction torque at the motor", role="rotor",
            parameters=[CandidateParameter("T_c", "N.m", 1e-3, 50.0, 0.5, 1.5, "Coulomb torque"),
                        CandidateParameter("d", "N.m.s/rad", 1e-5, 1.0, 2e-3, 1.5, "added viscous coefficient")],
            signature="as guideway friction, but on the motor side of the drive's compliance: the motor speed "
                      "stops and restarts at each reversal while the table moves on behind it",
            nonlinear=True, group="friction_torque", kinds=("rotational",))

    ripple_alike = True
    slope_at_rest = "friction stuck: T_c / w_reg"

    def _edit(self, e, point, vi, for_engine):
        frame = e.add(e.unique("effect_frame"), FixedRotational) + ".flange"
        return _to_ground(e, frame, point.ports[0], "friction_torque", RotationalFriction, T_c_pos=0.5, T_c_neg=0.5,
                          w_reg=W_REG)

    def _overrides(self, values, state):
        return _symmetric(state["friction"], values, ("T_c", "d"))


class ScrewNutBacklash(Candidate):
    """Backlash at the screw-nut (Eq 5.8-5.9): an elastic dead zone of total width ``b``.

    ``joint`` point naming two **components** (lumped drive, ``("axial", "axial_loss")``): the axial
    spring becomes a :class:`~components.backlash.Backlash` with its stiffness and the damper's damping
    in contact (the damper is removed). ``joint`` point naming two **ports** ``(a, b)`` (FE drive: the
    nut--table line; with a 1.49 kg nut on a 250 kg table the screw-nut clearance acts on the table the
    same way): a backlash element in series, contact stiffness ``contact_stiffness`` (default 1e11 N/m,
    ~100x the screw-nut axial stiffness, so the drive in contact changes by ~1 %; or the value of the
    point's first ``parameters`` entry) and small contact damping. If a joint spring already sits on
    that line (:class:`NutTableJoint`), that spring becomes the backlash (same name and stiffness) --
    a dead zone on the joint's axial deformation; its damper stays beside it.

    The gap starts closed on one flank: ``s_rel0 = -b/2``, so at rest the contact is just engaged with
    zero force (the linearisation at rest -- and the modal damping computed from it -- is that of the
    drive in contact) and the first reversal of the screw force opens the gap. ``eps_fraction`` (default
    0: sharp corners) smooths the dead zone's corners over ``eps = eps_fraction b``; note that with
    ``eps > 0`` the rest position carries a preload ``c eps / 8``.
    """

    slope_at_rest = "the clearance not crossed: its contact or open slope"

    def __init__(self, contact_stiffness: float = 1e11, contact_damping: float = 1e3, eps_fraction: float = 0.0):
        super().__init__(
            name="screw_nut_backlash", title="backlash at the screw-nut", role="screw_nut",
            parameters=[CandidateParameter("b", "m", 2e-7, 1e-4, 3e-6, 1.5,
                                           "total axial clearance (Table 5.2: 0.001885 rad x r_g = 3.0 um)")],
            signature="a delay and an impact after every reversal of the screw force (each voltage step): the "
                      "table acceleration rings late, the error correlates with reversals, not with velocity",
            nonlinear=True, group="backlash", kinds=("joint",))
        self.contact_stiffness = float(contact_stiffness)
        self.contact_damping = float(contact_damping)
        self.eps_fraction = float(eps_fraction)
        self.corner = "parabolic"

    def _shape(self) -> dict:
        """Constructor arguments of the clearance beyond its parameters (the corner shape)."""
        return {} if self.corner == "parabolic" else {"corner": self.corner}

    def _gap(self, b):
        return {"b": b, "s_rel0": -b / 2, "eps": self.eps_fraction * b}

    def _edit(self, e, point, vi, for_engine):
        b0 = self.parameters[0].median
        ports = point.ports
        if len(ports) >= 2 and all("." in p for p in ports[:2]):
            a, b = ports[:2]
            inner = [] if connected(e.s, a, b) else between(e.s, a, b)
            springs = [n for n in inner if type(e.s.component(n)) is Spring]
            if springs:   # a dead zone on the joint already there
                name = springs[0]
                e.replace(name, Backlash, c=float(e.s.get(f"{name}.c")), d=0.0, **self._gap(b0), **self._shape())
                return {"element": name}
            c = float(e.s.get(point.parameters[0])) if point.parameters else self.contact_stiffness
            name = e.unique("sn_backlash")
            insert_series(e, name, Backlash, {"c": c, "d": self.contact_damping, **self._gap(b0), **self._shape()},
                          a, b)
            body = f"{b.split('.')[0]}.s"
            detached = e.s.damping is not None and hasattr(e.s.damping, "modal_ratios") and \
                type(e.s.component(b.split(".")[0])).__name__ == "Mass"
            if detached:   # no modal damping force across the clearance: the contact's own damping only
                e.s.damping = DetachedBodyDamping(e.s.damping, [body])
            return {"element": name, "detached": body if detached else None}
        name = ports[0]
        c = float(e.s.get(f"{name}.c"))
        d = float(e.s.get(f"{ports[1]}.d")) if len(ports) > 1 else 0.0
        e.replace(name, Backlash, c=c, d=d, **self._gap(b0), **self._shape())
        if len(ports) > 1:
            e.remove(ports[1])
        return {"element": name}

    def _overrides(self, values, state):
        return {f"{state['element']}.{k}": v for k, v in self._gap(values["b"]).items()}

    def _extra_code(self, values, state):
        if not state.get("detached"):
            return []
        return ["from bscomp.validate.candidates import DetachedBodyDamping",
                f"s.damping = DetachedBodyDamping(s.damping, [{state['detached']!r}])"]


class CompliantBacklash(ScrewNutBacklash):
    """Backlash at the screw-nut with a **compliant, progressive** contact: clearance ``b``, contact
    stiffness ``k``, corner width ``w`` and the position ``x0`` of the nut in the gap at rest.

    A worn or lightly preloaded nut has both: a gap, and in contact an axial stiffness well below the
    rigid-contact value -- the FRF (measured in contact) sees the stiffness, the time series around
    every reversal the gap. Only where the ``screw_nut`` point is a connection (the FE drive's nut--table
    line): a :class:`~components.backlash.Backlash` in series with contact stiffness ``k`` (prior
    1e7..1e11 N/m). Same group as :class:`ScrewNutBacklash`: the better of the two is kept.

    Two more free parameters describe what a real clearance does that a sharp dead zone does not:

    * ``w``, the **corner width** as a fraction of ``b`` (the dead zone's ``eps = w b``, Gaussian
      corners, ``Backlash(corner="gaussian")``): the balls of a worn nut do not all take load at the same
      axial deflection (ball-size scatter, lead errors, Hertzian contact stiffening with load), so the
      contact stiffness comes in over a travel of some fraction of the gap; with the balls' gaps scattered
      normally the mean contact is a Gaussian-smoothed ramp, with tails on both sides (a uniform scatter
      would give the compact parabolic corner). Prior: log-normal, median 0.25, bounds 0.01..1 (1:
      no flat part left), sigma_log 1 -- from sharp (a new nut) to fully progressive.
    * ``x0``, **where the nut sits in the gap at t = 0**: ``s_rel0 = (1 - x0) b / 2``, so ``x0 = 1`` is the
      centre, ``x0 -> 0`` / ``x0 -> 2`` the two flanks. A record starting from rest says nothing about which
      flank the last motion left the contact on; the prior is centred (no preferred flank), bounds
      0.05..1.95, sigma_log 0.5 (fitted in log space as every candidate parameter).

    The linear part (FRF, modal damping) is the contact in engagement whatever ``x0``: the table is
    detached from the drive's modal damping (:class:`DetachedBodyDamping`), so the start position
    changes only the time series.
    """

    def __init__(self, contact_damping: float = 1e3):
        super().__init__(contact_damping=contact_damping)
        self.name = "compliant_backlash"
        self.title = "backlash at the screw-nut with a compliant contact"
        self.parameters = [self.parameters[0],
                           CandidateParameter("k", "N/m", 1e7, 1e11, 3e9, 1.5, "axial contact stiffness",
                                              linear=True),
                           CandidateParameter("w", "1", 0.01, 1.0, 0.25, 1.0,
                                              "corner width / b (the travel over which the contact comes in)"),
                           CandidateParameter("x0", "1", 0.05, 1.95, 1.0, 0.5,
                                              "position in the gap at rest (1: centred, 0 and 2: the flanks)")]
        self.signature = ("as backlash, and the drive's axial mode lower than modelled (the contact is softer "
                          "than the rigid nut-table bolting)")
        self.corner = "gaussian"

    def applicable(self, system):
        point = super().applicable(system)
        if not (len(point.ports) >= 2 and all("." in p for p in point.ports[:2])):
            raise NotApplicable(f"{self.name}: the screw_nut point of '{system.name}' names components, not a "
                                "connection to put a compliant clearance in")
        return point

    def _gap(self, b, w=0.25, x0=1.0):
        return {"b": b, "s_rel0": (1.0 - x0) * b / 2, "eps": w * b}

    def _edit(self, e, point, vi, for_engine):
        state = super()._edit(e, point, vi, for_engine)
        # on a joint already accepted the clearance takes that joint's stiffness (fitted there)
        state["merged"] = not state["element"].startswith("sn_backlash")
        return state

    def _overrides(self, values, state):
        gap = self._gap(values["b"], values.get("w", 0.25), values.get("x0", 1.0))
        out = {f"{state['element']}.{k}": v for k, v in gap.items()}
        if not state.get("merged"):
            out[f"{state['element']}.c"] = values["k"]
        return out
