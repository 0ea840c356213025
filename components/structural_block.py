"""A numeric ``M, C, K`` block between the potentials of other parts' ports (thesis Eq 3.44 / 5.4).

The matrix form of DESIGN.md for a block that is not a physical part of its own: a damping or stiffness
matrix measured or derived elsewhere and attached between coordinates of the model, e.g. the cross-coupling
dampers ``C_joint`` of thesis Eq 5.4 between two sub-models, or the projected damping ``Ψ^T C_model Ψ`` of a
CMS-reduced drive (Sec 5.2.3.3, :mod:`bscomp.systems.reduced_testbed`). Flows follow the block,
``F = M d'' + C d' + K d`` on the listed potentials; the other potentials of its ports carry no flow.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import Component, LinearStructure
from bscomp.kernel.ports import Flange, Generalized, Node6, RotFlange

_SPECS = {"Flange": Flange, "RotFlange": RotFlange, "Node6": Node6, "Generalized": Generalized}


class StructuralBlock(Component):
    """``M d'' + C d' + K d = F`` over chosen potentials of its ports.

    Parameters
    ----------
    ports : dict of str -> str
        Port name -> kind (``"Flange"``, ``"RotFlange"``, ``"Node6"``, ``"Generalized"``).
    dofs : sequence of str
        ``"port.potential"`` of each row/column (``"nut.w"``, ``"q1.q"``, ``"table.s"``).
    M, C, K : (n, n) array_like or sparse, optional
        The block (missing ones are zero); ``n = len(dofs)``.

    Attributes
    ----------
    <port> : the declared kinds
        Connect each to the part whose potentials the block couples.
    """

    def __init__(self, ports: dict, dofs, M=None, C=None, K=None):
        super().__init__()
        self.dofs = [str(d) for d in dofs]
        n = len(self.dofs)
        for name, kind in ports.items():
            if kind not in _SPECS:
                raise ModelDefinitionError(f"StructuralBlock: port '{name}' has kind {kind!r}; use one of "
                                           f"{sorted(_SPECS)}")
            self.add_port(name, _SPECS[kind](f"{kind} port of the block", optional=False)
                          if kind in ("Flange", "RotFlange") else _SPECS[kind](f"{kind} port of the block"))
        self.kinds = dict(ports)
        for d in self.dofs:
            port, _, pot = d.partition(".")
            if port not in self.kinds:
                raise ModelDefinitionError(f"StructuralBlock: dof '{d}' names no declared port ({sorted(ports)})")
        self.mats = {}
        for key, A in (("M", M), ("C", C), ("K", K)):
            if A is None:
                continue
            A = sp.csr_matrix(A)
            if A.shape != (n, n) or not np.all(np.isfinite(A.data)):
                raise ModelDefinitionError(f"StructuralBlock: {key} must be a finite ({n}, {n}) matrix, got "
                                           f"{A.shape}")
            self.mats[key] = A

    def template_key(self):
        return (id(self),)

    def structure(self):
        return LinearStructure(dofs=list(self.dofs), **self.mats)

    def equations(self):
        """The potentials the block does not couple carry no flow from it."""
        used = set(self.dofs)
        eqs = []
        for name in self.kinds:
            spec = self.ports()[name]
            port = getattr(self, name)
            for (pot, _), (flow, _) in zip(spec.kind.potentials, spec.kind.flows, strict=True):
                if f"{name}.{pot}" not in used:
                    eqs.append(getattr(port, flow))
        return eqs
