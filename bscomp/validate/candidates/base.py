"""The candidate-effect base: free parameters with priors, applicability, recorded edits, code lines.

See :mod:`bscomp.validate.candidates` for the library and the two-step application
(:meth:`Candidate.structure`, then :meth:`Candidate.overrides`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import UnknownNameError
from bscomp.kernel.interface import InsertionPoint, NotApplicable, ValidationInterface, interface_of
from bscomp.validate.candidates._edits import Edits

__all__ = ["CandidateParameter", "Candidate", "mass_spring_starts"]


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
    linear : bool
        True when the parameter shows in the small-signal (FRF) model of a nonlinear effect (a contact
        stiffness): diagnose then takes its screening value from the FRFs before scanning the rest.
    """

    name: str
    unit: str
    lower: float
    upper: float
    median: float
    sigma_log: float = 1.0
    doc: str = ""
    linear: bool = False

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
        Insertion-point role the effect goes to (:data:`bscomp.kernel.interface.ROLES`); ``where`` is the same.
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
    #: What a nonlinear effect's slope at rest is, in words (``"friction stuck: F_c / v_reg"``), for the message on
    #: FRFs measured where it does not leave it (:func:`~bscomp.validate.amplitude.stuck_note`)
    slope_at_rest = ""
    #: True for an effect a motor torque ripple (no candidate has one) can imitate over a short stroke: accepted only
    #: when the residual it leaves is not periodic in the motor angle (:func:`~bscomp.validate.acceptance.choose`)
    ripple_alike = False

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

    def mode_starts(self, medians, system=None) -> list:
        """Extra screening points of a linear effect that adds a lightly damped mode: ``[]`` here; a mass on a
        spring gives points along the mode's frequency (:func:`mass_spring_starts`). ``system``: the nominal model
        (where the mode depends on its values)."""
        return []

    def mode_hz(self, values: dict, system, known: dict | None = None) -> float | None:
        """The frequency [Hz] of the mode this effect adds at ``values`` in ``system`` (``known``: re-calibrated
        values of its parameters, dotted names), estimated from the effect's own parameters, or None (an effect that
        adds no mode of its own). :func:`~bscomp.validate.conclusion.conclusion` says when it lies above the
        measured FRFs: then only the time series saw the effect."""
        return None

    def apply(self, system, **values):
        """A copy of ``system`` with this effect added and its parameters set (prior medians for any
        not given)."""
        v = self.check({**self.medians(), **values})
        s = self.structure(system)
        self.assign(s, v)
        return s

    def code(self, values: dict, system=None) -> str:
        return "\n".join(self.code_lines(values, system))

    def added(self, system) -> list:
        """Names of the components this effect added to ``system`` (one returned by :meth:`structure` or
        :meth:`apply`)."""
        return list(_state(system, self).get("added", ()))

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


#: The band :func:`mass_spring_starts` screens [Hz] and its points per decade (neighbours 10 % apart in frequency:
#: a mode damped at a few % improves an FRF only within about that of the measured one).
MODE_BAND, MODE_POINTS_PER_DECADE = (20.0, 2000.0), 24


def mass_spring_starts(cand, medians, k_parallel: float = 0.0) -> list:
    """Screening points of a mass ``m`` on a spring ``k`` (the first two parameters) along its frequency
    ``sqrt(k/m) / 2 pi`` over :data:`MODE_BAND`, the mass at ``medians[0]`` (the refinement fits it; the frequency
    is what an FRF sees first), the rest at ``medians``: the 5 x 5 grid over both priors steps the frequency by
    ~1.8x, so a lightly damped part's mode between two of its points improved nothing and the refinement started
    from a rigid part (a 38 kg part at 205 Hz, ``benchmarks/diagnose_table.py --seed 2203 --case
    joint_friction``). Inside the spring's prior bounds. ``k_parallel``: a stiffness in parallel with ``k`` on the
    mass (a housing's bearing), so the frequency is ``sqrt((k + k_parallel) / m) / 2 pi``."""
    pk = cand.parameters[1]
    m = medians[0]
    n = int(round(MODE_POINTS_PER_DECADE * math.log10(MODE_BAND[1] / MODE_BAND[0]))) + 1
    ks = [m * (2.0 * math.pi * f) ** 2 - k_parallel for f in np.geomspace(*MODE_BAND, n)]
    return [(m, k, *medians[2:]) for k in ks if pk.lower <= k <= pk.upper]


def _zeta_damper(zeta, k, m):
    """Viscous coefficient of ``zeta`` of critical for a mass ``m`` on a spring ``k``."""
    return 2.0 * zeta * math.sqrt(k * m)


def _params_of(comp) -> dict:
    out = {}
    for n in comp.parameters():
        v = comp.get(n)
        out[n] = np.asarray(v).tolist() if np.ndim(v) else float(v)
    return out
