"""A linear mechanical model given as matrices, ``M q'' + C q' + K q = B u``, as a component.

Used to put a reduced model (CMS, thesis Sec 5.2.3, :mod:`bscomp.linear.reduction`) or any assembled
second-order model (Eq 3.44 / 5.1) back into a system, next to nonlinear parts (friction, backlash,
controllers), for simulation and optimal control. ``M, C, K`` enter as one sparse structural block
over generalized ports ``q0, q1, ...``; each named input is a ``RealInput`` acting through ``B``;
outputs ``y = C_q q + C_v q' + C_a q''`` are observables; chosen coordinates can be exposed as
translational or rotational flanges (ideal constraints ``flange.s = q_i``) to attach physical parts.
"""

from __future__ import annotations

import re

import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import Component, LinearStructure
from bscomp.kernel.ports import Flange, Generalized, RealInput, RotFlange


def _port_name(name: str) -> str:
    return re.sub(r"\W", "_", name)


class SecondOrderBlock(Component):
    """Matrix-defined linear mechanical model.

    Parameters
    ----------
    model : bscomp.linear.SecondOrderModel
        ``M, C, K, B, Cq, Cv, Ca`` with ``coordinates``, ``inputs`` and ``outputs`` names.
    expose : dict, optional
        ``{port_name: (coordinate_name, "Flange" | "RotFlange")}``: physical ports tied to coordinates.

    Attributes
    ----------
    q0 ... q<n> : Generalized
        The model's coordinates (optional).
    <input> : RealInput
        One per model input (name with '.' replaced by '_', e.g. ``motor_tau``).
    <exposed> : Flange or RotFlange
        The exposed flanges.
    """

    def __init__(self, model, expose: dict | None = None):
        super().__init__()
        self.model = model
        n = model.M.shape[0]
        for i in range(n):
            self.add_port(f"q{i}", Generalized(f"coordinate {model.coordinates[i]}"))
        self.input_ports = [_port_name(u) for u in model.inputs]
        for u, pn in zip(model.inputs, self.input_ports):
            self.add_port(pn, RealInput(f"input {u}"))
        self.expose = {}
        for pname, (coord, kind) in (expose or {}).items():
            if coord not in model.coordinates:
                raise ModelDefinitionError(f"SecondOrderBlock: cannot expose '{coord}': coordinates are "
                                           f"{model.coordinates[:10]}...")
            if kind not in ("Flange", "RotFlange"):
                raise ModelDefinitionError(
                    f"SecondOrderBlock: expose kind must be 'Flange' or 'RotFlange', got {kind!r}")
            self.add_port(pname, Flange(f"= {coord}", optional=True) if kind == "Flange"
                          else RotFlange(f"= {coord}", optional=True))
            self.expose[pname] = (model.coordinates.index(coord), kind)

    def template_key(self):
        return (id(self.model), tuple(sorted(self.expose.items())))

    def structure(self):
        m = self.model
        return LinearStructure(dofs=[f"q{i}.q" for i in range(m.M.shape[0])], M=sp.csr_matrix(m.M),
                               C=sp.csr_matrix(m.C), K=sp.csr_matrix(m.K))

    def constraints(self):
        cons = []
        for pname, (i, kind) in self.expose.items():
            port = getattr(self, pname)
            cons.append((port.s if kind == "Flange" else port.phi) - getattr(self, f"q{i}").q)
        return cons

    def equations(self):
        m = self.model
        B = sp.csr_matrix(m.B)
        u = [getattr(self, pn).u for pn in self.input_ports]
        eqs = []
        for i in range(m.M.shape[0]):
            row = B.getrow(i)
            f = 0
            for j, b in zip(row.indices, row.data):
                f = f - float(b) * u[j]
            eqs.append(getattr(self, f"q{i}").Q - f)
        for pname, (_, kind) in self.expose.items():
            port = getattr(self, pname)
            eqs.append(port.f if kind == "Flange" else port.tau)  # reaction only (through the constraint)
        return eqs

    def observables(self):
        m = self.model
        q = [getattr(self, f"q{i}").q for i in range(m.M.shape[0])]
        out = {}
        for k, name in enumerate(m.outputs):
            y = 0
            for mat, order in ((m.Cq, 0), (m.Cv, 1), (m.Ca, 2)):
                row = sp.csr_matrix(mat).getrow(k)
                for j, c in zip(row.indices, row.data):
                    term = q[j]
                    for _ in range(order):
                        term = self.der(term)
                    y = y + float(c) * term
            out[_port_name(name)] = y
        return out


