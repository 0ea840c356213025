"""State selection: which reduced coordinate is a state, which is algebraic (flattening step 4).

After alias and constraint elimination every reduced coordinate ``q_r`` has a projected force balance
``T^T Q = 0`` (thesis Eq 3.44, ``M q'' + C q' + K q = F``). Its role in the DAE follows from what acts on
it, read off the balance's structure (Jacobian sparsity of the scalar part plus the columns of the
structural ``M``, ``C``):

* with **inertia** (``dR/dq''`` non-zero): two states, position ``q`` and velocity ``v = dt(q)``, the
  balance being the equation of ``v'`` (second-order states, Eq 5.1-5.3);
* with **damping but no inertia**: a first-order state ``q``, the balance giving ``q'``;
* with **neither** (a massless, undamped node): an algebraic unknown ``z`` (quasi-static).

This is Modelica's state selection for mechanical systems without dummy derivatives: the constraints
were eliminated beforehand, so the selection is static and the DAE stays index 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["select_states", "Selectors", "DaeVariables", "dae_variables"]


def select_states(R, qdr, qddr, Mr, Cr, nr):
    """Split the reduced coordinates into inertial, damped-only and static ones.

    Returns
    -------
    Rv : SX
        The projected balances stacked.
    inertial, damped, static : list of int
    """
    qddr_v = ca.vertcat(*qddr) if nr else ca.SX(0, 1)
    qdr_v = ca.vertcat(*qdr) if nr else ca.SX(0, 1)
    Rv = ca.vertcat(*[R[j] for j in range(nr)]) if nr else ca.SX(0, 1)
    Jm = ca.jacobian(Rv, qddr_v).sparsity() if nr else None
    Jc = ca.jacobian(Rv, qdr_v).sparsity() if nr else None
    m_cols = np.zeros(nr, bool)
    c_cols = np.zeros(nr, bool)
    if nr:
        m_cols[np.unique(np.array(Jm.get_col(), dtype=int))] = True if Jm.nnz() else m_cols[[]]
        c_cols[np.unique(np.array(Jc.get_col(), dtype=int))] = True if Jc.nnz() else c_cols[[]]
        m_cols |= np.asarray(abs(Mr).sum(axis=0)).ravel() > 0
        c_cols |= np.asarray(abs(Cr).sum(axis=0)).ravel() > 0
    inertial = [j for j in range(nr) if m_cols[j]]
    damped = [j for j in range(nr) if not m_cols[j] and c_cols[j]]
    static = [j for j in range(nr) if not m_cols[j] and not c_cols[j]]
    return Rv, inertial, damped, static


class Selectors:
    """Where each reduced coordinate's position/velocity/acceleration lives in (x, x', z)."""

    def __init__(self, inertial, damped, static):
        ni = len(inertial)
        self.q_in_x = {j: i for i, j in enumerate(inertial)}
        self.q_in_x.update({j: 2 * ni + i for i, j in enumerate(damped)})
        self.q_in_z = {j: i for i, j in enumerate(static)}
        self.v_in_x = {j: ni + i for i, j in enumerate(inertial)}
        self.v_in_xd = {j: 2 * ni + i for i, j in enumerate(damped)}
        self.a_in_xd = {j: ni + i for i, j in enumerate(inertial)}


@dataclass
class DaeVariables:
    """The DAE's unknowns: ``x = (q_i, v_i, q_d, x_int)``, ``x'``, ``z = (q_s, z_int, loop signals)``.

    ``dq_in`` are the symbols ``dt(q)`` of the inertial positions (the kinematic equations
    ``dt(q) - v = 0`` tie them to the velocities).
    """

    X: list
    XD: list
    Z: list
    x_names: list
    z_names: list
    dq_in: list


def dae_variables(rnames, reduced, roles, asm, sig_syms, sig_names, sig_loop) -> DaeVariables:
    """Order the unknowns: inertial positions, their velocities, damped positions, internal states;
    static coordinates, internal algebraic variables, loop signals.

    ``reduced`` = (q_r, q_r', q_r'') symbol lists, ``roles`` = (inertial, damped, static).
    """
    qr, qdr, qddr = reduced
    inertial, damped, static = roles
    dq_in = [ca.SX.sym(f"dt({rnames[j]})") for j in inertial]
    X = [qr[j] for j in inertial] + [qdr[j] for j in inertial] + [qr[j] for j in damped] + asm.xint
    XD = dq_in + [qddr[j] for j in inertial] + [qdr[j] for j in damped] + asm.xint_d
    Z = [qr[j] for j in static] + asm.zint + [sig_syms[k] for k in sig_loop]
    x_names = ([rnames[j] for j in inertial] + [f"der({rnames[j]})" for j in inertial]
               + [rnames[j] for j in damped] + asm.xint_names)
    z_names = [rnames[j] for j in static] + asm.zint_names + [sig_names[k] for k in sig_loop]
    return DaeVariables(X, XD, Z, x_names, z_names, dq_in)
