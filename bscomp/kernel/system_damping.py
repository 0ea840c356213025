"""System-level damping applied at flattening (thesis Sec 3.4, Appendix A.3, Eq A.10-A.15).

A System may carry a damping option (``system.damping``, e.g. :class:`bscomp.kernel.damping.ModalDamping`
or ``RayleighDamping``): an object whose ``matrix(M, K[, coordinates])`` turns the undamped mechanical
matrices into a viscous damping matrix ``C`` (modal ratios under the proportional-damping assumption,
rigid-body modes undamped, Sec 5.2.2.1). Flattening extracts ``M, K`` of the reduced coordinates at the
start point (:func:`bscomp.kernel.mechanics.start_matrices`), asks the option for ``C`` and adds it to
the structural damping, so every analysis of the Dae sees the same damped model. Only the option's
interface is used here; the formulas live with the options in :mod:`bscomp.kernel.damping`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.errors import SingularSystemError
from bscomp.kernel.mechanics import start_matrices

__all__ = ["system_damping_matrix", "apply_system_damping"]


def system_damping_matrix(damping, M, K, coordinates) -> np.ndarray:
    """The matrix of a system-level damping option (``System.damping``) for the mechanical (M, K).

    Options with ``needs_coordinates = True`` assign their ratios by mode character and are given the
    coordinate names; the others only see M and K.
    """
    if getattr(damping, "needs_coordinates", False):
        return damping.matrix(M, K, coordinates=list(coordinates))
    return damping.matrix(M, K)


def apply_system_damping(dae, damping):
    """Add a system-level damping matrix (modal or Rayleigh, Eq A.10-A.15) to the structural C.

    Records ``dae.system_damping`` (the option) and ``dae.system_damping_basis = (M, K, C_add)``: what the
    damping was computed from, so that linear analyses re-derive it when parameters or the operating
    point change M or K (modal damping follows the modes).

    Raises
    ------
    SingularSystemError
        If a reduced coordinate has no inertia (the modes need a non-singular M).
    NotLinearError
        If the Dae has internal differential states.
    """
    m = dae.mech
    if m.static or m.damped:
        names = [m.coordinate_names[j] for j in m.static + m.damped]
        raise SingularSystemError(f"system damping {damping!r} needs inertia on every coordinate of "
                                  f"'{dae.name}'; without inertia: {names[:10]} (add masses or drop the option)")
    dae.check_index1()
    M, K = start_matrices(dae)
    Cadd = sp.csc_matrix(system_damping_matrix(damping, M, K, list(m.coordinate_names)))
    m.C = (m.C + Cadd).tocsc()
    # everything built on the structural C goes; the scalar equations' Jacobian does not depend on it
    for key in [k for k in dae._cache if k not in ("jac_sx", "mx")]:
        del dae._cache[key]
    dae.stats["system_damping"] = repr(damping)
    dae.system_damping = damping
    dae.system_damping_basis = (M, K, Cadd)
