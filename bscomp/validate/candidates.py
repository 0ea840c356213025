"""Candidate effects: the physical effects a model may be missing, each as a system edit with priors.

Thesis Sec 3.5.2.3-3.5.2.4 compares the test-bed model with measured FRFs and guesses what is missing:
bearing-housing mass and compliance, guideway compliance, nut-table (bolted joint) compliance, friction
and backlash "greatly amplified by the addition of the table", and a time delay from the D/A converters.
Each guess is a :class:`Candidate` here: a component inserted at a named place of the drive
(``system.insertion_points``, see :mod:`bscomp.systems.validation_drive`) with free parameters, bounds and
a physical prior, and a plain-words *signature* -- what its absence looks like in the residuals.

A candidate is applied in two steps: :meth:`Candidate.structure` edits a copy of the system (adds the
components, at prior values) and :meth:`Candidate.overrides` maps the free parameters to component
parameters by dotted name. The fit flattens the structure once and varies only the overrides (they
stay symbolic in the Dae), so a fit costs evaluations, not re-compilations.

Nonlinear effects (friction, backlash) are invisible to an FRF measured at large amplitude with
random or stepped-sine excitation as modelled here: their :meth:`Candidate.structure` with
``linear=True`` leaves the system unchanged, and only time series carry their evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bscomp.errors import UnknownNameError

__all__ = ["CandidateParameter", "Candidate", "NutTableJoint", "GuidewayCompliance", "BearingHousing",
           "ParameterScale", "MissingInertia", "MissingMass", "GuidewayFriction", "StribeckGuidewayFriction",
           "ScrewNutBacklash", "AmplifierDelay", "ExtraDamping", "default_candidates"]


@dataclass
class CandidateParameter:
    """A free parameter of a candidate effect.

    Attributes
    ----------
    name : str
        Short name (``"k"``), unique within the candidate.
    unit : str
    lower, upper : float
        Hard bounds of the fit (> 0; fitted in log space).
    median : float
        Prior median (the start of the first fit).
    sigma_log : float
        Prior spread: the prior is log-normal, ``ln(value) ~ N(ln(median), sigma_log^2)`` (used to draw
        extra starting points; the bounds are the hard limits).
    doc : str
    """

    name: str
    unit: str
    lower: float
    upper: float
    median: float
    sigma_log: float = 1.0
    doc: str = ""

    def starts(self, n: int) -> list:
        """``n`` starting values: the median, then quantiles of the prior inside the bounds."""
        qs = sorted([0.0, -1.0, 1.0, -2.0, 2.0, -0.5, 0.5, -1.5, 1.5][:n], key=abs)
        lo, hi = math.log(self.lower), math.log(self.upper)
        return [math.exp(min(max(math.log(self.median) + q * self.sigma_log, lo + 1e-9), hi - 1e-9)) for q in qs]


@dataclass
class Candidate:
    """Base class of a candidate effect (subclasses fill the fields and the two methods).

    Attributes
    ----------
    name : str
        Identifier (``"nut_table_joint"``).
    title : str
        Words for a report (``"nut-table bolted-joint compliance"``).
    where : str
        Insertion point name or component.
    parameters : list of CandidateParameter
    signature : str
        What the residuals look like when this effect is missing, in plain words.
    nonlinear : bool
        True when the effect only shows in time series (friction, backlash).
    group : str
        Candidates of one group exclude each other (e.g. Coulomb vs Stribeck friction at the guideway).
    is_effect : bool
        False for a parameter re-scaling (used in re-calibration, not a missing effect).
    """

    name: str = ""
    title: str = ""
    where: str = ""
    parameters: list = field(default_factory=list)
    signature: str = ""
    nonlinear: bool = False
    group: str = ""
    is_effect: bool = True

    # ---- to be provided by subclasses ------------------------------------------------------------
    def structure(self, system, linear: bool = False):
        """A copy of ``system`` with the effect's components added (at prior values)."""
        raise NotImplementedError

    def overrides(self, values: dict, system=None) -> dict:
        """Dotted parameter values for free-parameter ``values`` (``{"k": 2e8}``)."""
        raise NotImplementedError

    def code_lines(self, values: dict, system=None) -> list:
        """Python lines that add the effect to a system ``s`` (for a system file)."""
        raise NotImplementedError

    # ---- generic --------------------------------------------------------------------------------
    @property
    def parameter_names(self) -> list:
        return [p.name for p in self.parameters]

    def medians(self) -> dict:
        return {p.name: p.median for p in self.parameters}

    def check(self, values: dict) -> dict:
        out = {}
        for p in self.parameters:
            if p.name not in values:
                raise UnknownNameError(f"candidate '{self.name}' needs parameter '{p.name}' [{p.unit}]")
            out[p.name] = float(values[p.name])
        extra = set(values) - set(self.parameter_names)
        if extra:
            raise UnknownNameError(f"candidate '{self.name}' has no parameter(s) {sorted(extra)}; it has "
                                   f"{self.parameter_names}")
        return out

    def apply(self, system, **values):
        """A copy of ``system`` with this effect added and its parameters set (prior medians for any
        not given)."""
        v = {**self.medians(), **values}
        v = self.check(v)
        s = self.structure(system)
        for k, val in self.overrides(v, s).items():
            s.set(k, val)
        return s

    def code(self, values: dict, system=None) -> str:
        return "\n".join(self.code_lines(self.check({**self.medians(), **values}), system))

    def __repr__(self):
        return f"<Candidate {self.name}: {self.title} at {self.where}>"


