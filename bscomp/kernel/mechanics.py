"""Mechanics of a flattened Dae: operating point and the second-order matrices ``M, C, K, B``.

The Dae keeps its mechanical structure (:class:`~bscomp.kernel.dae.MechanicalInfo`): which entries of
``(x, x', z)`` hold each reduced coordinate's position, velocity and acceleration, and which rows are
its projected force balances. Differentiating the residual at a consistent point and reading those
rows and columns gives the linearized equation of motion (thesis Eq 3.44 / 5.1)

.. math:: M \\ddot q + C \\dot q + K q = B u,

with the internal algebraic variables ``w`` (quasi-static signals, amplifier currents, ...) eliminated
by a Schur complement of their equations ``G``. This is the part of linearization the kernel itself
needs: a system-level damping (modal or Rayleigh, Eq A.10-A.15) is computed from the undamped ``M, K``
when the system is flattened (:mod:`bscomp.kernel.system_damping`). Outputs, the first-order form and
everything built on it are :mod:`bscomp.linear`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bscomp.errors import NotLinearError, SingularSystemError, UnknownNameError, check_mapping, check_number
from bscomp.kernel.dae import Dae

__all__ = ["OperatingPoint", "operating_point", "sparse_jacobians", "require_second_order", "SecondOrderBlocks",
           "second_order_blocks", "start_matrices"]


@dataclass
class OperatingPoint:
    """Numeric operating point of a Dae: ``x``, ``x'``, ``z``, ``u``, ``p``."""

    xd: np.ndarray
    x: np.ndarray
    z: np.ndarray
    u: np.ndarray
    p: np.ndarray


def operating_point(dae: Dae, at: dict | None = None, params: dict | None = None) -> OperatingPoint:
    """Consistent operating point: states and inputs set by name in ``at``; (x', z) solved."""
    p = dae.parameter_vector({k: v for k, v in (params or {}).items() if k not in dae.structural_parameters})
    x = dae.x_start.copy()
    u = np.zeros(dae.nu)
    for k, v in check_mapping("at", at, "state and input values").items():
        if k in dae.x_names:
            x[dae.x_names.index(k)] = check_number(f"at['{k}']", v)
        elif k in dae.u_names:
            u[dae.u_names.index(k)] = check_number(f"at['{k}']", v)
        else:
            raise UnknownNameError(f"operating point names '{k}', which is neither a state {dae.x_names[:10]}... "
                                   f"nor an input {dae.u_names} of '{dae.name}'")
    xd, z = dae.initialize(x, u, p)
    return OperatingPoint(xd, x, z, u, p)


def sparse_jacobians(dae: Dae, op: OperatingPoint):
    """``(dF/dx', dF/dx, dF/dz, dF/du)`` at ``op``, scipy sparse."""
    return dae.jacobians_at(op.xd, op.x, op.z, op.u, op.p)[1:]


def require_second_order(dae: Dae):
    """Raise :class:`NotLinearError` if the Dae has internal differential states (no second-order form)."""
    if dae.mech.has_internal_states:
        raise NotLinearError(f"'{dae.name}' has internal differential states (not only mechanical coordinates); "
                             "its linearization has no second-order form: use linearize()")


@dataclass
class SecondOrderBlocks:
    """The mechanical rows of a linearized Dae: ``M q'' + C q' + K q + B_u u = 0`` (internal algebraic
    variables eliminated), plus what output equations need to be condensed the same way.

    Attributes
    ----------
    M, C, K, Bu : sparse matrices
        Over the reduced coordinates (``B = -Bu``).
    Sq_x, Sq_z, Sv_x, Sv_xd_out, Sa_xd, Sw : sparse matrices
        Selectors: positions, velocities (``dt(q)`` counted, for outputs), accelerations, internal
        algebraic variables ``w`` in ``(x, x', z)``.
    zint : list of int
        Entries of ``z`` that are internal algebraic variables.
    lu : SuperLU or None
        Factorisation of ``dG/dw``.
    G : tuple or None
        ``(G_q, G_v, G_a, G_u)``, the internal equations' Jacobians.
    """

    M: Any
    C: Any
    K: Any
    Bu: Any
    Sq_x: Any
    Sq_z: Any
    Sv_x: Any
    Sv_xd_out: Any
    Sa_xd: Any
    Sw: Any
    zint: list
    lu: Any
    G: Any


