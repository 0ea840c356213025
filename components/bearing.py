"""Rolling bearing: axial and radial stiffness between a shaft node and its housing (Sec 3.3.3.2).

The thesis models a bearing as linear springs between the screw node where the bearing acts and the
(rigid) frame: axial ``k_axial`` along z and radial ``k_radial`` along x and y (Table 3.1: the
angular-contact pair 2.70e8 / 1.9e8 N/m, the floating deep-groove bearing 0 / 4.0e7 N/m). A floating
(radial-only) bearing has ``k_axial = 0``. Tilting stiffness ``k_tilt`` about x and y is optional
(0 in the thesis). With ``u = d_housing - d_shaft``:

.. math:: F_{shaft} = \\operatorname{diag}(k_r, k_r, k_a, k_t, k_t, 0)\\,u
          + \\operatorname{diag}(c_r, c_r, c_a, 0, 0, 0)\\,\\dot u

The rotation about the shaft axis is free (the bearing's purpose).
"""

from __future__ import annotations

import numpy as np

from bscomp.kernel.component import Parameter

from ._joint6 import PartialJoint6


class Bearing(PartialJoint6):
    """Linear bearing support.

    Parameters
    ----------
    grounded : bool
        True: the housing is the rigid frame and only ``node_a`` (the shaft node) exists.

    Attributes
    ----------
    node_a : Node6
        Shaft node.
    node_b : Node6
        Housing node (absent if ``grounded``).
    """

    k_axial = Parameter(unit="N/m", min=0.0, doc="axial stiffness along z (0 = floating bearing)")
    k_radial = Parameter(unit="N/m", min=0.0, doc="radial stiffness (x and y)")
    k_tilt = Parameter(0.0, unit="N.m/rad", min=0.0, doc="tilting stiffness about x and y")
    c_axial = Parameter(0.0, unit="N.s/m", min=0.0, doc="axial viscous damping")
    c_radial = Parameter(0.0, unit="N.s/m", min=0.0, doc="radial viscous damping")

    def stiffness(self):
        return np.diag([self.k_radial, self.k_radial, self.k_axial, self.k_tilt, self.k_tilt, 0.0])

    def damping(self):
        return np.diag([self.c_radial, self.c_radial, self.c_axial, 0.0, 0.0, 0.0])