def _points(system, key, default):
    pts = getattr(system, "insertion_points", {}) or {}
    return pts.get(key, default)


def _fmt(x):
    return f"{x:.6g}"


# ---- linear structural effects ------------------------------------------------------------------------
class NutTableJoint(Candidate):
    """Nut-table bolted-joint compliance: spring + damper in series between the nut and the table."""

    def __init__(self):
        super().__init__(
            name="nut_table_joint", title="nut-table bolted-joint compliance", where="nut_table",
            parameters=[CandidateParameter("k", "N/m", 1e7, 1e10, 5e8, 1.0, "axial joint stiffness"),
                        CandidateParameter("d", "N.s/m", 1e2, 1e6, 1e4, 1.5, "joint damping")],
            signature="the table-side axial mode is lower (and differently damped) than modelled while the "
                      "rigid-body level fits: residual in the table FRF near the first axial mode, ringing "
                      "of the table acceleration after each step that the model does not show",
            group="nut_table")

    def structure(self, system, linear=False):
        from bscomp.components import Damper, Spring

        s = system.copy()
        a, b = _points(s, "nut_table", ("nut.flange_b", "table.flange_a"))
        s.insert("joint", Spring(c=5e8), between=(a, b))
        s.add("joint_loss", Damper(d=1e4))
        s.connect(a, "joint_loss.flange_a")
        s.connect("joint_loss.flange_b", b)
        return s

    def overrides(self, values, system=None):
        return {"joint.c": values["k"], "joint_loss.d": values["d"]}

    def code_lines(self, values, system=None):
        a, b = _points(system, "nut_table", ("nut.flange_b", "table.flange_a")) if system else \
            ("nut.flange_b", "table.flange_a")
        return [f's.insert("joint", Spring(c={_fmt(values["k"])}), between=("{a}", "{b}"))',
                f's.add("joint_loss", Damper(d={_fmt(values["d"])}))',
                f's.connect("{a}", "joint_loss.flange_a")', f's.connect("joint_loss.flange_b", "{b}")']


class _MassOnSpring(Candidate):
    """A mass attached through a spring (5 % damping) at a node: a local mode the model lacks."""

    prefix = "extra"
    zeta = 0.05

    def _node(self, system):
        raise NotImplementedError

    def overrides(self, values, system=None):
        m, k = values["m"], values["k"]
        return {f"{self.prefix}_mass.m": m, f"{self.prefix}_spring.c": k,
                f"{self.prefix}_loss.d": 2 * self.zeta * math.sqrt(k * m)}


