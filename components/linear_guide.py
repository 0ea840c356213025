"""Linear guides: vertical and lateral springs at each slide (thesis Sec 3.3.3.4, Fig 3.9).

Each slide (carriage) of a rail is a pair of linear springs between the table attachment point above
it and the (rigid) rail/frame: ``k_vertical`` along the vertical axis and ``k_lateral`` along the
lateral axis; the feed direction (z, the screw axis) is free. The slides' own rotational stiffness is
neglected, as in the thesis (two rails and four slides carry the moments through the vertical and
lateral springs). With ``d_s`` the displacement of slide s:

.. math:: F_s = -\\operatorname{diag}(k_{lat}, k_{vert}, 0, 0, 0, 0)\\, d_s
          - \\operatorname{diag}(c_{lat}, c_{vert}, 0, 0, 0, 0)\\,\\dot d_s

(for ``vertical="y"``; ``vertical="x"`` swaps the axes). Appendix C study values: ``k_vertical =
5e8``, ``k_lateral = 4e8 N/m`` per slide (Table C.1).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import Component, LinearStructure, Parameter
from bscomp.kernel.ports import Node6

from ._node_dofs import DOF_NAMES


class LinearGuide(Component):
    """Rail slides as vertical + lateral springs to ground (Fig 3.9).

    Parameters
    ----------
    slides : sequence of str or int
        Names of the slide ports (an int n gives ``s0 ... s<n-1>``; default 4, Fig 3.9).
    vertical : {"y", "x"}
        Vertical axis; the lateral axis is the other radial axis.

    Attributes
    ----------
    s0 ... : Node6
        One port per slide (required), connected to the table's attachment points.
    """

    k_vertical = Parameter(unit="N/m", min=0.0, doc="vertical stiffness per slide")
    k_lateral = Parameter(unit="N/m", min=0.0, doc="lateral stiffness per slide")
    c_vertical = Parameter(0.0, unit="N.s/m", min=0.0, doc="vertical damping per slide")
    c_lateral = Parameter(0.0, unit="N.s/m", min=0.0, doc="lateral damping per slide")

    def __init__(self, slides=4, vertical: str = "y", **params):
        super().__init__(**params)
        if vertical not in ("x", "y"):
            raise ModelDefinitionError(f"LinearGuide: vertical must be 'x' or 'y', got {vertical!r}")
        self.vertical = vertical
        if isinstance(slides, int):
            slides = [f"s{i}" for i in range(slides)]
        self.slides = [str(s) for s in slides]
        if not self.slides:
            raise ModelDefinitionError("LinearGuide needs at least one slide")
        for s in self.slides:
            self.add_port(s, Node6(f"slide {s} (attach to the table point above it)", optional=False))

    def _diag(self, vert, lat):
        d = np.zeros(6)
        d[1 if self.vertical == "y" else 0] = vert
        d[0 if self.vertical == "y" else 1] = lat
        return sp.kron(sp.identity(len(self.slides)), sp.diags(d)).tocsr()

    def structure(self):
        dofs = [f"{s}.{d}" for s in self.slides for d in DOF_NAMES]
        C = self._diag(self.c_vertical, self.c_lateral) if (self.c_vertical or self.c_lateral) else None
        return LinearStructure(dofs=dofs, K=self._diag(self.k_vertical, self.k_lateral), C=C)
