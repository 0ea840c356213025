"""Ballscrew shaft: stepped Timoshenko beam finite elements (thesis Sec 3.3.1, Appendix A).

The shaft is split into 2-node Timoshenko elements with six DOF per node, ``(u, v, w, θx, θy, θz)``
(Eq 3.27, Fig 3.5), z = screw axis, node 0 at z = 0. The consistent mass and stiffness matrices of
Eq (A.1)-(A.6) (:mod:`components._beam_element`) are assembled by
:func:`components._beam_fe.assemble_shaft` (threaded sections: stiffness from the root diameter, mass
from the equivalent diameter of Eq 3.1) and enter the system as one sparse ``LinearStructure`` over the
node ports ``n0, n1, ...``:

.. math:: M_{BS}\\,\\ddot d + K_{BS}\\,d = F

Extra ports at arbitrary axial positions (``points``, e.g. the nut contact point P of Sec 3.3.4)
follow the element shape functions (Eq 3.27 / A.7) through ideal constraints
``d_P - N(z_P) d = 0``; forces applied there reach the nodes as ``N^T F_P`` (virtual work).

``dofs`` keeps a subset of the six fields per node: ``("w", "tz")`` is the axial + torsional model of
thesis Chapter 5 (exact for a straight shaft, whose axial, torsional and bending fields are
uncoupled); the other potentials of every port are constrained to zero. Sign conventions are those of
:mod:`components._beam_element` (right-hand rotations; ``θy = +du/dz``, ``θx = -dv/dz``).
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import Component, Constraint, LinearStructure, Parameter
from bscomp.kernel.ports import Node6

from ._beam_element import STEEL_E, STEEL_NU, STEEL_RHO
from ._beam_fe import assemble_shaft, select_dofs
from ._node_dofs import DOF_NAMES, check_dofs, pin_unused


class Ballscrew(Component):
    """Timoshenko FE model of a stepped ballscrew shaft.

    Parameters
    ----------
    sections : sequence of Section
        Shaft sections in order of increasing z (:class:`bscomp.components.Section`).
    dofs : tuple of str
        Kept fields per node, a subset of ``("u", "v", "w", "tx", "ty", "tz")``.
    points : dict of str -> float
        Extra ports at axial positions z [m] (0 <= z <= length), reached through N(z) (Eq 3.27).

    Attributes
    ----------
    n0 ... n<N> : Node6
        One port per FE node (optional: a free end is force-free).
    <point> : Node6
        One port per entry of ``points``.
    """

    E = Parameter(STEEL_E, unit="Pa", positive=True, doc="Young's modulus (steel: 210 GPa, App B.1)")
    rho = Parameter(STEEL_RHO, unit="kg/m^3", positive=True, doc="density (steel: 7800 kg/m^3, App B.1)")
    nu = Parameter(STEEL_NU, unit="1", min=0.0, max=0.5, doc="Poisson's ratio (steel: 0.27, App B.1)")
    kappa = Parameter(0.9, unit="1", positive=True, doc="shear correction factor (9/10, text after Eq A.6)")

    def __init__(self, sections, dofs=DOF_NAMES, points: dict | None = None, **params):
        super().__init__(**params)
        self.sections = list(sections)
        self.dofs = check_dofs(dofs, "Ballscrew")
        geometry = self._beam(E=STEEL_E, rho=STEEL_RHO, nu=STEEL_NU, kappa=0.9)  # node layout only
        self.z_nodes = geometry.z_nodes
        self.points = {}
        for i, z in enumerate(self.z_nodes):
            self.add_port(f"n{i}", Node6(f"FE node {i} at z = {z:.6g} m"))
        for name, z in (points or {}).items():
            z = float(z)
            if not -1e-12 <= z <= self.length + 1e-12:
                raise ModelDefinitionError(f"Ballscrew point '{name}' at z = {z} m is outside the shaft "
                                           f"[0, {self.length:.6g}] m")
            self.points[name] = z
            self.add_port(name, Node6(f"point on the screw axis at z = {z:.6g} m (shape functions, Eq 3.27)"))

    @property
    def length(self) -> float:
        """Shaft length [m]."""
        return float(self.z_nodes[-1])

    @property
    def n_nodes(self) -> int:
        return len(self.z_nodes)

    def node_at(self, z: float) -> int:
        """Index of the node nearest to axial position ``z`` [m]."""
        return int(np.argmin(np.abs(self.z_nodes - z)))

    def beam_model(self):
        """The assembled :class:`components._beam_fe.BeamModel` at the current parameter values."""
        v = self._values
        return self._beam(E=v["E"], rho=v["rho"], nu=v["nu"], kappa=v["kappa"])

    def template_key(self):
        """Instance configuration baked into the constraints (kept dofs, shape-function coefficients)."""
        v = self._values
        geometry = tuple((s.length, s.d_out, s.d_in, s.n_elements, s.d_mass) for s in self.sections)
        return (self.dofs, tuple(self.points.items()), geometry, v["E"], v["nu"], v["kappa"])

    def _beam(self, E, rho, nu, kappa):
        return assemble_shaft(self.sections, E=E, rho=rho, nu=nu, kappa=kappa)

    def structure(self):
        beam = self._beam(E=self.E, rho=self.rho, nu=self.nu, kappa=self.kappa)
        sel = select_dofs(beam, keep=self.dofs)
        names = [f"n{i}.{d}" for i in range(beam.n_nodes) for d in self.dofs]
        return LinearStructure(dofs=names, M=sel.M, K=sel.K)

    def constraints(self):
        cons = []
        for i in range(self.n_nodes):
            cons += pin_unused(getattr(self, f"n{i}"), self.dofs)
        if not self.points:
            return cons
        beam = self.beam_model()  # shape functions depend on Φ (E, nu, kappa), read as numbers here
        for name, z in self.points.items():
            port = getattr(self, name)
            N = beam.shape_matrix(z).tocsr()
            for k, d in enumerate(DOF_NAMES):
                row = N.getrow(k)
                expr = getattr(port, d)
                for j, a in zip(row.indices, row.data, strict=True):
                    node, dof = divmod(int(j), 6)
                    if DOF_NAMES[dof] in self.dofs:
                        expr = expr - float(a) * getattr(getattr(self, f"n{node}"), DOF_NAMES[dof])
                cons.append(Constraint(expr, solve_for=getattr(port, d)))
        return cons