class GuidewayCompliance(_MassOnSpring):
    """Guideway compliance: part of the table rocks on the compliant box way (seen along the axis as a
    mass on a spring at the table), the ~900 Hz mode of thesis Fig 3.33."""

    prefix = "guideway"

    def __init__(self):
        super().__init__(
            name="guideway_compliance", title="guideway compliance (table rocking on the ways)",
            where="table_guide",
            parameters=[CandidateParameter("m", "kg", 1.0, 200.0, 30.0, 1.0, "mass rocking on the ways"),
                        CandidateParameter("k", "N/m", 1e7, 5e10, 1e9, 1.5, "guideway stiffness along the axis")],
            signature="an extra resonance in the table acceleration FRF (thesis: ~900 Hz) with no model "
                      "counterpart; the motor-side FRF hardly changes",
            group="guideway_compliance")

    def structure(self, system, linear=False):
        from bscomp.components import Damper, Mass, Spring

        s = system.copy()
        node = _points(s, "table_guide", ("table.flange_b", "guide.flange_a"))[0]
        s.add("guideway_spring", Spring(c=1e9))
        s.add("guideway_loss", Damper(d=1e4))
        s.add("guideway_mass", Mass(m=30.0))
        for part in ("guideway_spring", "guideway_loss"):
            s.connect(node, f"{part}.flange_a")
            s.connect(f"{part}.flange_b", "guideway_mass.flange_a")
        return s

    def code_lines(self, values, system=None):
        o = self.overrides(values)
        node = _points(system, "table_guide", ("table.flange_b",))[0] if system else "table.flange_b"
        return [f's.add("guideway_spring", Spring(c={_fmt(o["guideway_spring.c"])}))',
                f's.add("guideway_loss", Damper(d={_fmt(o["guideway_loss.d"])}))',
                f's.add("guideway_mass", Mass(m={_fmt(o["guideway_mass.m"])}))',
                f's.connect("{node}", "guideway_spring.flange_a")',
                's.connect("guideway_spring.flange_b", "guideway_mass.flange_a")',
                f's.connect("{node}", "guideway_loss.flange_a")',
                's.connect("guideway_loss.flange_b", "guideway_mass.flange_a")']


class BearingHousing(_MassOnSpring):
    """Bearing-housing mass and compliance: the housing block on its fasteners, in series with the
    screw's axial support (thesis Sec 3.5.2.3)."""

    prefix = "housing"

    def __init__(self):
        super().__init__(
            name="bearing_housing", title="bearing-housing mass and compliance", where="lead_axial",
            parameters=[CandidateParameter("m", "kg", 0.5, 100.0, 10.0, 1.0, "housing mass"),
                        CandidateParameter("k", "N/m", 1e7, 5e10, 1e9, 1.5, "fastener (housing) stiffness")],
            signature="the axial mode seen from both motor and table is softer than modelled and a second "
                      "axial mode appears above it; both FRFs change near the axial modes",
            group="bearing_housing")

    def structure(self, system, linear=False):
        from bscomp.components import Damper, Mass, Spring

        s = system.copy()
        a, b = _points(s, "lead_axial", ("lead.flange_b", "axial.flange_a"))
        s.insert("housing_spring", Spring(c=1e9), between=(a, b))
        s.add("housing_loss", Damper(d=1e4))
        s.add("housing_mass", Mass(m=10.0))
        s.connect(a, "housing_loss.flange_a")
        s.connect("housing_loss.flange_b", b)
        s.connect("housing_mass.flange_a", b)
        return s

    def code_lines(self, values, system=None):
        o = self.overrides(values)
        a, b = _points(system, "lead_axial", ("lead.flange_b", "axial.flange_a")) if system else \
            ("lead.flange_b", "axial.flange_a")
        return [f's.insert("housing_spring", Spring(c={_fmt(o["housing_spring.c"])}), between=("{a}", "{b}"))',
                f's.add("housing_loss", Damper(d={_fmt(o["housing_loss.d"])}))',
                f's.add("housing_mass", Mass(m={_fmt(o["housing_mass.m"])}))',
                f's.connect("{a}", "housing_loss.flange_a")', f's.connect("housing_loss.flange_b", "{b}")',
                f's.connect("housing_mass.flange_a", "{b}")']


class ParameterScale(Candidate):
    """Re-scale an existing parameter (e.g. a coupling stiffness error). Not a missing effect: a wrong
    value, fixed by re-calibration."""

    def __init__(self, parameter: str, lower: float = 0.3, upper: float = 3.0, title: str = ""):
        super().__init__(
            name=f"scale:{parameter}", title=title or f"error in {parameter}", where=parameter,
            parameters=[CandidateParameter("factor", "1", lower, upper, 1.0, 0.3, f"factor on {parameter}")],
            signature=f"a mis-set {parameter}: the modes it governs sit at the wrong frequencies",
            group=f"scale:{parameter}", is_effect=False)
        self.parameter = parameter

    def structure(self, system, linear=False):
        s = system.copy()
        s._scale_base = getattr(s, "_scale_base", {})
        s._scale_base.setdefault(self.parameter, float(system.get(self.parameter)))
        return s

    def overrides(self, values, system=None):
        base = (getattr(system, "_scale_base", {}) or {}).get(self.parameter) if system is not None else None
        if base is None:
            raise UnknownNameError(f"{self.name}: apply to a system first (base value unknown)")
        return {self.parameter: base * values["factor"]}

    def code_lines(self, values, system=None):
        base = float(system.get(self.parameter)) if system is not None else float("nan")
        return [f's.set("{self.parameter}", {_fmt(base * values["factor"])})']


