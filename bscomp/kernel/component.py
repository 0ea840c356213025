"""Component base class: parameters, variables, ports and equations.

A component file declares, in this order: ports, parameters, variables, then the methods that give its
physics. The kernel (:func:`bscomp.flatten`) calls these methods once per flattening with CasADi
symbols bound to every declared name, so equations read like the maths::

    class Spring(PartialCompliant):
        c = Parameter(unit="N/m", positive=True, doc="spring constant")
        s_rel0 = Parameter(0.0, unit="m", doc="unstretched length")

        def equations(self):
            return [self.f - self.c * (self.s_rel - self.s_rel0)]

Parameters are declared once: the unit string is parsed when the class is created (a typo is a
:class:`~bscomp.errors.ModelDefinitionError`), the class docstring's numpydoc ``Parameters`` section is
generated from the declarations (name, unit, bounds, default, ``doc``), and values may be given as
``"<number> <unit>"`` strings converted to the declared unit (:meth:`Parameter.from_text`).

What a component may contribute
--------------------------------
``equations()``
    residuals (CasADi SX expressions that must vanish). They define, explicitly, every **port flow**
    that is not a constraint reaction (``self.flange_b.f - f``), every **signal output**
    (``self.y.y - expr``), and give one equation per **internal variable**. ``der(x)`` is the time
    derivative of any expression of potentials and variables; a variable whose derivative appears is
    a differential state, the others are algebraic.
``constraints()``
    ideal (workless) holonomic constraints, affine in the port potentials: rigid attachment
    ``flange_b.s - flange_a.s``, an ideal lead screw ``flange_b.s - r_g*flange_a.phi`` (Modelica's
    ``IdealGearR2T``), a fixed point ``flange.s - s0``. Their reaction flows ``A^T lambda`` are
    added by the kernel, and the constraint is eliminated from the DAE (no index problem).
``structure()``
    linear structural blocks: numeric sparse ``M``, ``C``, ``K`` acting on a list of port potentials
    (``"node3.w"``...). A 300-DOF beam stays three sparse matrices. Called with numeric parameter
    values; the parameters it reads become *structural* (changing them re-flattens).
``observables()``
    named expressions users can ask for as outputs (``table.a``).
"""

from __future__ import annotations

import copy
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any

import numpy as np

from bscomp.errors import ArgumentTypeError, ModelDefinitionError, ParameterError, UnknownNameError
from bscomp.kernel.docstrings import _format_default, parameters_docstring
from bscomp.kernel.ports import PortSpec
from bscomp.kernel.units import Unit, UnitSyntaxError, parse_quantity, parse_unit, same_dimension

__all__ = ["Parameter", "Variable", "Component", "LinearStructure", "Constraint", "PortRef", "parameters_docstring"]

BUILDING: ContextVar = ContextVar("bscomp_building", default=None)
"""``(component, path)`` whose equations the kernel is building (templates), else None."""


def _foreign(obj, what: str) -> None:
    """Refuse a symbol of component ``obj`` read while another component's equations are built."""
    cur = BUILDING.get()
    if cur is None or cur[0] is obj:
        return
    raise ModelDefinitionError(
        f"the equations of component '{cur[1]}' ({type(cur[0]).__name__}) read {what} of another component "
        f"'{obj._display_name()}' ({type(obj).__name__}): a component's equations may use only its own ports, "
        "variables and parameters; connect the two through ports (a flange, or a RealOutput -> RealInput signal)")


