"""System: a graph of named components and connections (and itself usable as a component).

>>> from bscomp import System
>>> from bscomp.components import Mass, Spring, Fixed
>>> s = System("oscillator")
>>> s.add("wall", Fixed()); s.add("k", Spring(c=1e4)); s.add("m", Mass(m=1.0))
>>> s.connect("wall.flange", "k.flange_a"); s.connect("k.flange_b", "m.flange_a")
>>> s.set("m.m", 2.0); s.set("k.c", "10 N/mm")
"""

from __future__ import annotations

import copy

from bscomp.errors import (
    ArgumentTypeError,
    DuplicateNameError,
    PortConnectionError,
    UnknownNameError,
    check_mapping,
)
from bscomp.kernel.component import Component, PortRef
from bscomp.kernel.ports import PortSpec

__all__ = ["System"]


class System:
    """A named graph of components, connections and exposed (outer) ports.

    Parameters
    ----------
    name : str
        Name of the system (used in messages and as default prefix when nested).
    """

    def __init__(self, name: str = "system"):
        self.name = name
        self._components: dict[str, Component | System] = {}
        self._connections: list[tuple[str, str]] = []
        self._exposed: dict[str, str] = {}
        self._name = None
        self._parent = None
        self.description = ""
        self.sources: dict[str, str] = {}
        self.damping = None  # system-level option: bscomp.kernel.damping.ModalDamping / RayleighDamping

    # ---- building -----------------------------------------------------------------------------
    def add(self, name: str, component):
        """Add a component (or a sub-system) under ``name``; returns it."""
        if not isinstance(name, str) or not name or "." in name or not name.replace("_", "a").isalnum():
            raise DuplicateNameError(f"invalid component name {name!r} in system '{self.name}': use letters, "
                                     "digits and '_' (dots separate hierarchy levels)")
        if name in self._components:
            raise DuplicateNameError(f"system '{self.name}' already has a component named '{name}' "
                                     f"({type(self._components[name]).__name__}); choose another name")
        self._check_new(f"system.add('{name}', ...)", component)
        component._name = name
        component._parent = self
        self._components[name] = component
        return component

    def _check_new(self, call: str, component) -> None:
        """``component`` may join this system: a Component or System in no system yet, not containing this one."""
        if not isinstance(component, (Component, System)):
            raise ArgumentTypeError(f"{call} needs a Component or System, got {type(component).__name__} "
                                    f"{component!r}"[:300])
        if component._parent is not None:
            raise DuplicateNameError(f"this {type(component).__name__} instance is already in system "
                                     f"'{component._parent.name}' as '{component._name}'; one instance cannot be "
                                     "in two places: use a copy (component.copy()) instead")
        obj = self
        while obj is not None:
            if obj is component:
                what = "cannot contain itself" if component is self else \
                    f"already contains '{self.name}': adding it there would make a cycle"
                raise DuplicateNameError(f"{call}: system '{component.name}' {what}; add a copy (system.copy()) "
                                         "instead")
            obj = obj._parent

    def connect(self, a, b) -> None:
        """Connect two ports: potentials equal, flows sum to zero (signals: output drives input).

        ``a`` and ``b`` are dotted names (``"nut.flange_a"``) or port references (``nut.flange_a``).
        """
        na, nb = self._port_name(a), self._port_name(b)
        sa, sb = self.port_spec(na), self.port_spec(nb)
        ka, kb = sa.kind, sb.kind
        if ka.is_signal != kb.is_signal or (not ka.is_signal and ka != kb):
            raise PortConnectionError(f"cannot connect '{na}' ({ka.name}) to '{nb}' ({kb.name}): ports of different "
                                      "kinds; insert a converter (IdealLeadScrew for rotary-linear, a sensor or "
                                      "a source for physical-signal)")
        if ka.is_signal:
            if ka.signal == "out" and kb.signal == "out":
                raise PortConnectionError(f"cannot connect two outputs '{na}' and '{nb}': a signal has one source")
            if sa.unit and sb.unit and sa.unit != sb.unit:
                raise PortConnectionError(f"cannot connect '{na}' [{sa.unit}] to '{nb}' [{sb.unit}]: units differ; "
                                          "insert a Gain that converts the unit")
        if na == nb:
            raise PortConnectionError(f"cannot connect port '{na}' to itself")
        self._connections.append((na, nb))

    # ---- editing (used by diagnose to insert candidate effects) -------------------------------
    def disconnect(self, a, b) -> None:
        """Remove the connection between ports ``a`` and ``b`` (made at this level, either order)."""
        na, nb = self._port_name(a), self._port_name(b)
        for i, (x, y) in enumerate(self._connections):
            if (x, y) in ((na, nb), (nb, na)):
                del self._connections[i]
                return
        raise UnknownNameError(f"system '{self.name}' has no connection between '{na}' and '{nb}'; connections: "
                               f"{self._connections[:20]}")

    def insert(self, name: str, component, between: tuple, ports: tuple = ("flange_a", "flange_b")):
        """Cut the connection ``between = (a, b)`` and put ``component`` in series:
        ``a -> name.ports[0]``, ``name.ports[1] -> b``. Returns the component."""
        a, b = between
        self.disconnect(a, b)
        self.add(name, component)
        self.connect(a, f"{name}.{ports[0]}")
        self.connect(f"{name}.{ports[1]}", b)
        return component

    def remove(self, name: str) -> None:
        """Remove a component and every connection of this level that touches it."""
        if name not in self._components:
            raise UnknownNameError(f"system '{self.name}' has no component '{name}'")
        comp = self._components.pop(name)
        comp._parent = None
        comp._name = None
        self._connections = [(x, y) for x, y in self._connections
                             if x.split(".")[0] != name and y.split(".")[0] != name]

    def replace(self, name: str, component) -> None:
        """Put ``component`` in place of component ``name``, keeping its connections (same port names)."""
        old = self._components.get(name)
        if old is None:
            raise UnknownNameError(f"system '{self.name}' has no component '{name}'")
        if component is old:
            return
        self._check_new(f"system.replace('{name}', ...)", component)
        ports = component.ports() if isinstance(component, Component) else \
            {**component._exposed, **component._components}
        missing = [p for a, b in self._connections for p in (a, b)
                   if p.split(".")[0] == name and p.split(".", 1)[1].split(".")[0] not in ports]
        if missing:
            raise UnknownNameError(f"cannot replace '{name}': the new {type(component).__name__} lacks ports used by "
                                   f"connections {missing}")
        old._parent = None
        old._name = None
        component._name = name
        component._parent = self
        self._components[name] = component

    def linear_equivalent(self) -> "System":
        """A copy in which every component that defines ``linear_equivalent()`` (friction, backlash) is
        replaced by its small-signal equivalent (removed when it returns None): what a measured FRF of a
        drive with friction and backlash is compared with."""
        new = self.copy()
        for path, comp in list(new.leaves()):
            f = getattr(comp, "linear_equivalent", None)
            if f is None:
                continue
            owner = new.component(path.rpartition(".")[0]) if "." in path else new
            rep = f()
            if rep is None:
                owner.remove(path.rpartition(".")[2])
            else:
                owner.replace(path.rpartition(".")[2], rep)
        # a ground that only anchored a removed element (friction to ground) goes with it
        for path, comp in list(new.leaves()):
            owner = new.component(path.rpartition(".")[0]) if "." in path else new
            leaf = path.rpartition(".")[2]
            if type(comp).__name__ in ("Fixed", "FixedRotational") and not any(
                    leaf in (a.split(".")[0], b.split(".")[0]) for a, b in owner._connections):
                owner.remove(leaf)
        return new

    def expose(self, outer: str, inner) -> None:
        """Make an inner port reachable as ``outer`` when this system is used as a component."""
        ni = self._port_name(inner)
        self.port_spec(ni)
        if outer in self._exposed or outer in self._components:
            raise DuplicateNameError(f"system '{self.name}' already uses the name '{outer}'")
        self._exposed[outer] = ni

    # ---- names --------------------------------------------------------------------------------
    def _port_name(self, p) -> str:
        if isinstance(p, str):
            return p
        if isinstance(p, PortRef):
            path = []
            obj = p.component
            while obj is not None and obj is not self:
                if obj._name is None:
                    raise UnknownNameError(f"port {p} belongs to a component that is not in system '{self.name}'")
                path.append(obj._name)
                obj = obj._parent
            if obj is not self:
                raise UnknownNameError(f"port {p} belongs to a component that is not in system '{self.name}'")
            return ".".join(reversed(path)) + "." + p.port
        raise ArgumentTypeError(f"a port is given as 'component.port' or component.port, got {p!r}")

    def component(self, dotted: str):
        """The component (or sub-system) at a dotted path."""
        obj = self
        for part in dotted.split("."):
            if not isinstance(obj, System) or part not in obj._components:
                have = sorted(obj._components) if isinstance(obj, System) else []
                raise UnknownNameError(f"system '{self.name}' has no component '{dotted}' (at '{part}'); "
                                       f"components here: {have}")
            obj = obj._components[part]
        return obj

    def resolve_port(self, dotted: str) -> tuple[Component, str, str]:
        """Resolve ``a.b.port`` (through exposed ports of sub-systems) to (leaf component, port, leaf path)."""
        parts = dotted.split(".")
        if len(parts) < 2:
            if dotted in self._exposed:
                return self.resolve_port(self._exposed[dotted])
            raise UnknownNameError(f"'{dotted}' is not a port name: write 'component.port'")
        comp = self._components.get(parts[0])
        if comp is None:
            raise UnknownNameError(f"system '{self.name}' has no component '{parts[0]}' (in port '{dotted}'); "
                                   f"components: {sorted(self._components)}")
        rest = ".".join(parts[1:])
        if isinstance(comp, System):
            leaf, port, path = comp.resolve_port(rest)
            return leaf, port, parts[0] + "." + path
        if len(parts) != 2 or parts[1] not in comp.ports():
            raise UnknownNameError(f"component '{parts[0]}' ({type(comp).__name__}) has no port '{rest}'; "
                                   f"its ports are {sorted(comp.ports())}")
        return comp, parts[1], parts[0]

    def port_spec(self, dotted: str) -> PortSpec:
        leaf, port, _ = self.resolve_port(dotted)
        return leaf.ports()[port]

    # ---- parameters ---------------------------------------------------------------------------
    def set(self, dotted: str, value) -> "System":
        """Override a parameter by dotted name, e.g. ``system.set("coupling.k_T", 45940)``.

        ``value`` is a number in the parameter's declared unit, or a ``"<number> <unit>"`` string converted
        to it (``system.set("table.m", "250 kg")``, ``system.set("sn.k_ball", "20.7 N/um")``); a unit of
        another dimension raises :class:`~bscomp.errors.ParameterError` naming the parameter, the given
        and the expected unit. The CLI's ``--set NAME=VALUE`` passes such strings through here.
        """
        if not isinstance(dotted, str):
            raise ArgumentTypeError(f"system.set() takes a parameter name 'component.parameter' (a str), got "
                                    f"{type(dotted).__name__} {dotted!r}")
        comp_path, _, pname = dotted.rpartition(".")
        if not comp_path:
            raise UnknownNameError(f"'{dotted}' is not a parameter name: write 'component.parameter'")
        comp = self.component(comp_path)
        if isinstance(comp, System):
            raise UnknownNameError(f"'{comp_path}' is a sub-system; name a parameter of one of its components "
                                   f"({sorted(comp._components)})")
        comp.set(pname, value)
        return self

    def get(self, dotted: str):
        comp_path, _, pname = dotted.rpartition(".")
        comp = self.component(comp_path)
        if isinstance(comp, System):
            raise UnknownNameError(f"'{dotted}' is not a parameter")
        return comp.get(pname)

    def parameters(self) -> dict[str, tuple]:
        """All parameters: dotted name -> (value, unit, description)."""
        out = {}
        for path, comp in self.leaves():
            for n, p in comp.parameters().items():
                out[f"{path}.{n}"] = (comp._values.get(n), p.unit, p.doc)
        return out

    def leaves(self, prefix: str = ""):
        """(dotted path, leaf component) pairs, depth first, in insertion order."""
        for name, comp in self._components.items():
            path = f"{prefix}{name}"
            if isinstance(comp, System):
                yield from comp.leaves(path + ".")
            else:
                yield path, comp

    def connections(self, prefix: str = ""):
        """All connections as pairs of leaf-port paths, including those inside sub-systems."""
        for name, comp in self._components.items():
            if isinstance(comp, System):
                yield from comp.connections(prefix + name + ".")
        for a, b in self._connections:
            _, pa, ca_ = self.resolve_port(a)
            _, pb, cb_ = self.resolve_port(b)
            yield f"{prefix}{ca_}.{pa}", f"{prefix}{cb_}.{pb}"

    def copy(self) -> "System":
        """A deep copy (components included), detached from any parent."""
        new = copy.deepcopy(self)
        new._parent = None
        new._name = None
        return new

    def with_parameters(self, overrides: dict | None = None) -> "System":
        """A copy with parameter overrides applied."""
        overrides = check_mapping("with_parameters(overrides)", overrides, "parameter values")
        new = self.copy()
        for k, v in overrides.items():
            new.set(k, v)
        return new

    def describe(self) -> str:
        lines = [f"System '{self.name}'" + (f": {self.description}" if self.description else "")]
        for path, comp in self.leaves():
            lines.append("  " + comp.describe().replace("\n", "\n  ").replace(f"'{comp._name}'", f"'{path}'", 1))
        for a, b in self.connections():
            lines.append(f"  connect({a}, {b})")
        return "\n".join(lines)

    def __repr__(self):
        return f"<System {self.name}: {len(self._components)} components, {len(self._connections)} connections>"