class MissingInertia(Candidate):
    """A rotating inertia the model lacks at the motor (tachometer, brake, encoder disc)."""

    def __init__(self):
        super().__init__(
            name="missing_inertia", title="missing inertia at the motor", where="rotor",
            parameters=[CandidateParameter("J", "kg.m2", 1e-5, 1e-2, 1e-3, 1.5, "added inertia")],
            signature="the motor-speed FRF level at low frequency (rigid-body inertia) and the coupling mode "
                      "frequency are both lower than modelled; accelerations after each voltage step too small",
            group="rotor_inertia")

    def structure(self, system, linear=False):
        from bscomp.components import Inertia

        s = system.copy()
        node = _points(s, "rotor", "rotor")
        s.add("extra_inertia", Inertia(J=1e-3))
        s.connect("extra_inertia.flange_a", f"{node}.flange_a")
        return s

    def overrides(self, values, system=None):
        return {"extra_inertia.J": values["J"]}

    def code_lines(self, values, system=None):
        return [f's.add("extra_inertia", Inertia(J={_fmt(values["J"])}))',
                's.connect("extra_inertia.flange_a", "rotor.flange_a")']


class MissingMass(Candidate):
    """A mass the model lacks on the table (fixture, workpiece). Degenerate with re-calibrating
    ``table.m``: skipped by :func:`~bscomp.validate.diagnose.diagnose` when that is uncertain."""

    def __init__(self):
        super().__init__(
            name="missing_mass", title="missing mass on the table", where="table",
            parameters=[CandidateParameter("m", "kg", 0.5, 500.0, 20.0, 1.5, "added mass")],
            signature="the rigid-body inertia and the table-side axial mode are both lower than measured",
            group="table_mass")
        self.degenerate_with = "table.m"

    def structure(self, system, linear=False):
        from bscomp.components import Mass

        s = system.copy()
        s.add("extra_mass", Mass(m=20.0))
        s.connect("extra_mass.flange_a", "table.flange_a")
        return s

    def overrides(self, values, system=None):
        return {"extra_mass.m": values["m"]}

    def code_lines(self, values, system=None):
        return [f's.add("extra_mass", Mass(m={_fmt(values["m"])}))',
                's.connect("extra_mass.flange_a", "table.flange_a")']


class ExtraDamping(Candidate):
    """Extra modal damping, stiffness-proportional: a damper ``d = beta c`` beside every spring, so mode
    *i* gains ``zeta_i = zeta (f_i / f_1)`` with ``f_1`` the first elastic mode of the nominal model."""

    def __init__(self, f1: float = 117.7):
        super().__init__(
            name="extra_damping", title="extra modal damping (stiffness-proportional)", where="all springs",
            parameters=[CandidateParameter("zeta", "1", 1e-3, 0.3, 0.02, 1.0, "added damping ratio at f_1")],
            signature="resonance peaks lower and broader than modelled at unchanged frequencies; ringing after "
                      "each step dies out faster than the model's",
            group="damping")
        self.f1 = f1

    def _springs(self, system):
        from bscomp.components import Spring, TorsionalSpring

        return [p for p, c in system.leaves() if isinstance(c, (Spring, TorsionalSpring)) and not
                p.startswith(("guideway", "housing"))]

    def structure(self, system, linear=False):
        from bscomp.components import Damper, Spring, TorsionalDamper

        s = system.copy()
        pairs = {}
        for a, b in s.connections():
            pairs.setdefault(a.split(".")[0], []).append((a, b))
        for path in self._springs(s):
            comp = s.component(path)
            cls = Damper if isinstance(comp, Spring) else TorsionalDamper
            name = f"extra_loss_{path.replace('.', '_')}"
            s.add(name, cls(d=0.0))
            for port in ("flange_a", "flange_b"):
                other = next((b if a == f"{path}.{port}" else a) for a, b in s.connections()
                             if f"{path}.{port}" in (a, b))
                s.connect(f"{name}.{port}", other)
        s._extra_damping_springs = {f"extra_loss_{p.replace('.', '_')}": float(s.get(f"{p}.c")) for p in
                                    self._springs(system)}
        return s

    def overrides(self, values, system=None):
        beta = 2 * values["zeta"] / (2 * math.pi * self.f1)
        springs = getattr(system, "_extra_damping_springs", {}) if system is not None else {}
        return {f"{name}.d": beta * c for name, c in springs.items()}

    def code_lines(self, values, system=None):
        beta = 2 * values["zeta"] / (2 * math.pi * self.f1)
        lines = [f"# extra damping: beside every spring a damper d = {_fmt(beta)} * c "
                 f"(zeta = {_fmt(values['zeta'])} at {self.f1:g} Hz)"]
        if system is not None:
            for path in self._springs(system):
                cls = "Damper" if type(system.component(path)).__name__ == "Spring" else "TorsionalDamper"
                name = f"extra_loss_{path.replace('.', '_')}"
                lines.append(f's.add("{name}", {cls}(d={_fmt(beta * float(system.get(path + ".c")))}))  '
                             f"# beside {path}, connect to its two flanges")
        return lines


