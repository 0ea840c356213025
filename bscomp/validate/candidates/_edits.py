"""System edits made by candidate effects, recorded so that one code path both edits and writes code.

A candidate (:mod:`bscomp.validate.candidates`) edits a copy of a System through :class:`Edits`; the same
record renders as Python lines for a system file (:meth:`Edits.render`), so ``Candidate.code_lines``
reproduces ``Candidate.apply`` by construction. The helpers here also find where to cut a line that an
earlier effect has already cut (:func:`cut`, :func:`between`), and keep connection sets intact when a
component is removed.

Only top-level connections (``System._connections``) are edited: insertion points name ports of
top-level components.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ModelDefinitionError

__all__ = ["Edits", "nets", "between", "connected", "cut", "insert_series"]


def _lit(v) -> str:
    """A Python literal for a constructor argument."""
    if isinstance(v, (bool, np.bool_)):
        return repr(bool(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        t = f"{float(v):.10g}"
        if any(ch in t for ch in ".en"):                 # 0.0005, 5e-06, inf/nan
            return t
        if abs(v) < 1e5:
            return t + ".0"
        mant, _, exp = f"{float(v):.9e}".partition("e")  # 270000000 -> 2.7e+08
        return f"{mant.rstrip('0').rstrip('.')}e{exp}"
    if isinstance(v, np.ndarray):
        return repr(v.tolist())
    return repr(v)


class Edits:
    """Edits of ``system`` (in place), each recorded as it is made.

    Methods mirror :class:`~bscomp.kernel.system.System` (``add``, ``replace``, ``remove``, ``connect``,
    ``disconnect``); components are given as a class and keyword arguments so they can be written back.
    """

    def __init__(self, system):
        self.s = system
        self.ops: list = []
        self.added: list = []

    # ---- names ----------------------------------------------------------------------------------
    def unique(self, base: str, taken=()) -> str:
        """``base``, or ``base_2``, ``base_3``... : a component name not yet used (nor in ``taken``)."""
        name, i = base, 2
        while name in self.s._components or name in taken:
            name, i = f"{base}_{i}", i + 1
        return name

    # ---- edits ----------------------------------------------------------------------------------
    def add(self, name: str, cls, **kw) -> str:
        self.s.add(name, cls(**kw))
        self.ops.append(("add", name, cls, kw))
        self.added.append(name)
        return name

    def replace(self, name: str, cls, **kw) -> str:
        """Put a new ``cls(**kw)`` in place of component ``name`` (same name, same connections)."""
        self.s.replace(name, cls(**kw))
        self.ops.append(("replace", name, cls, kw))
        return name

    def connect(self, a: str, b: str) -> None:
        self.s.connect(a, b)
        self.ops.append(("connect", a, b))

    def disconnect(self, a: str, b: str) -> None:
        self.s.disconnect(a, b)
        self.ops.append(("disconnect", a, b))

    def remove(self, name: str) -> dict:
        """Remove component ``name``; the ports it linked stay linked (a removed port's partners are
        chained). Returns ``{port: [partners]}`` of the removed component."""
        partners = self.partners(name)
        self.s.remove(name)
        self.ops.append(("remove", name))
        for others in partners.values():
            for q in others[1:]:
                self.connect(others[0], q)
        return partners

    def partners(self, name: str) -> dict:
        """``{port: [ports directly connected to name.port]}`` over the top-level connections."""
        out: dict = {}
        for x, y in self.s._connections:
            for mine, other in ((x, y), (y, x)):
                if mine.split(".", 1)[0] == name and other.split(".", 1)[0] != name:
                    out.setdefault(mine.split(".", 1)[1], []).append(other)
        return out

    def rename(self, old: str, new: str, cls, **kw) -> str:
        """Replace component ``old`` by ``cls(**kw)`` named ``new``, on the same connection sets."""
        partners = self.remove(old)
        self.add(new, cls, **kw)
        for port, others in partners.items():
            self.connect(f"{new}.{port}", others[0])
        return new

    # ---- code ------------------------------------------------------------------------------------
    def render(self, overrides: dict) -> list:
        """Python lines (imports first) that repeat the edits on a system ``s``, with ``overrides``
        (dotted parameter values) written into the constructors where possible, else as ``s.set``."""
        ov = dict(overrides)
        last = {}
        for i, op in enumerate(self.ops):
            if op[0] in ("add", "replace"):
                last[op[1]] = i
        kws = {i: dict(op[3]) for i, op in enumerate(self.ops) if op[0] in ("add", "replace")}
        for key in list(ov):
            comp, _, pname = key.rpartition(".")
            i = last.get(comp)
            if i is not None and pname in self.ops[i][2].parameters():
                kws[i][pname] = ov.pop(key)
        imports: dict = {}
        lines = []
        for i, op in enumerate(self.ops):
            if op[0] in ("add", "replace"):
                cls = op[2]
                imports.setdefault(cls.__module__, set()).add(cls.__name__)
                args = ", ".join(f"{k}={_lit(v)}" for k, v in kws[i].items())
                lines.append(f's.{op[0]}("{op[1]}", {cls.__name__}({args}))')
            elif op[0] == "remove":
                lines.append(f's.remove("{op[1]}")')
            else:
                lines.append(f's.{op[0]}("{op[1]}", "{op[2]}")')
        lines += [f's.set("{k}", {_lit(v)})' for k, v in ov.items()]
        head = [f"from {mod} import {', '.join(sorted(names))}" for mod, names in sorted(imports.items())]
        return head + lines


# ---- where a line is now cut ------------------------------------------------------------------------------
def nets(system) -> dict:
    """``{port: root}``: connection sets of the top-level connections (union-find)."""
    parent: dict = {}

    def find(k):
        parent.setdefault(k, k)
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for a, b in system._connections:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    return {k: find(k) for k in list(parent)}


def connected(system, a: str, b: str) -> bool:
    """True when ``a`` and ``b`` are joined by a connection of their own (either order)."""
    return any((x, y) in ((a, b), (b, a)) for x, y in system._connections)


def between(system, a: str, b: str) -> list:
    """Components with one port in the connection set of ``a`` and another in that of ``b`` (what an
    earlier effect put in series on the line ``a``--``b``); [] when ``a`` and ``b`` share a set."""
    n = nets(system)
    ra, rb = n.get(a, a), n.get(b, b)
    if ra == rb:
        return []
    own = {a.split(".", 1)[0], b.split(".", 1)[0]}
    on_a, on_b = set(), set()
    for port, root in n.items():
        comp = port.split(".", 1)[0]
        if comp in own:
            continue
        if root == ra:
            on_a.add(comp)
        elif root == rb:
            on_b.add(comp)
    return sorted(on_a & on_b)


def cut(e: Edits, a: str, b: str) -> tuple:
    """Cut the line ``a``--``b`` for an element in series; returns ``(a, [ports on the far side])``.

    If ``a`` and ``b`` are connected directly, that connection is removed (far side ``[b]``). If an
    earlier effect sits between them, the line is cut at the ``a`` side: ``a`` is disconnected from the
    ports of the element(s) between that it was connected to, which become the far side. Raises
    :class:`~bscomp.errors.ModelDefinitionError` when ``a`` and ``b`` are neither connected nor bridged.
    """
    if connected(e.s, a, b):
        e.disconnect(a, b)
        return a, [b]
    inner = set(between(e.s, a, b))
    far = [y if x == a else x for x, y in e.s._connections
           if a in (x, y) and (y if x == a else x).split(".", 1)[0] in inner]
    if not far:
        raise ModelDefinitionError(f"cannot insert in series between '{a}' and '{b}': they are not connected "
                                   "and no element bridges them (check the insertion point)")
    for q in far:
        e.disconnect(a, q)
    return a, far


def insert_series(e: Edits, name: str, cls, kw: dict, a: str, b: str, ports=("flange_a", "flange_b")) -> str:
    """Add ``cls(**kw)`` as ``name`` in series on the line ``a``--``b`` (see :func:`cut`)."""
    left, far = cut(e, a, b)
    e.add(name, cls, **kw)
    e.connect(left, f"{name}.{ports[0]}")
    for q in far:
        e.connect(f"{name}.{ports[1]}", q)
    return name
