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
from bscomp.kernel.condensation import condense_massless, is_asymmetric, massless_split
from bscomp.kernel.damping import nonsymmetric_damping
from bscomp.kernel.mechanics import start_matrices

__all__ = ["system_damping_matrix", "apply_system_damping"]


def system_damping_matrix(damping, M, K, coordinates) -> np.ndarray:
    """The matrix of a system-level damping option (``System.damping``) for the mechanical (M, K).

    Options with ``needs_coordinates = True`` assign their ratios by mode character and are given the
    coordinate names; the others only see M and K.

    Coordinates without inertia (zero columns of ``M``: a massless node, the MA-recovered ports of a CMS
    superelement) are condensed statically first, row by row (their rows may carry inertia loads):
    ``M_c = M_mm - K_m0 K_00^{-1} M_0m``, ``K_c = K_mm - K_m0 K_00^{-1} K_0m``; the damping acts on the coordinates
    with inertia. A condensed pair that is not symmetric (MA coupling, Eq 5.14/5.18) gets the option's ratios
    through left and right eigenvectors (:func:`bscomp.kernel.damping.nonsymmetric_damping`).
    """
    Md = M.toarray() if sp.issparse(M) else np.asarray(M, float)
    Kd = K.toarray() if sp.issparse(K) else np.asarray(K, float)
    massless, massive = massless_split(Md)            # the dense tests: the same rule without sparse copies
    if not massless.size and not is_asymmetric(Md) and not is_asymmetric(Kd):
        return _option_matrix(damping, M, K, coordinates)
    Mc, Kc = Md[np.ix_(massive, massive)], Kd[np.ix_(massive, massive)]
    if massless.size:
        Mc, Kc, *_ = condense_massless(Md, Kd, massless, massive, coordinates, "system damping")
    names = [coordinates[i] for i in massive]
    if is_asymmetric(Mc) or is_asymmetric(Kc):
        Cc = nonsymmetric_damping(damping, Mc, Kc, names)
    else:
        Cc = np.asarray(sp.csr_matrix(_option_matrix(damping, 0.5 * (Mc + Mc.T), 0.5 * (Kc + Kc.T), names)).toarray())
    C = np.zeros(Md.shape)
    C[np.ix_(massive, massive)] = Cc
    return C


def _option_matrix(damping, M, K, coordinates):
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
        If a coordinate that is a state has damping but no inertia (the modes need a non-singular M), or
        coordinates without inertia are not held by a stiffness.
    NotLinearError
        If the Dae has internal differential states.
    """
    m = dae.mech
    if m.damped:
        names = [m.coordinate_names[j] for j in m.damped]
        raise SingularSystemError(f"system damping {damping!r} needs inertia on every coordinate of "
                                  f"'{dae.name}' that is a state; damped but without inertia: {names[:10]} (add "
                                  "masses or drop the option)")
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