def second_order_blocks(dae: Dae, jacobians, uidx, internal_rows=None) -> SecondOrderBlocks:
    """The second-order blocks from the Jacobians of F (:func:`sparse_jacobians`) for inputs ``uidx``.

    ``internal_rows``: the rows of the internal algebraic equations (default: every row after the
    inertial and balance rows; :func:`start_matrices` passes them without the internal states' ODEs).

    Raises
    ------
    SingularSystemError
        If the internal algebraic equations are singular.
    """
    Jxd, Jx, Jz, Ju = jacobians
    m = dae.mech
    nr = len(m.coordinate_names)
    nx, nz = dae.nx, dae.nz

    def S(where, n):
        rows = [where[j] for j in where]
        cols = list(where)
        return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, nr))

    Sq_x, Sq_z = S(m.q_in_x, nx), S(m.q_in_z, nz)
    Sv_x, Sv_xd, Sa_xd = S(m.v_in_x, nx), S(m.v_in_xd, nx), S(m.a_in_xd, nx)
    # derivative of an inertial position (dt(q)) is its velocity: for outputs only
    Sv_xd_out = Sv_xd + S({j: i for i, j in enumerate(m.inertial)}, nx)
    zint = [i for i in range(nz) if i not in set(m.q_in_z.values())]
    Sw = sp.csr_matrix((np.ones(len(zint)), (zint, np.arange(len(zint)))), shape=(nz, len(zint)))
    ni = len(m.inertial)
    rows_R = m.balance_rows
    rows_G = list(range(ni + nr, Jx.shape[0])) if internal_rows is None else list(internal_rows)

    def blocks(rows):
        Jxd_r, Jx_r, Jz_r = Jxd[rows], Jx[rows], Jz[rows]
        return (Jx_r @ Sq_x + Jz_r @ Sq_z, Jx_r @ Sv_x + Jxd_r @ Sv_xd, Jxd_r @ Sa_xd, Jz_r @ Sw,
                Ju[rows][:, uidx])

    Rq, Rv, Ra, Rw, Ru = blocks(rows_R)
    lu = G = None
    if zint:
        Gq, Gv, Ga, Gw, Gu = blocks(rows_G)
        G = (Gq, Gv, Ga, Gu)
        try:
            lu = spla.splu(sp.csc_matrix(Gw))
        except RuntimeError as exc:
            raise SingularSystemError(f"'{dae.name}': internal algebraic equations are singular") from exc

        def schur(Rx, Gx):
            Gx = sp.csc_matrix(Gx)
            if Gx.nnz == 0:
                return sp.csr_matrix(Rx)
            return sp.csr_matrix(Rx - Rw @ sp.csr_matrix(lu.solve(Gx.toarray())))

        Kq, Cv_, Ma, Bu = schur(Rq, Gq), schur(Rv, Gv), schur(Ra, Ga), schur(Ru, Gu)
    else:
        Kq, Cv_, Ma, Bu = sp.csr_matrix(Rq), sp.csr_matrix(Rv), sp.csr_matrix(Ra), sp.csr_matrix(Ru)
    return SecondOrderBlocks(Ma, Cv_, Kq, Bu, Sq_x, Sq_z, Sv_x, Sv_xd_out, Sa_xd, Sw, zint, lu, G)


def start_matrices(dae: Dae, params: dict | None = None):
    """``(M, K)`` (csr) of the mechanical part linearized at the start point with zero inputs (parameter
    overrides ``params`` applied; structural ones are ignored).

    Internal differential states (a Pade delay, a controller's integrator) are held at their start
    values: they act on the mechanics as inputs do, so M and K -- what a system damping option needs --
    are those of the structure alone.
    """
    op = operating_point(dae, None, params)
    jac = sparse_jacobians(dae, op)
    rows = None
    m = dae.mech
    if m.has_internal_states:
        first = 2 * len(m.inertial) + len(m.damped)           # x = [q_i, q_i', q_d, internal states]
        own = sp.csr_matrix(jac[0][:, first:])                # rows holding an internal state's derivative
        rows = [r for r in range(len(m.inertial) + len(m.coordinate_names), own.shape[0]) if own[r].nnz == 0]
        zint = [i for i in range(dae.nz) if i not in set(m.q_in_z.values())]
        if len(rows) != len(zint):
            require_second_order(dae)
    try:
        b = second_order_blocks(dae, jac, [], internal_rows=rows)
    except (SingularSystemError, ValueError, RuntimeError):
        if rows is None:
            raise
        require_second_order(dae)                             # not separable: the NotLinearError
    return sp.csr_matrix(b.M), sp.csr_matrix(b.K)