class Parameter:
    """A named, unit-carrying parameter of a component (a descriptor).

    The unit is parsed by :func:`bscomp.kernel.units.parse_unit` when the component class is created (a
    typo raises :class:`~bscomp.errors.ModelDefinitionError`), and the class docstring gets a numpydoc
    ``Parameters`` entry made of the name, unit, bounds, default and ``doc``. A value may be given as a
    ``"<number> <unit>"`` string (``"250 kg"``, ``"20.7 N/um"``): it is converted to the declared unit
    after a dimension check.

    Parameters
    ----------
    default : float, array or None
        Default value; ``None`` means the user must give one.
    unit : str
        SI unit, e.g. ``"kg"``, ``"N/m"``, ``"N.m/rad"``; ``"1"`` for a dimensionless number. A matrix whose
        entries have different units lists them separated by ``|`` (``"N/m|N|N.m/rad"``).
    doc : str
        One-line description.
    min, max : float, optional
        Inclusive physical bounds.
    positive : bool
        Strictly positive (masses, stiffnesses, lengths).
    """

    def __init__(self, default=None, unit: str = "", doc: str = "", min: float | None = None,
                 max: float | None = None, positive: bool = False):
        self.default = default
        self.unit = unit
        self.doc = doc
        self.min = min
        self.max = max
        self.positive = positive
        self.name = ""
        self._units: tuple | None = None

    @property
    def scalar(self) -> bool:
        """True for a parameter that takes one number: its default is a number (or it has none) and its unit is
        one unit, not a ``|``-separated list of matrix entries. Vector and matrix parameters declare an
        array default or such a list (``Bushing.K``, ``RigidBody.I``)."""
        return np.ndim(self.default) == 0 and "|" not in str(self.unit)

    @property
    def units(self) -> tuple[Unit, ...]:
        """The declared unit, parsed (one :class:`~bscomp.kernel.units.Unit` per ``|``-separated entry)."""
        if self._units is None:
            self._units = tuple(parse_unit(u) for u in str(self.unit).split("|"))
        return self._units

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        ctx = obj.__dict__.get("_ctx")
        if ctx is not None:
            return ctx.params[self.name]
        _foreign(obj, f"parameter '{self.name}'")
        obj.__dict__.setdefault("_read_params", set()).add(self.name)
        return obj._values[self.name]

    def __set__(self, obj, value):
        obj.set(self.name, value)

    def validate(self, value, owner=None):
        """Check a value against the bounds; return it as float or float array.

        A string is read as ``"<number> <unit>"`` and converted to the declared unit (a bare number is in
        the declared unit already).
        """
        where = f"{owner._display_name()}.{self.name}" if owner is not None else self.name
        if value is None:
            raise ParameterError(f"parameter {where} [{self.unit}] has no value: give one, e.g. "
                                 f"{type(owner).__name__}({self.name}=...) or system.set('{where}', ...)")
        if isinstance(value, str):
            value = self.from_text(value, where)
        if isinstance(value, (bool, np.bool_, bytes, bytearray, dict, set)) or np.iscomplexobj(value):
            kind = "a bool" if isinstance(value, (bool, np.bool_)) else f"a {type(value).__name__}"
            raise ParameterError(f"parameter {where}{_class_of(owner)} [{self.unit}] must be a number, got "
                                 f"{value!r} ({kind})")
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"parameter {where} [{self.unit}] must be a number, got {value!r}") from exc
        if self.scalar and arr.ndim != 0:
            raise ParameterError(f"parameter {where}{_class_of(owner)} [{self.unit}] takes one real number, got "
                                 f"{value!r} "
                                 f"(shape {arr.shape}); give a single value, e.g. {self.name}=1.0")
        if not np.all(np.isfinite(arr)):
            raise ParameterError(f"parameter {where} [{self.unit}] is {value!r}: NaN and inf are not physical")
        if self.positive and np.any(arr <= 0):
            raise ParameterError(f"parameter {where} = {value!r} {self.unit} must be > 0 ({self.doc or 'physical'}"
                                 f" quantity); a zero or negative value is not physical")
        if self.min is not None and np.any(arr < self.min):
            raise ParameterError(f"parameter {where} = {value!r} {self.unit} is below its physical bound "
                                 f"{self.min} {self.unit}")
        if self.max is not None and np.any(arr > self.max):
            raise ParameterError(f"parameter {where} = {value!r} {self.unit} is above its physical bound "
                                 f"{self.max} {self.unit}")
        return float(arr) if arr.ndim == 0 else arr

    def from_text(self, text: str, where: str | None = None) -> float:
        """The value of ``"<number> <unit>"`` in the declared unit: ``"250 kg"`` -> 250.0 for ``unit="kg"``,
        ``"20.7 N/um"`` -> 2.07e7 for ``unit="N/m"``, ``"4.55 deg"`` -> 0.0794 for ``unit="rad"``.

        Raises :class:`~bscomp.errors.ParameterError` naming the parameter, the given and the expected
        unit when the text does not parse or its unit has another dimension (angles count: ``"100 Hz"``
        is not ``rad/s``).
        """
        where = where or self.name
        try:
            number, given = parse_quantity(text)
        except UnitSyntaxError as exc:
            raise ParameterError(f"parameter {where} [{self.unit}] must be a number or a '<number> <unit>' "
                                 f"string, got {text!r} ({exc}); e.g. '1 {self.units[0].text}'") from None
        if given is None:
            return number
        if len(self.units) != 1:
            raise ParameterError(f"parameter {where} has one unit per entry [{self.unit}]: give numbers in "
                                 f"those units, not the string {text!r}")
        declared = self.units[0]
        if not same_dimension(given, declared, angle=True):
            si = f" (SI {given.si})" if given.si != given.text else ""
            raise ParameterError(f"parameter {where}: {text!r} is given in '{given.text}'{si}, which is not a unit "
                                 f"of the dimension of its declared unit '{self.unit}'; give it in '{self.unit}' or a "
                                 "unit convertible to it")
        return number * given.scale / declared.scale

    def doc_entry(self) -> list[str]:
        """The numpydoc ``Parameters`` entry of this parameter (two lines: name and type, description)."""
        quals = [f"[{self.unit}]"]
        if self.positive:
            quals.append("> 0")
        if self.min is not None and self.max is not None:
            quals.append(f"in [{self.min:.6g}, {self.max:.6g}]")
        elif self.min is not None:
            quals.append(f">= {self.min:.6g}")
        elif self.max is not None:
            quals.append(f"<= {self.max:.6g}")
        if self.default is not None:
            quals.append(f"default {_format_default(self.default)}")
        return [f"{self.name} : {', '.join(quals)}", f"    {self.doc or '(no description)'}"]


