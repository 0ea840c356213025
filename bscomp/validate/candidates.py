"""Candidate effects: the physical effects a model may be missing, each as a system edit with priors.

Thesis Sec 3.5.2.3-3.5.2.4 compares the test-bed model with measured FRFs and guesses what is missing:
bearing-housing mass and compliance, guideway compliance, nut-table (bolted joint) compliance, friction
and backlash "greatly amplified by the addition of the table", and a time delay from the D/A converters.
Each guess is a :class:`Candidate` here: components inserted at an **insertion point of a role** that the
drive declares in its validation interface (``system.validation``, :mod:`bscomp.interface`), with free
parameters, bounds and a physical prior, and a plain-words *signature* -- what its absence looks like in
the residuals. A drive without a point of the candidate's role (or of a kind the candidate handles)
makes it *not applicable*: :meth:`Candidate.applicable` raises :class:`~bscomp.interface.NotApplicable`
with the reason; any other failure while inserting it is an error and propagates.

A candidate is applied in two steps: :meth:`Candidate.structure` edits a copy of the system (adds the
components, at prior values) and :meth:`Candidate.overrides` maps the free parameters to component
parameters by dotted name. The fit flattens the structure once and varies only the overrides (they
stay symbolic in the Dae), so a fit costs evaluations, not re-compilations. Two effects that an
evaluation engine applies better outside the model -- an exact input delay and extra modal damping --
also say so through :meth:`Candidate.engine_hooks` (``structure(..., for_engine=True)`` then leaves
the model unchanged). Every edit is recorded (:mod:`bscomp.validate._edits`), so
:meth:`Candidate.code_lines` writes the same edit as Python lines for a system file.

Nonlinear effects (friction, backlash) are invisible to an FRF measured at large amplitude with
random or stepped-sine excitation as modelled here: their :meth:`Candidate.structure` with
``linear=True`` leaves the system unchanged, and only time series carry their evidence.

Effects at the same place stack: the nut-table joint compliance and the screw-nut backlash share the
nut--table line of the FE test bed; whichever comes second turns the element already there into a
backlash whose contact stiffness is the joint's (see :class:`ScrewNutBacklash`), in either order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import ModelDefinitionError, UnknownNameError
from bscomp.interface import InsertionPoint, NotApplicable, ValidationInterface, interface_of

from ._edits import Edits, between, connected, insert_series

__all__ = ["CandidateParameter", "Candidate", "NutTableJoint", "TableSubassembly", "BearingHousing",
           "ParameterScale", "CouplingStiffness", "MissingInertia", "MissingMass", "GuidewayFriction",
           "StribeckGuidewayFriction", "ScrewNutBacklash", "AmplifierDelay", "ExtraDamping",
           "AddedModalDamping", "default_candidates", "V_REG"]

LN10 = math.log(10.0)


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
    """Base class of a candidate effect (subclasses set the fields and implement ``_edit``/``_overrides``).

    Attributes
    ----------
    name : str
        Identifier (``"nut_table_joint"``).
    title : str
        Words for a report (``"nut-table bolted-joint compliance"``).
    role : str
        Insertion-point role the effect goes to (:data:`bscomp.interface.ROLES`); ``where`` is the same.
    parameters : list of CandidateParameter
    signature : str
        What the residuals look like when this effect is missing, in plain words.
    nonlinear : bool
        True when the effect only shows in time series (friction, backlash).
    group : str
        Candidates of one group exclude each other (e.g. Coulomb vs Stribeck friction at the guideway).
    is_effect : bool
        False for a parameter re-scaling (used in re-calibration, not a missing effect).
    kinds : tuple of str
        Insertion-point kinds the candidate handles.
    """

    name: str = ""
    title: str = ""
    role: str = ""
    parameters: list = field(default_factory=list)
    signature: str = ""
    nonlinear: bool = False
    group: str = ""
    is_effect: bool = True
    kinds: tuple = ()

    #: True when an evaluation engine applies the effect exactly from :meth:`engine_hooks`
    exact_delay = False

    @property
    def where(self) -> str:
        return self.role

    # ---- applicability ---------------------------------------------------------------------------
    def applicable(self, system) -> InsertionPoint:
        """The insertion point this candidate uses in ``system``; raises :class:`NotApplicable` (with
        the reason) when the drive declares none of the candidate's role, of a kind it handles, or names
        ports/components/parameters the system does not have."""
        return self._resolve(system)[1]

    def _resolve(self, system):
        vi = interface_of(system) or _legacy_interface(system)
        if vi is None:
            raise NotApplicable(f"{self.name}: system '{system.name}' declares no validation interface "
                                f"(system.validation), so no '{self.role}' insertion point")
        try:
            point = vi.point(self.role)
        except NotApplicable as exc:
            raise NotApplicable(f"{self.name}: {exc}") from None
        if point.kind not in self.kinds:
            raise NotApplicable(f"{self.name}: the '{self.role}' insertion point of '{system.name}' is of kind "
                                f"'{point.kind}'; this candidate handles {list(self.kinds)}")
        for port in point.ports:
            try:
                if "." in port:
                    system.port_spec(port)
                else:
                    system.component(port)
            except UnknownNameError as exc:
                raise NotApplicable(f"{self.name}: the '{self.role}' insertion point names '{port}', which "
                                    f"'{system.name}' does not have ({exc})") from None
        for name in point.parameters:
            try:
                system.get(name)
            except UnknownNameError as exc:
                raise NotApplicable(f"{self.name}: the '{self.role}' insertion point names parameter "
                                    f"'{name}', which '{system.name}' does not have ({exc})") from None
        return vi, point

    def degenerate(self, system) -> set:
        """Dotted parameters whose re-calibration absorbs this effect (skip it when one is uncertain)."""
        d = getattr(self, "degenerate_with", None)
        return {d} if isinstance(d, str) else set(d or ())

    # ---- to be provided by subclasses ------------------------------------------------------------
    def _edit(self, e: Edits, point: InsertionPoint, vi, for_engine: bool) -> dict:
        """Edit ``e.s`` (through ``e``) at prior values; return the state :meth:`_overrides` needs."""
        raise NotImplementedError

    def _overrides(self, values: dict, state: dict) -> dict:
        raise NotImplementedError

    def _assign_extra(self, system, values: dict, state: dict) -> None:
        """Settings that are not component parameters (system-level damping)."""

    def _extra_code(self, values: dict, state: dict) -> list:
        return []

    # ---- public API ------------------------------------------------------------------------------
    def structure(self, system, linear: bool = False, for_engine: bool = False):
        """A copy of ``system`` with the effect's components added (at prior values).

        ``linear=True`` leaves nonlinear effects out (the model for FRFs); ``for_engine=True`` leaves
        out what an evaluation engine applies itself from :meth:`engine_hooks`. Raises
        :class:`NotApplicable` as :meth:`applicable`; any other failure propagates.
        """
        vi, point = self._resolve(system)
        s = system.copy()
        states = dict(getattr(s, "_effect_state", {}) or {})
        s._effect_state = states
        if linear and self.nonlinear:
            states[self.name] = {"inactive": True}
            return s
        e = Edits(s)
        state = dict(self._edit(e, point, vi, for_engine) or {})
        state["added"] = list(e.added)
        states[self.name] = state
        return s

    def overrides(self, values: dict, system=None) -> dict:
        """Dotted parameter values for free-parameter ``values`` (``{"k": 2e8}``) in ``system``, a result
        of :meth:`structure` (possibly with further effects added on top)."""
        state = _state(system, self)
        if state.get("inactive"):
            return {}
        return self._overrides(values, state)

    def engine_hooks(self, values: dict, system=None) -> dict:
        """Effects an evaluation engine applies outside the model (``{"input_delay": T}``...); {}."""
        return {}

    def assign(self, system, values: dict) -> None:
        """Set free-parameter ``values`` in a result of :meth:`structure`, in place."""
        for k, val in self.overrides(values, system).items():
            system.set(k, val)
        state = _state(system, self)
        if not state.get("inactive"):
            self._assign_extra(system, values, state)

    def code_lines(self, values: dict, system=None) -> list:
        """Python lines (imports included) that add the effect at ``values`` to a system ``s`` that is
        ``system``: running them on a copy of ``system`` gives what :meth:`apply` gives."""
        if system is None:
            raise UnknownNameError(f"{self.name}.code_lines needs the system the effect is added to")
        v = self.check({**self.medians(), **values})
        vi, point = self._resolve(system)
        e = Edits(system.copy())
        state = dict(self._edit(e, point, vi, False) or {})
        return e.render(self._overrides(v, state)) + self._extra_code(v, state)

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
        v = self.check({**self.medians(), **values})
        s = self.structure(system)
        self.assign(s, v)
        return s

    def code(self, values: dict, system=None) -> str:
        return "\n".join(self.code_lines(values, system))

    def __repr__(self):
        return f"<Candidate {self.name}: {self.title} at {self.role}>"


def _state(system, cand) -> dict:
    states = (getattr(system, "_effect_state", None) if system is not None else None) or {}
    if cand.name not in states:
        raise UnknownNameError(f"candidate '{cand.name}': overrides need a system returned by its structure() "
                               "(possibly with other effects added on top)")
    return states[cand.name]


def _legacy_interface(system):
    """A :class:`ValidationInterface` from the older ``system.insertion_points`` dictionary, or None."""
    pts = getattr(system, "insertion_points", None)
    if not pts:
        return None
    comps = system._components
    ground = "ground.flange" if "ground" in comps else None
    out = [InsertionPoint("structure", "all")]
    for key, val in pts.items():
        if key == "nut_table":
            out.append(InsertionPoint("nut_table", "connection", tuple(val)))
        elif key == "table_guide":
            out.append(InsertionPoint("table_guide", "attach", (tuple(val)[0],), ground=ground))
        elif key in ("lead_axial", "screw_support"):
            out.append(InsertionPoint("screw_support", "connection", tuple(val)))
        elif key == "screw_nut":
            names = (val,) if isinstance(val, str) else tuple(val)
            if len(names) == 1 and f"{names[0]}_loss" in comps:
                names += (f"{names[0]}_loss",)
            out.append(InsertionPoint("screw_nut", "joint", names))
        elif key == "amplifier":
            out.append(InsertionPoint("amplifier", "connection", tuple(val)))
        elif key == "table":
            out.append(InsertionPoint("table", "attach", (f"{val}.flange_a" if "." not in val else val,)))
        elif key == "rotor":
            out.append(InsertionPoint("rotor", "rotational", (f"{val}.flange_a" if "." not in val else val,)))
    return ValidationInterface(inputs=[getattr(system, "input", "")], outputs=list(getattr(system, "outputs", [])),
                               points=out, ground=ground)


def _zeta_damper(zeta, k, m):
    """Viscous coefficient of ``zeta`` of critical for a mass ``m`` on a spring ``k``."""
    return 2.0 * zeta * math.sqrt(k * m)


def _params_of(comp) -> dict:
    out = {}
    for n in comp.parameters():
        v = comp.get(n)
        out[n] = np.asarray(v).tolist() if np.ndim(v) else float(v)
    return out


# ---- linear structural effects ------------------------------------------------------------------------
class NutTableJoint(Candidate):
    """Nut-table bolted-joint compliance: spring ``k`` + damper ``d`` in series between nut and table.

    At the ``nut_table`` connection ``(a, b)``. If a screw-nut backlash already sits on that line (the
    FE test bed's clearance is modelled there too), the joint's spring becomes that backlash's contact
    stiffness (one element, renamed to this joint's spring name) and the damper goes beside it: two
    compliances in series would leave a massless node, which a drive with system-level modal damping
    cannot have.
    """

    def __init__(self):
        super().__init__(
            name="nut_table_joint", title="nut-table bolted-joint compliance", role="nut_table",
            parameters=[CandidateParameter("k", "N/m", 1e6, 1e11, 5e8, 2.3, "axial joint stiffness"),
                        CandidateParameter("d", "N.s/m", 1.0, 1e6, 1e3, 2.3, "joint damping")],
            signature="the table-side axial mode is lower (and differently damped) than modelled while the "
                      "rigid-body level fits: residual in the table FRF near the first axial mode, ringing "
                      "of the table acceleration after each step that the model does not show",
            group="nut_table", kinds=("connection",))

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Backlash, Damper, Spring

        a, b = point.ports[:2]
        spring = e.unique("nt_joint")
        loss = e.unique("nt_joint_loss", taken=(spring,))
        inner = [] if connected(e.s, a, b) else between(e.s, a, b)
        clear = [n for n in inner if isinstance(e.s.component(n), Backlash)]
        if clear:   # the backlash's contact becomes this joint's spring (same element, renamed)
            old = clear[0]
            kw = {**_params_of(e.s.component(old)), "c": 5e8, "d": 0.0}
            e.rename(old, spring, Backlash, **kw)
            for st in e.s._effect_state.values():
                if st.get("element") == old:
                    st["element"] = spring
        else:
            insert_series(e, spring, Spring, {"c": 5e8}, a, b)
        e.add(loss, Damper, d=1e3)
        e.connect(f"{spring}.flange_a", f"{loss}.flange_a")
        e.connect(f"{spring}.flange_b", f"{loss}.flange_b")
        return {"spring": spring, "damper": loss}

    def _overrides(self, values, state):
        return {f"{state['spring']}.c": values["k"], f"{state['damper']}.d": values["d"]}


class TableSubassembly(Candidate):
    """A sub-assembly on a joint at the table: mass ``m`` on its own spring ``k`` (+ 5 % damping).

    The second shape an extra table-side mode can take (the first is :class:`NutTableJoint`): a part of
    the table (a fixture, a saddle, a cover, the part of the table rocking on its ways) attached to the
    table side of the ``nut_table`` point through a compliant joint. It adds one mode near
    ``sqrt(k (1/m + 1/M)) / 2 pi`` (``M`` the table's moving mass). The mass is **additive**: the
    rigid-body mass grows by ``m`` (it is not taken from the table); re-calibrate ``table.m`` if the
    total mass is known.
    """

    zeta = 0.05

    def __init__(self):
        super().__init__(
            name="table_subassembly", title="sub-assembly on a compliant joint at the table", role="nut_table",
            parameters=[CandidateParameter("m", "kg", 1.0, 200.0, 20.0, 1.2, "mass of the sub-assembly"),
                        CandidateParameter("k", "N/m", 1e6, 1e11, 5e8, 2.3, "stiffness of its joint")],
            signature="an extra resonance (and anti-resonance) in the table acceleration FRF with no model "
                      "counterpart; the motor-side FRF hardly changes",
            group="table_mode", kinds=("connection",))

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Damper, Mass, Spring

        node = point.ports[1]
        spring = e.unique("sub_spring")
        loss = e.unique("sub_loss")
        mass = e.unique("sub_mass")
        e.add(spring, Spring, c=5e8)
        e.add(loss, Damper, d=_zeta_damper(self.zeta, 5e8, 20.0))
        e.add(mass, Mass, m=20.0)
        for part in (spring, loss):
            e.connect(node, f"{part}.flange_a")
            e.connect(f"{part}.flange_b", f"{mass}.flange_a")
        return {"spring": spring, "damper": loss, "mass": mass}

    def _overrides(self, values, state):
        m, k = values["m"], values["k"]
        return {f"{state['mass']}.m": m, f"{state['spring']}.c": k,
                f"{state['damper']}.d": _zeta_damper(self.zeta, k, m)}


class BearingHousing(Candidate):
    """Bearing-housing mass and compliance at the screw's thrust support (thesis Sec 3.5.2.3).

    ``support`` point (FE drive, ``(screw port, bearing)``): the grounded thrust bearing becomes the
    same bearing un-grounded, its housing side on a :class:`~components.housing.Housing` -- mass ``m``
    on an axial fastener spring ``k`` with 5 % of critical damping to the frame, radial and tilt
    potentials held (no free DOF besides the axial one). ``connection`` point (lumped drive,
    ``(a, b)``): a spring ``k`` (+ damper) in series at ``a``--``b`` and the mass ``m`` at ``b``.
    """

    zeta = 0.05

    def __init__(self):
        super().__init__(
            name="bearing_housing", title="bearing-housing mass and compliance", role="screw_support",
            parameters=[CandidateParameter("m", "kg", 0.5, 100.0, 10.0, 1.3, "housing mass"),
                        CandidateParameter("k", "N/m", 1e7, 5e10, 1e9, 2.0, "axial fastener (housing) stiffness")],
            signature="the axial mode seen from both motor and table is softer than modelled and a second "
                      "axial mode appears above it; both FRFs change near the axial modes",
            group="bearing_housing", kinds=("support", "connection"))

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Damper, Housing, Mass, Spring
        from bscomp.components._joint6 import PartialJoint6

        d0 = _zeta_damper(self.zeta, 1e9, 10.0)
        if point.kind == "support":
            bearing = point.ports[1]
            comp = e.s.component(bearing)
            if not isinstance(comp, PartialJoint6) or not comp.grounded:
                raise ModelDefinitionError(f"{self.name}: the 'screw_support' point names '{bearing}', which is "
                                           f"not a grounded 6-DOF joint ({type(comp).__name__})")
            e.replace(bearing, type(comp), grounded=False, **_params_of(comp))
            h = e.unique("housing")
            e.add(h, Housing, m=10.0, c=1e9, d=d0)
            e.connect(f"{bearing}.node_b", f"{h}.node")
            return {"mass": f"{h}.m", "stiffness": f"{h}.c", "damping": f"{h}.d"}
        a, b = point.ports[:2]
        spring, loss, mass = e.unique("housing_spring"), e.unique("housing_loss"), e.unique("housing_mass")
        insert_series(e, spring, Spring, {"c": 1e9}, a, b)
        e.add(loss, Damper, d=d0)
        e.add(mass, Mass, m=10.0)
        e.connect(f"{spring}.flange_a", f"{loss}.flange_a")
        e.connect(f"{spring}.flange_b", f"{loss}.flange_b")
        e.connect(f"{mass}.flange_a", f"{spring}.flange_b")
        return {"mass": f"{mass}.m", "stiffness": f"{spring}.c", "damping": f"{loss}.d"}

    def _overrides(self, values, state):
        m, k = values["m"], values["k"]
        return {state["mass"]: m, state["stiffness"]: k, state["damping"]: _zeta_damper(self.zeta, k, m)}


class ParameterScale(Candidate):
    """Re-scale an existing parameter (e.g. a coupling stiffness error). Not a missing effect: a wrong
    value, fixed by re-calibration. Applicable wherever the parameter exists."""

    def __init__(self, parameter: str, lower: float = 0.3, upper: float = 3.0, title: str = ""):
        super().__init__(
            name=f"scale:{parameter}", title=title or f"error in {parameter}", role="coupling",
            parameters=[CandidateParameter("factor", "1", lower, upper, 1.0, 0.3, f"factor on {parameter}")],
            signature=f"a mis-set {parameter}: the modes it governs sit at the wrong frequencies",
            group=f"scale:{parameter}", is_effect=False, kinds=("parameter",))
        self.parameter = parameter
        self.degenerate_with = parameter

    def _resolve(self, system):
        try:
            system.get(self.parameter)
        except UnknownNameError as exc:
            raise NotApplicable(f"{self.name}: '{system.name}' has no parameter '{self.parameter}' ({exc})") from None
        return None, InsertionPoint("coupling", "parameter", parameters=(self.parameter,))

    def _edit(self, e, point, vi, for_engine):
        name = point.parameters[0]
        return {"parameter": name, "base": float(e.s.get(name))}

    def _overrides(self, values, state):
        return {state["parameter"]: state["base"] * values["factor"]}


class CouplingStiffness(ParameterScale):
    """Coupling stiffness: a factor on the parameter the ``coupling`` point names (``coupling.k_T`` on
    the FE test bed, ``coupling.c`` on the lumped drive). Degenerate with that parameter: skipped by a
    diagnosis that re-calibrates it (:meth:`degenerate`)."""

    def __init__(self, lower: float = 0.2, upper: float = 5.0):
        Candidate.__init__(
            self, name="coupling_stiffness", title="coupling stiffness differs from its nominal value",
            role="coupling",
            parameters=[CandidateParameter("factor", "1", lower, upper, 1.0, 0.8, "factor on the coupling stiffness")],
            signature="the coupling (torsion) mode sits at another frequency than modelled, the axial mode "
                      "hardly moves; the motor-speed FRF shows it most",
            group="coupling", is_effect=True, kinds=("parameter",))
        self.parameter = None
        self.degenerate_with = None

    _resolve = Candidate._resolve

    def degenerate(self, system) -> set:
        try:
            return set(self.applicable(system).parameters[:1])
        except NotApplicable:
            return set()


class MissingInertia(Candidate):
    """A rotating inertia the model lacks at the motor (tachometer, brake, encoder disc)."""

    def __init__(self):
        super().__init__(
            name="missing_inertia", title="missing inertia at the motor", role="rotor",
            parameters=[CandidateParameter("J", "kg.m2", 1e-5, 1e-2, 1e-3, 1.5, "added inertia")],
            signature="the motor-speed FRF level at low frequency (rigid-body inertia) and the coupling mode "
                      "frequency are both lower than modelled; accelerations after each voltage step too small",
            group="rotor_inertia", kinds=("rotational",))

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Inertia

        name = e.unique("extra_inertia")
        e.add(name, Inertia, J=1e-3)
        e.connect(f"{name}.flange_a", point.ports[0])
        return {"inertia": name}

    def _overrides(self, values, state):
        return {f"{state['inertia']}.J": values["J"]}


class MissingMass(Candidate):
    """A mass the model lacks on the table (fixture, workpiece). Degenerate with re-calibrating the
    table's mass: skipped by :func:`~bscomp.validate.diagnose.diagnose` when that is uncertain."""

    def __init__(self):
        super().__init__(
            name="missing_mass", title="missing mass on the table", role="table",
            parameters=[CandidateParameter("m", "kg", 0.5, 500.0, 20.0, 1.5, "added mass")],
            signature="the rigid-body inertia and the table-side axial mode are both lower than measured",
            group="table_mass", kinds=("attach",))
        self.degenerate_with = "table.m"

    def degenerate(self, system) -> set:
        try:
            comp = self.applicable(system).ports[0].split(".", 1)[0]
        except NotApplicable:
            return set()
        return {f"{comp}.m"} if "m" in system.component(comp).parameters() else set()

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Mass

        name = e.unique("extra_mass")
        e.add(name, Mass, m=20.0)
        e.connect(f"{name}.flange_a", point.ports[0])
        return {"mass": name}

    def _overrides(self, values, state):
        return {f"{state['mass']}.m": values["m"]}


class AddedModalDamping:
    """System-level damping: a base option with ``modal_ratios`` plus ``zeta`` on every elastic mode.

    Wraps e.g. :class:`~bscomp.systems.testbed.DriveModalDamping`; rigid-body modes stay undamped
    (Sec 5.2.2.1). The matrix follows Eq A.10-A.15 (:func:`bscomp.damping.modal_damping_matrix`).
    """

    needs_coordinates = True

    def __init__(self, base, zeta: float):
        self.base = base
        self.zeta = float(zeta)

    def modal_ratios(self, lam, phi, M, coordinates=None) -> np.ndarray:
        if getattr(self.base, "needs_coordinates", False):
            z = np.asarray(self.base.modal_ratios(lam, phi, M, coordinates), float)
        else:
            z = np.asarray(self.base.modal_ratios(lam, phi, M), float)
        rigid = np.abs(lam) <= 1e-9 * np.max(np.abs(lam))
        z = z + self.zeta
        z[rigid] = 0.0
        return z

    def matrix(self, M, K, coordinates=None):
        import scipy.linalg as sla

        from bscomp.damping import modal_damping_matrix

        Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
        Kd = K.toarray() if hasattr(K, "toarray") else np.asarray(K)
        lam, phi = sla.eigh(Kd, Md)
        rigid = np.abs(lam) <= 1e-9 * np.max(np.abs(lam))
        z = self.modal_ratios(lam, phi, Md, coordinates)
        return modal_damping_matrix(Md, Kd, z, n_rigid=int(rigid.sum()))

    def __repr__(self):
        return f"AddedModalDamping({self.base!r}, zeta={self.zeta:g})"


class ExtraDamping(Candidate):
    """Extra damping of every elastic mode (the ``structure`` point).

    On a drive with system-level modal damping (``system.damping`` with ``modal_ratios``, e.g. the FE
    test bed's :class:`~bscomp.systems.testbed.DriveModalDamping`): ``zeta`` added to every elastic
    mode's ratio (:class:`AddedModalDamping`); an evaluation engine gets it as the hook
    ``{"extra_modal_damping": zeta}``. Otherwise (lumped drive) stiffness-proportional: a damper
    ``d = beta c`` beside every spring, so mode *i* gains ``zeta_i = zeta (f_i / f_1)`` with ``f_1`` the
    first elastic mode of the nominal model.
    """

    def __init__(self, f1: float = 117.7):
        super().__init__(
            name="extra_damping", title="extra modal damping", role="structure",
            parameters=[CandidateParameter("zeta", "1", 1e-3, 0.3, 0.02, 1.0, "added damping ratio (at f_1)")],
            signature="resonance peaks lower and broader than modelled at unchanged frequencies; ringing after "
                      "each step dies out faster than the model's",
            group="damping", kinds=("all",))
        self.f1 = f1

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Damper, Spring, TorsionalDamper, TorsionalSpring

        base = e.s.damping
        if base is not None and hasattr(base, "modal_ratios"):
            if not for_engine:
                e.s.damping = AddedModalDamping(base, self.parameters[0].median)
            return {"mode": "modal", "engine": bool(for_engine)}
        effects = {n for st in (getattr(e.s, "_effect_state", {}) or {}).values() for n in st.get("added", ())}
        springs = [(p, c) for p, c in e.s.leaves() if isinstance(c, (Spring, TorsionalSpring))
                   and p.split(".")[0] not in effects]
        if not springs:
            raise NotApplicable(f"{self.name}: '{e.s.name}' has neither modal damping (system.damping with "
                                "modal_ratios) nor springs to put dampers beside")
        dampers = {}
        for path, comp in springs:
            name = e.unique(f"extra_loss_{path.replace('.', '_')}")
            e.add(name, Damper if isinstance(comp, Spring) else TorsionalDamper, d=0.0)
            e.connect(f"{name}.flange_a", f"{path}.flange_a")
            e.connect(f"{name}.flange_b", f"{path}.flange_b")
            dampers[name] = float(comp.get("c"))
        return {"mode": "springs", "dampers": dampers}

    def _overrides(self, values, state):
        if state["mode"] == "modal":
            return {}
        beta = 2 * values["zeta"] / (2 * math.pi * self.f1)
        return {f"{name}.d": beta * c for name, c in state["dampers"].items()}

    def _assign_extra(self, system, values, state):
        if state["mode"] == "modal" and isinstance(system.damping, AddedModalDamping):
            system.damping.zeta = float(values["zeta"])

    def _extra_code(self, values, state):
        if state["mode"] != "modal":
            return []
        return ["from bscomp.validate.candidates import AddedModalDamping",
                f"s.damping = AddedModalDamping(s.damping, zeta={values['zeta']:.10g})"]

    def engine_hooks(self, values, system=None):
        if system is not None and _state(system, self).get("mode") != "modal":
            return {}
        return {"extra_modal_damping": float(values["zeta"])}


class AmplifierDelay(Candidate):
    """D/A converter + amplifier latency ``T`` in the signal line of the ``amplifier`` point.

    In the model: a Padé delay (:class:`~components.pade_delay.PadeDelay`, order 2) inserted in the line,
    so an updated System runs anywhere. An evaluation engine applies the delay exactly instead
    (``exact_delay``; ``e^{-j omega T}`` on FRFs, a shift of the input in time) from
    :meth:`engine_hooks`, with ``structure(..., for_engine=True)`` leaving the model unchanged.
    """

    exact_delay = True

    def __init__(self, order: int = 2):
        super().__init__(
            name="amplifier_delay", title="amplifier / D/A time delay", role="amplifier",
            parameters=[CandidateParameter("T", "s", 1e-5, 5e-3, 3e-4, 1.2, "time delay")],
            signature="phase lag growing linearly with frequency in every FRF at unchanged magnitude; the "
                      "response to each voltage step starts late",
            group="delay", kinds=("connection",))
        self.order = order

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components.pade_delay import PadeDelay

        if for_engine:
            return {"delay": None}
        a, b = point.ports[:2]
        name = e.unique("delay")
        insert_series(e, name, PadeDelay, {"order": self.order, "T": 3e-4}, a, b, ports=("u", "y"))
        return {"delay": name}

    def _overrides(self, values, state):
        return {} if state["delay"] is None else {f"{state['delay']}.T": values["T"]}

    def engine_hooks(self, values, system=None):
        return {"input_delay": float(values["T"])}


# ---- nonlinear effects (time series only) --------------------------------------------------------------
V_REG = 5e-4
"""Regularisation velocity [m/s] of the friction candidates (see components/coulomb_friction.py)."""


def _ground(e, point, vi) -> str:
    g = point.ground or (vi.ground if vi is not None else None)
    if g is not None:
        return g
    from bscomp.components import Fixed

    return e.add(e.unique("effect_ground"), Fixed) + ".flange"


class GuidewayFriction(Candidate):
    """Coulomb friction at the guideways (thesis Eq 5.7, Table 5.2: 2066 N) between the ``table_guide``
    node and the ground; the drive's own viscous term ``B v`` stays where it is (on the table or the
    motor), so the friction element adds only ``F_c``."""

    def __init__(self):
        super().__init__(
            name="guideway_friction", title="Coulomb friction at the guideways", role="table_guide",
            parameters=[CandidateParameter("F_c", "N", 10.0, 2e4, 1000.0, 1.5, "Coulomb force")],
            signature="residual correlates with sign(table velocity): the model moves too far and too fast, "
                      "errors jump at every velocity reversal and the table position drifts",
            nonlinear=True, group="guideway_friction", kinds=("attach", "connection"))

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import CoulombFriction

        g = _ground(e, point, vi)
        name = e.add(e.unique("friction"), CoulombFriction, F_c_pos=1000.0, F_c_neg=1000.0, v_reg=V_REG)
        e.connect(f"{name}.flange_a", g)
        e.connect(f"{name}.flange_b", point.ports[0])
        return {"friction": name}

    def _overrides(self, values, state):
        f = state["friction"]
        return {f"{f}.F_c_pos": values["F_c"], f"{f}.F_c_neg": values["F_c"]}


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
        from bscomp.components import StribeckFriction

        g = _ground(e, point, vi)
        name = e.add(e.unique("friction"), StribeckFriction, F_s_pos=300.0, F_s_neg=300.0, F_c_pos=1000.0,
                     F_c_neg=1000.0, v1_pos=5e-3, v1_neg=5e-3, v2_pos=V_REG, v2_neg=V_REG, v_reg=V_REG)
        e.connect(f"{name}.flange_a", g)
        e.connect(f"{name}.flange_b", point.ports[0])
        return {"friction": name}

    def _overrides(self, values, state):
        f = state["friction"]
        return {f"{f}.F_c_pos": values["F_c"], f"{f}.F_c_neg": values["F_c"],
                f"{f}.F_s_pos": values["F_s"], f"{f}.F_s_neg": values["F_s"]}


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

    def _gap(self, b):
        return {"b": b, "s_rel0": -b / 2, "eps": self.eps_fraction * b}

    def _edit(self, e, point, vi, for_engine):
        from bscomp.components import Backlash, Spring

        b0 = self.parameters[0].median
        ports = point.ports
        if len(ports) >= 2 and all("." in p for p in ports[:2]):
            a, b = ports[:2]
            inner = [] if connected(e.s, a, b) else between(e.s, a, b)
            springs = [n for n in inner if type(e.s.component(n)) is Spring]
            if springs:   # a dead zone on the joint already there
                name = springs[0]
                e.replace(name, Backlash, c=float(e.s.get(f"{name}.c")), d=0.0, **self._gap(b0))
                return {"element": name}
            c = float(e.s.get(point.parameters[0])) if point.parameters else self.contact_stiffness
            name = e.unique("sn_backlash")
            insert_series(e, name, Backlash, {"c": c, "d": self.contact_damping, **self._gap(b0)}, a, b)
            return {"element": name}
        name = ports[0]
        c = float(e.s.get(f"{name}.c"))
        d = float(e.s.get(f"{ports[1]}.d")) if len(ports) > 1 else 0.0
        e.replace(name, Backlash, c=c, d=d, **self._gap(b0))
        if len(ports) > 1:
            e.remove(ports[1])
        return {"element": name}

    def _overrides(self, values, state):
        return {f"{state['element']}.{k}": v for k, v in self._gap(values["b"]).items()}


def default_candidates() -> list:
    """The library of missing effects (the thesis's Sec 3.5 guesses), in a fixed order."""
    return [NutTableJoint(), TableSubassembly(), BearingHousing(), CouplingStiffness(), MissingInertia(),
            MissingMass(), GuidewayFriction(), StribeckGuidewayFriction(), ScrewNutBacklash(), AmplifierDelay(),
            ExtraDamping()]
