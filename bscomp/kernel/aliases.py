"""Connection sets: alias elimination of connected potentials and signals (flattening step 1).

Modelica's ``connect(a, b)`` makes the potential variables of ``a`` and ``b`` equal and adds their flow
variables to a zero-sum balance (Modelica Language Specification, Sec 9.2 "Generation of connection
equations"). Here the equal potentials are not written as equations: a union-find over the port
potentials merges every connection set into one **coordinate** (alias elimination), and connected
signals into one **signal**. Each coordinate's flows are summed to zero later, as its generalised force
balance (d'Alembert / virtual work, thesis Eq 3.44 ``M q'' + C q' + K q = F``).

Names are stable: a connection set takes the name of its earliest-declared potential, or the name a
component gives it through ``coordinate_names`` (``mass.s`` instead of ``mass.flange_a.s``).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

__all__ = ["ConnectionSets", "union_ports", "connection_sets"]


class _UnionFind:
    """Disjoint sets of port potentials; the earlier-declared key stays the root (stable names)."""

    def __init__(self):
        self.parent = {}
        self._order = {}

    def add(self, k):
        self.parent.setdefault(k, k)
        self._order.setdefault(k, len(self._order))

    def find(self, k):
        p = self.parent
        root = k
        while p[root] != root:
            root = p[root]
        while p[k] != root:
            p[k], k = root, p[k]
        return root

    def union(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            if self._order[ra] <= self._order[rb]:
                self.parent[rb] = ra
            else:
                self.parent[ra] = rb


def union_ports(system, leaves, by_path):
    """Merge the potentials of connected ports.

    Parameters
    ----------
    system : System
    leaves : list
        Leaf components (``.path``, ``.comp``) in declaration order.
    by_path : dict
        Leaf by dotted path.

    Returns
    -------
    uf : _UnionFind
        Keys ``(path, port, potential index)``.
    connected : set of (str, str)
        ``(path, port)`` of every port named in a connection.
    """
    uf = _UnionFind()
    connected = set()
    for lf in leaves:
        for pname, spec in lf.comp.ports().items():
            for i in range(len(spec.kind.potentials)):
                uf.add((lf.path, pname, i))
    for a, b in system.connections():
        pa, _, na = a.rpartition(".")
        pb, _, nb = b.rpartition(".")
        spec = by_path[pa].comp.ports()[na]
        connected.add((pa, na))
        connected.add((pb, nb))
        for i in range(len(spec.kind.potentials)):
            uf.union((pa, na, i), (pb, nb, i))
    return uf, connected


@dataclass
class ConnectionSets:
    """Coordinates and signals of a system after alias elimination.

    Attributes
    ----------
    coord_names, coord_units : list of str
        One entry per physical coordinate (connection set of potentials).
    port_coord : dict
        ``"path.port.potential"`` -> coordinate index.
    sig_names, sig_units : list of str
        One entry per signal connection set (named after its output, if any).
    sig_inputs : dict
        Signal index -> ``[(path, port, PortSpec)]`` of the inputs reading it.
    connected : set of (str, str)
        Ports named in a connection.
    """

    uf: _UnionFind
    connected: set
    coord_of: dict = field(default_factory=dict)
    coord_names: list = field(default_factory=list)
    coord_units: list = field(default_factory=list)
    port_coord: dict = field(default_factory=dict)
    sig_of: dict = field(default_factory=dict)
    sig_names: list = field(default_factory=list)
    sig_units: list = field(default_factory=list)
    sig_out_owner: dict = field(default_factory=dict)
    sig_inputs: dict = field(default_factory=lambda: defaultdict(list))

    def coordinate(self, path, port, i):
        """Coordinate index of potential ``i`` of ``path.port``."""
        return self.coord_of[self.uf.find((path, port, i))]

    def signal(self, path, port):
        """Signal index of ``path.port``."""
        return self.sig_of[self.uf.find((path, port, 0))]


def connection_sets(leaves, by_path, uf, connected) -> ConnectionSets:
    """Number and name the coordinates and signals of the merged connection sets (declaration order)."""
    cs = ConnectionSets(uf, connected)
    named = set()                          # coordinates named after a body (``mass.s``)
    for lf in leaves:
        for pname, spec in lf.comp.ports().items():
            for i, (pot, unit) in enumerate(spec.kind.potentials):
                root = uf.find((lf.path, pname, i))
                if spec.kind.is_signal:
                    if root not in cs.sig_of:
                        cs.sig_of[root] = len(cs.sig_names)
                        cs.sig_names.append(f"{lf.path}.{pname}")
                        cs.sig_units.append(spec.unit)
                    k = cs.sig_of[root]
                    if spec.kind.signal == "out":
                        cs.sig_out_owner[k] = f"{lf.path}.{pname}"
                        cs.sig_names[k] = f"{lf.path}.{pname}"
                    else:
                        cs.sig_inputs[k].append((lf.path, pname, spec))
                else:
                    if root not in cs.coord_of:
                        cs.coord_of[root] = len(cs.coord_names)
                        rp, rn, _ = root
                        rpot = by_path[rp].comp.ports()[rn].kind.potentials[i][0]
                        cs.coord_names.append(f"{rp}.{rn}.{rpot}")
                        cs.coord_units.append(unit)
                    alias = getattr(lf.comp, "coordinate_names", {}).get(f"{pname}.{pot}")
                    c = cs.coord_of[root]
                    cs.port_coord[f"{lf.path}.{pname}.{pot}"] = c
                    if alias and c not in named:
                        named.add(c)
                        cs.coord_names[c] = f"{lf.path}.{alias}"
    return cs