def _class_of(owner) -> str:
    """`` (Mass)`` for a named component (its name alone does not say its class), else ``""``."""
    return f" ({type(owner).__name__})" if owner is not None and owner.__dict__.get("_name") else ""


class Variable:
    """An internal variable of a component (a descriptor).

    It is a differential state if ``der()`` of it appears in the component's equations, otherwise
    algebraic.

    Parameters
    ----------
    unit : str
    start : float
        Initial value (a guess for algebraic variables).
    doc : str
    """

    def __init__(self, unit: str = "", start: float = 0.0, doc: str = ""):
        self.unit = unit
        self.start = start
        self.doc = doc
        self.name = ""

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        ctx = obj.__dict__.get("_ctx")
        if ctx is None:
            _foreign(obj, f"variable '{self.name}'")
            raise ModelDefinitionError(
                f"variable {obj._display_name()}.{self.name} is symbolic: it only exists while the system is "
                "flattened (use it inside equations()/observables(), or read results from an analysis)")
        return ctx.vars[self.name]


@dataclass
class Constraint:
    """An ideal holonomic constraint ``expr = 0``, affine in port potentials.

    ``solve_for`` optionally names the potential to eliminate (a symbol appearing in ``expr``).
    """

    expr: Any
    solve_for: Any = None


@dataclass
class LinearStructure:
    """Linear structural block ``M dd'' + C dd' + K d = F`` on port potentials.

    Parameters
    ----------
    dofs : list of str
        ``"port.potential"`` for each row/column, e.g. ``["node0.w", "node0.tz", ...]``.
    M, C, K : array or scipy.sparse matrix, optional
        Square matrices of size ``len(dofs)``; missing ones are zero.
    """

    dofs: list
    M: Any = None
    C: Any = None
    K: Any = None


@dataclass(frozen=True)
class PortRef:
    """A reference to a port of a component in a system: ``component.port``."""

    component: "Component"
    port: str

    def __str__(self):
        return f"{self.component._display_name()}.{self.port}"


