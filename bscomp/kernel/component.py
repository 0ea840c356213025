"""Component base class: parameters, variables, ports and equations.

A component file declares, in this order: ports, parameters, variables, then the methods that give its
physics. The kernel (:func:`bscomp.flatten`) calls these methods once per flattening with CasADi
symbols bound to every declared name, so equations read like the maths::

    class Spring(PartialCompliant):
        c = Parameter(unit="N/m", positive=True, doc="spring constant")
        s_rel0 = Parameter(0.0, unit="m", doc="unstretched length")

        def equations(self):
            return [self.f - self.c * (self.s_rel - self.s_rel0)]

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
from dataclasses import dataclass
from typing import Any

import numpy as np

from bscomp.errors import ModelDefinitionError, ParameterError, UnknownNameError
from bscomp.kernel.ports import PortSpec

__all__ = ["Parameter", "Variable", "Component", "LinearStructure", "Constraint", "PortRef"]


class Parameter:
    """A named, unit-carrying parameter of a component (a descriptor).

    Parameters
    ----------
    default : float, array or None
        Default value; ``None`` means the user must give one.
    unit : str
        SI unit, e.g. ``"kg"``, ``"N/m"``, ``"N.m/rad"``.
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

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        ctx = obj.__dict__.get("_ctx")
        if ctx is not None:
            return ctx.params[self.name]
        obj.__dict__.setdefault("_read_params", set()).add(self.name)
        return obj._values[self.name]

    def __set__(self, obj, value):
        obj._values[self.name] = self.validate(value, obj)

    def validate(self, value, owner=None):
        """Check a value against the bounds; return it as float or float array."""
        where = f"{owner._display_name()}.{self.name}" if owner is not None else self.name
        if value is None:
            raise ParameterError(f"parameter {where} [{self.unit}] has no value: give one, e.g. "
                                 f"{type(owner).__name__}({self.name}=...) or system.set('{where}', ...)")
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"parameter {where} [{self.unit}] must be a number, got {value!r}") from exc
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
    def __init__(self):
        self.params: dict = {}
        self.vars: dict = {}
        self.dvars: dict = {}
        self.ports: dict = {}
        self.der_pairs: list = []  # (symbol, derivative symbol)


class Component:
    """Base class of every physical part. See the module docstring for what a subclass defines."""

    def __init__(self, **params):
        self._values = {}
        self._ctx = None
        self._name = None
        self._parent = None
        for pname, p in self.parameters().items():
            if pname in params:
                setattr(self, pname, params.pop(pname))
            elif p.default is not None:
                self._values[pname] = p.validate(p.default, self)
            else:
                self._values[pname] = None
        if params:
            raise UnknownNameError(
                f"{type(self).__name__} has no parameter(s) {sorted(params)}; "
                f"its parameters are {sorted(self.parameters())}")

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
        """Time derivative of an expression of this component's potentials and variables."""
        import casadi as ca
        ctx = self._ctx
        if ctx is None:
            raise ModelDefinitionError("der() can only be used while the system is flattened")
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
        """Set a parameter (validated against its bounds)."""
        params = self.parameters()
        if name not in params:
            raise UnknownNameError(f"{self._display_name()} ({type(self).__name__}) has no parameter '{name}'; "
                                   f"it has {sorted(params)}")
        setattr(self, name, value)
        return self

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