class AmplifierDelay(Candidate):
    """D/A converter + amplifier latency: a Padé delay (order 2) between the amplifier and the motor."""

    def __init__(self, order: int = 2):
        super().__init__(
            name="amplifier_delay", title="amplifier / D/A time delay", where="amplifier",
            parameters=[CandidateParameter("T", "s", 1e-5, 5e-3, 3e-4, 1.0, "time delay")],
            signature="phase lag growing linearly with frequency in every FRF at unchanged magnitude; the "
                      "response to each voltage step starts late",
            group="delay")
        self.order = order

    def structure(self, system, linear=False):
        from bscomp.components.pade_delay import PadeDelay

        s = system.copy()
        a, b = _points(s, "amplifier", ("amp.i", "kt.u"))
        s.insert("delay", PadeDelay(order=self.order, T=3e-4), between=(a, b), ports=("u", "y"))
        return s

    def overrides(self, values, system=None):
        return {"delay.T": values["T"]}

    def code_lines(self, values, system=None):
        a, b = _points(system, "amplifier", ("amp.i", "kt.u")) if system else ("amp.i", "kt.u")
        return ["from bscomp.components.pade_delay import PadeDelay",
                f's.insert("delay", PadeDelay(order={self.order}, T={_fmt(values["T"])}), between=("{a}", "{b}"), '
                'ports=("u", "y"))']


# ---- nonlinear effects (time series only) --------------------------------------------------------------
V_REG = 5e-4
"""Regularisation velocity [m/s] of the friction candidates (see components/coulomb_friction.py)."""


class GuidewayFriction(Candidate):
    """Coulomb friction at the guideways (thesis Eq 5.7, Table 5.2: 2066 N), beside the viscous term."""

    def __init__(self):
        super().__init__(
            name="guideway_friction", title="Coulomb friction at the guideways", where="table_guide",
            parameters=[CandidateParameter("F_c", "N", 10.0, 2e4, 1000.0, 1.0, "Coulomb force")],
            signature="residual correlates with sign(table velocity): the model moves too far and too fast, "
                      "errors jump at every velocity reversal and the table position drifts",
            nonlinear=True, group="guideway_friction")

    def structure(self, system, linear=False):
        from bscomp.components.coulomb_friction import CoulombFriction

        s = system.copy()
        if linear:
            return s
        s.add("friction", CoulombFriction(F_c=1000.0, v_reg=V_REG))
        s.connect("friction.flange_a", "ground.flange")
        s.connect("friction.flange_b", _points(s, "table_guide", ("table.flange_b",))[0])
        return s

    def overrides(self, values, system=None):
        return {"friction.F_c_pos": values["F_c"], "friction.F_c_neg": values["F_c"]}

    def code_lines(self, values, system=None):
        return ["from bscomp.components.coulomb_friction import CoulombFriction",
                f's.add("friction", CoulombFriction(F_c={_fmt(values["F_c"])}, v_reg={V_REG:g}))',
                's.connect("friction.flange_a", "ground.flange")', 's.connect("friction.flange_b", "table.flange_b")']