class _PortBinding:
    """Symbols of one port while a component is flattened (attribute access: ``flange.s``...)."""

    def __init__(self, spec: PortSpec, potentials, flows, derivs):
        self.spec = spec
        self._pot = dict(zip([n for n, _ in spec.kind.potentials], potentials))
        self._flow = dict(zip([n for n, _ in spec.kind.flows], flows))
        self._derivs = derivs

    def __getattr__(self, item):
        d = self.__dict__
        if item in d["_pot"]:
            return d["_pot"][item]
        if item in d["_flow"]:
            return d["_flow"][item]
        import casadi as ca
        if item == "d" and len(d["_pot"]) == 6:
            return ca.vertcat(*d["_pot"].values())
        if item == "F" and len(d["_flow"]) == 6:
            return ca.vertcat(*d["_flow"].values())
        raise AttributeError(f"port {d['spec'].name} of kind {d['spec'].kind.name} has no '{item}'")


class _Context:
    def __init__(self, path: str = ""):
        self.path = path     # the component's path in the system, for messages
        self.no_der: list = []  # (symbol, name): what der() cannot differentiate (flows, 2nd derivatives...)
        self.params: dict = {}
        self.vars: dict = {}
        self.dvars: dict = {}
        self.ports: dict = {}
        self.der_pairs: list = []  # (symbol, derivative symbol)


_KINDS = {Parameter: "Parameter", Variable: "Variable", PortSpec: "port"}


def _kind(obj) -> str | None:
    return next((k for t, k in _KINDS.items() if isinstance(obj, t)), None)


def _check_declarations(cls) -> None:
    """A declaration object bound to one name only; a name keeps its kind (Parameter, Variable, port)
    in subclasses (a Variable shadowing an inherited Parameter would be listed as both)."""
    seen = {}
    for name, obj in vars(cls).items():
        kind = _kind(obj)
        if kind is None:
            continue
        if id(obj) in seen:
            raise ModelDefinitionError(
                f"{cls.__name__}: one {kind} object is declared under two names, '{seen[id(obj)]}' and '{name}'; "
                f"a {'PortSpec' if kind == 'port' else kind} instance can be declared once: create one per name "
                f"(e.g. {name} = Flange(...))")
        seen[id(obj)] = name
        for base in cls.__mro__[1:]:
            inherited = _kind(vars(base).get(name))
            if inherited is not None and inherited != kind:
                raise ModelDefinitionError(
                    f"{cls.__name__}.{name} is declared as a {kind} but {base.__name__}.{name} is a {inherited}: a "
                    f"subclass cannot change what a declared name is; choose another name for the {kind}")


class Component:
    """Base class of every physical part. See the module docstring for what a subclass defines."""

    def __init_subclass__(cls, **kwargs):
        """Parse the units of the parameters the class declares and document every parameter (numpydoc)."""
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("_read_tracker"):   # bscomp.kernel.sharing's recording subclass: nothing to check
            return
        _check_declarations(cls)
        for name, p in vars(cls).items():
            if isinstance(p, Parameter):
                try:
                    _ = p.units
                except UnitSyntaxError as exc:
                    raise ModelDefinitionError(f"{cls.__name__}.{name}: unit {p.unit!r} is not a unit the library "
                                               f"reads ({exc})") from None
        cls.__doc__ = parameters_docstring(cls.__doc__, cls.parameters())

    def __init__(self, *args, **params):
        if args:
            names = list(self.parameters())
            example = f"{names[0]}={args[0]!r}" if names else "..."
            raise ArgumentTypeError(f"{type(self).__name__} takes its parameters by name, e.g. "
                                    f"{type(self).__name__}({example}); its parameters are {names}")
        self._values = {}
        self._ctx = None
        self._name = None
        self._parent = None
        for pname, p in self.parameters().items():
            if pname in params:
                self._values[pname] = p.validate(params.pop(pname), self)
            elif p.default is not None:
                self._values[pname] = p.validate(p.default, self)
            else:
                self._values[pname] = None
        if params:
            raise UnknownNameError(
                f"{type(self).__name__} has no parameter(s) {sorted(params)}; "
                f"its parameters are {sorted(self.parameters())}")
        self.check(dict(self._values))

    # ---- declarations -------------------------------------------------------------------------
    @classmethod
    def parameters(cls) -> dict[str, Parameter]:
        """Declared parameters, in declaration order (base classes first)."""
        return cls._collect(Parameter)

    @classmethod
    def variables(cls) -> dict[str, Variable]:
        return cls._collect(Variable)

    def ports(self) -> dict[str, PortSpec]:
        """Declared ports: class-level declarations plus ports added per instance (:meth:`add_port`)."""
        out = self._collect(PortSpec)
        out.update(self.__dict__.get("_extra_ports", {}))
        return out

    def add_port(self, name: str, spec: PortSpec) -> None:
        """Declare a port on this instance (e.g. one Node6 per FE node; call in ``__init__``).

        It is then reached as ``self.<name>`` like a class-level port.
        """
        extra = self.__dict__.setdefault("_extra_ports", {})
        if name in extra or name in self._collect(PortSpec) or name in self.parameters():
            raise ModelDefinitionError(f"{type(self).__name__} already has a port or parameter named '{name}'")
        if any(s is spec for s in self.ports().values()):
            raise ModelDefinitionError(f"{type(self).__name__}.add_port('{name}', ...): this PortSpec object is "
                                       f"already the port '{spec.name}'; a PortSpec instance can be declared once: "
                                       "create one per port (e.g. Node6(...) in the loop)")
        spec.name = name
        extra[name] = spec

    def __getattr__(self, item):
        extra = self.__dict__.get("_extra_ports")
        if extra is not None and item in extra:
            return self._port_instance(item)
        raise AttributeError(f"{type(self).__name__} has no attribute '{item}'")

    @classmethod
    def _collect(cls, kind):
        out = {}
        for klass in reversed(cls.__mro__):
            for k, v in vars(klass).items():
                if isinstance(v, kind):
                    out[k] = v
        return out

    # ---- physics (overridden by subclasses) ---------------------------------------------------
    def equations(self) -> list:
        """Residual equations (see module docstring)."""
        return []

    def connector_equations(self) -> list:
        """Equations a partial base class fixes once (flows of a compliant element...)."""
        return []

    def constraints(self) -> list:
        """Ideal holonomic constraints, affine in port potentials."""
        return []

    def structure(self) -> LinearStructure | None:
        """Linear structural block (numeric), or None."""
        return None

    def tangent(self) -> LinearStructure | None:
        """Optional: this component's exact linearization at rest (every port potential and rate zero) at
        the current parameter values, as a numeric block over its port potentials.

        A component whose equations are costly to re-linearize but whose tangent is cheap (e.g. a joint
        attached through position-dependent shape functions) provides it, and
        :func:`bscomp.linear.sweeps.position_sweep` then updates one linearization per parameter value instead
        of re-evaluating the whole model (checked against a full linearization once per sweep).
        """
        return None

    def observables(self) -> dict:
        """Named expressions available as outputs (``"a"`` -> ``component.a``)."""
        return {}

    # ---- helpers available inside equations ---------------------------------------------------
    def der(self, expr):
        """Time derivative of an expression of this component's port potentials (up to their second
        derivative: ``der(der(flange.s))``), variables (once) and parameters (constant).

        A flow, a signal, a third derivative or ``der(der(v))`` of a variable has no derivative the kernel
        knows: :class:`~bscomp.errors.ModelDefinitionError` (declare a Variable for the rate instead).
        """
        import casadi as ca
        ctx = self.__dict__.get("_ctx")
        if ctx is None:
            raise ModelDefinitionError(f"der() of component '{self._display_name()}' ({type(self).__name__}) can "
                                       "only be used inside equations()/observables(), while the system is flattened")
        try:
            expr = ca.SX(expr)
        except (NotImplementedError, TypeError) as exc:
            raise ModelDefinitionError(f"der() in component '{ctx.path or self._display_name()}' "
                                       f"({type(self).__name__}) takes an expression of its ports, variables and "
                                       f"parameters, got {type(expr).__name__} {expr!r}"[:400]) from exc
        if ctx.no_der and ca.depends_on(expr, ca.vertcat(*[s for s, _ in ctx.no_der])):
            bad = [n for s, n in ctx.no_der if ca.depends_on(expr, s)]
            raise ModelDefinitionError(
                f"der() in component '{ctx.path or self._display_name()}' ({type(self).__name__}) cannot "
                f"differentiate {str(expr)[:200]}: it depends on {bad[:6]}, which has no known derivative (a flow, a "
                "signal, a third derivative of a potential or a second one of a variable). der() differentiates "
                "port potentials up to der(der(port.s)), Variables once, and parameters (0). Declare a Variable "
                "for the quantity or its rate (e.g. v = Variable() with the equation 'v - der(flange.s)', or "
                "f = Variable() with 'flange.f - f') and differentiate that")
        syms = [a for a, _ in ctx.der_pairs]
        ders = [b for _, b in ctx.der_pairs]
        return ca.jtimes(expr, ca.vertcat(*syms), ca.vertcat(*ders))

    # ---- values -------------------------------------------------------------------------------
    def get(self, name: str):
        """Numeric value of a parameter."""
        if name not in self.parameters():
            raise UnknownNameError(f"{self._display_name()} ({type(self).__name__}) has no parameter '{name}'; "
                                   f"it has {sorted(self.parameters())}")
        return self._values[name]

    def set(self, name: str, value) -> "Component":
        """Set a parameter: validated against its bounds (:meth:`Parameter.validate`), then the whole set of
        would-be values against the cross-parameter conditions (:meth:`check`) before it is stored, so a
        rejected value leaves the component unchanged."""
        self._values.update(self.checked({name: value}))
        return self

    def checked(self, values: dict) -> dict:
        """``values`` (parameter name -> value) validated against their bounds and, with the component's other
        values, against :meth:`check`; returned converted, nothing stored (what :meth:`set` stores)."""
        params = self.parameters()
        out = {}
        for name, value in values.items():
            if name not in params:
                raise UnknownNameError(f"{self._display_name()} ({type(self).__name__}) has no parameter '{name}'; "
                                       f"it has {sorted(params)}")
            out[name] = params[name].validate(value, self)
        self.check({**self._values, **out})
        return out

    def check(self, values: dict) -> None:
        """Conditions between parameters (or on one that its bounds cannot say, such as ``lead != 0``).

        ``values`` maps every declared parameter name to its value (already checked against its own bounds,
        ``None`` for a required one not given yet, which this method skips). A violated condition raises
        :class:`~bscomp.errors.ParameterError` naming the component and the parameters and how to fix
        it. Called at the end of ``Component.__init__`` (instance state a check reads, such as a mesh,
        must be set before ``super().__init__``), by :meth:`set` (and so ``System.set`` and ``params=``
        overrides of a System) with the would-be values, and by :meth:`bscomp.Dae.parameter_vector` with
        a run's values. Default: no condition.
        """

    def _where(self, *names: str) -> str:
        """``'sat.y_min', 'sat.y_max' (Saturation)``: parameters by dotted name, for error messages."""
        return ", ".join(f"'{self._display_name()}.{n}'" for n in names) + _class_of(self)

    def copy(self):
        """A deep copy, detached from any system."""
        new = copy.deepcopy(self)
        new._parent = None
        return new

    def _display_name(self) -> str:
        return self._name or type(self).__name__

    def _port_instance(self, name):
        ctx = self.__dict__.get("_ctx")
        if ctx is not None:
            return ctx.ports[name]
        _foreign(self, f"port '{name}'")
        return PortRef(self, name)

    def describe(self) -> str:
        """Table of the ports and parameters with units."""
        lines = [f"{type(self).__name__} '{self._display_name()}'"]
        for n, p in self.ports().items():
            lines.append(f"  port  {n:<12} {p.kind.name:<10} {p.doc}")
        for n, p in self.parameters().items():
            v = self._values.get(n)
            vs = "None" if v is None else (f"{v:.6g}" if np.ndim(v) == 0 else f"array{np.shape(v)}")
            lines.append(f"  param {n:<12} = {vs:<12} [{p.unit}] {p.doc}")
        return "\n".join(lines)

    def __repr__(self):
        return f"<{type(self).__name__} {self._name or ''}>"