class StribeckGuidewayFriction(Candidate):
    """Stribeck friction at the guideways (Eq 5.6): breakaway ``F_s`` above the Coulomb level ``F_c``."""

    def __init__(self):
        super().__init__(
            name="guideway_stribeck", title="Stribeck friction at the guideways", where="table_guide",
            parameters=[CandidateParameter("F_c", "N", 10.0, 2e4, 1000.0, 1.0, "Coulomb force"),
                        CandidateParameter("F_s", "N", 1.0, 2e4, 300.0, 1.5,
                                           "static term F_stat of Eq 5.6 (decays over v1 = 5 mm/s)")],
            signature="as Coulomb friction, plus extra force at low sliding speed (a breakaway jerk after "
                      "each reversal)",
            nonlinear=True, group="guideway_friction")

    def structure(self, system, linear=False):
        from bscomp.components.stribeck_friction import StribeckFriction

        s = system.copy()
        if linear:
            return s
        s.add("friction", StribeckFriction(F_s=1500.0, F_c=1000.0, v1=5e-3, v2=V_REG, v_reg=V_REG))
        s.connect("friction.flange_a", "ground.flange")
        s.connect("friction.flange_b", _points(s, "table_guide", ("table.flange_b",))[0])
        return s

    def overrides(self, values, system=None):
        return {"friction.F_c_pos": values["F_c"], "friction.F_c_neg": values["F_c"],
                "friction.F_s_pos": values["F_s"], "friction.F_s_neg": values["F_s"]}

    def code_lines(self, values, system=None):
        return ["from bscomp.components.stribeck_friction import StribeckFriction",
                f's.add("friction", StribeckFriction(F_s={_fmt(values["F_s"])}, F_c={_fmt(values["F_c"])}, v1=5e-3, '
                f'v2={V_REG:g}, v_reg={V_REG:g}))',
                's.connect("friction.flange_a", "ground.flange")', 's.connect("friction.flange_b", "table.flange_b")']


class ScrewNutBacklash(Candidate):
    """Backlash at the screw-nut (Eq 5.8-5.9): the axial spring becomes an elastic dead zone of width
    ``b`` (same stiffness and damping in contact), starting in contact on one flank."""

    def __init__(self):
        super().__init__(
            name="screw_nut_backlash", title="backlash at the screw-nut", where="screw_nut",
            parameters=[CandidateParameter("b", "m", 2e-7, 1e-4, 5e-6, 1.0, "total clearance (axial)")],
            signature="a delay and an impact after every reversal of the screw force (each voltage step): the "
                      "table acceleration rings late, the error correlates with reversals, not with velocity",
            nonlinear=True, group="backlash")

    def structure(self, system, linear=False):
        from bscomp.components.backlash import Backlash

        s = system.copy()
        if linear:
            return s
        name = _points(s, "screw_nut", "axial")
        c = float(s.get(f"{name}.c"))
        d = float(s.get(f"{name}_loss.d")) if f"{name}_loss" in s._components else 0.0
        conns = [(a, b) for a, b in s._connections if a.split(".")[0] in (name, f"{name}_loss")
                 or b.split(".")[0] in (name, f"{name}_loss")]
        ports = {}
        for a, b in conns:
            mine, other = (a, b) if a.split(".")[0] in (name, f"{name}_loss") else (b, a)
            ports.setdefault(mine.split(".")[-1], other)
        s.remove(name)
        if f"{name}_loss" in s._components:
            s.remove(f"{name}_loss")
        s.add(name, Backlash(b=5e-6, c=c, d=d, s_rel0=-2.5e-6, eps=1e-6))
        s.connect(ports["flange_a"], f"{name}.flange_a")
        s.connect(f"{name}.flange_b", ports["flange_b"])
        s._backlash_name = name
        return s

    def overrides(self, values, system=None):
        name = getattr(system, "_backlash_name", "axial") if system is not None else "axial"
        b = values["b"]
        return {f"{name}.b": b, f"{name}.s_rel0": -b / 2, f"{name}.eps": 0.2 * b}

    def code_lines(self, values, system=None):
        b = values["b"]
        return ["from bscomp.components.backlash import Backlash",
                "c, d = s.get('axial.c'), s.get('axial_loss.d')",
                "s.remove('axial'); s.remove('axial_loss')",
                f"s.add('axial', Backlash(b={_fmt(b)}, c=c, d=d, s_rel0={_fmt(-b / 2)}, eps={_fmt(0.2 * b)}))",
                "s.connect('lead.flange_b', 'axial.flange_a'); s.connect('axial.flange_b', 'nut.flange_a')"]


def default_candidates() -> list:
    """The library of missing effects (the thesis's Sec 3.5 guesses), in a fixed order."""
    return [NutTableJoint(), GuidewayCompliance(), BearingHousing(), MissingInertia(), MissingMass(),
            GuidewayFriction(), StribeckGuidewayFriction(), ScrewNutBacklash(), AmplifierDelay(), ExtraDamping()]

