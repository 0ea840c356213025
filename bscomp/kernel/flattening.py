"""Flatten a connected :class:`~bscomp.System` into an index-1 :class:`~bscomp.kernel.dae.Dae`.

The steps, one module each (one pass, linear in the number of components):

1. **Connection sets** (:mod:`~bscomp.kernel.aliases`). Union-find over port potentials: connected
   potentials become one *coordinate* (alias elimination); connected signals one signal. Each
   connection set's flows sum to zero, which is imposed below as the generalised force balance of its
   coordinate.
2. **Components** (:mod:`~bscomp.kernel.templates`, :mod:`~bscomp.kernel.instances`,
   :mod:`~bscomp.kernel.signals`). Each component class is processed once with CasADi symbols bound to
   its names; every instance calls the template. Explicit equations (``port.f - expr``, ``y - expr``,
   ``var - expr``) are solved locally, so flows, outputs and most internal variables never become DAE
   unknowns; free signals become inputs.
3. **Constraints** (:mod:`~bscomp.kernel.constraints`). The affine holonomic constraints ``A q + b = 0``
   (rigid joints, ideal lead screw ``s = r_g phi``, fixed points) are eliminated by sparse Gauss-Jordan
   with partial pivoting: ``q = T q_r + t0``. Their reactions ``A^T lambda`` vanish in the projected
   balance ``T^T Q(q, q', q'') = 0`` (principle of virtual work), so no index reduction is needed.
   Structural blocks (``LinearStructure``) are assembled as sparse ``M, C, K`` and projected with ``T``:
   they enter the residual as sparse matrix products, never as scalar expressions.
4. **State selection** (:mod:`~bscomp.kernel.states`). A reduced coordinate with inertia gets states
   (q, v); one with damping but no inertia is a first-order state; one with neither is algebraic.
5. **System damping** (:mod:`~bscomp.kernel.system_damping`), if the system carries one.
6. **Checks** (:mod:`~bscomp.kernel.checks`). Parameter values, connected ports, symbols, equation and
   unknown counts, structural rank of ``[dF/dx', dF/dz]`` (index 1) and a numeric LU at the start point;
   each failure raises a named error naming components.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from bscomp.errors import UnderdeterminedError
from bscomp.kernel.aliases import connection_sets, union_ports
from bscomp.kernel.checks import check_connected, check_counts, check_parameters, check_symbols
from bscomp.kernel.constraints import (
    apply_stages,
    eliminate_constraints,
    project_balance,
    project_blocks,
    substitution_stages,
)
from bscomp.kernel.dae import Dae, MechanicalInfo
from bscomp.kernel.instances import Assembly
from bscomp.kernel.signals import resolve_signals
from bscomp.kernel.states import Selectors, dae_variables, select_states
from bscomp.kernel.system import System
from bscomp.kernel.system_damping import apply_system_damping
from bscomp.kernel.templates import vc

__all__ = ["flatten"]


class _Leaf:
    """Bookkeeping of one leaf component during flattening."""

    def __init__(self, path, comp):
        self.path = path
        self.comp = comp


def flatten(system: System, *, check: bool = True) -> Dae:
    """Flatten a system into a :class:`~bscomp.kernel.dae.Dae` (see module docstring).

    Parameters
    ----------
    system : System
    check : bool
        Run the structural and numeric checks (index 1, non-singular start).

    Raises
    ------
    UnconnectedPortError, ModelDefinitionError, OverdeterminedError, UnderdeterminedError,
    HighIndexError, SingularSystemError, ParameterError
    """
    t_start = time.perf_counter()
    leaves = [_Leaf(p, c) for p, c in system.leaves()]
    if not leaves:
        raise UnderdeterminedError(f"system '{system.name}' has no components")
    by_path = {lf.path: lf for lf in leaves}
    check_parameters(leaves)

    # -- 1. connection sets --------------------------------------------------------------------
    uf, connected = union_ports(system, leaves, by_path)
    check_connected(leaves, connected)
    sets = connection_sets(leaves, by_path, uf, connected)
    nq = len(sets.coord_names)
    full = ([ca.SX.sym(n) for n in sets.coord_names], [ca.SX.sym(f"der({n})") for n in sets.coord_names],
            [ca.SX.sym(f"der(der({n}))") for n in sets.coord_names])
    sig_syms = [ca.SX.sym(n) for n in sets.sig_names]

    # -- 2. components and signals -------------------------------------------------------------
    asm = Assembly(sets, *full, sig_syms)
    for lf in leaves:
        asm.add(lf)
    p_all, p0 = asm.parameters()
    sig = resolve_signals(sets, sig_syms, asm.sig_def)

    # -- 3. constraint elimination and projection ------------------------------------------------
    T, t0, indep, dep_of = eliminate_constraints(asm.constraints, nq, sets.coord_names)
    nr = len(indep)
    Tcsr = T.tocsr()
    reduced = tuple([f[c] for c in indep] for f in full)
    stages = substitution_stages(sig, Tcsr, t0, dep_of, full, reduced)
    TT = Tcsr.T.tocsr()
    R, eqs_s = project_balance(asm.Q, TT, nr, asm.eqs, stages)
    Mr, Cr, Kr, Kt0 = project_blocks(asm.blocks, nq, Tcsr, TT, t0)

    # -- 4. state selection and the DAE's unknowns ------------------------------------------------
    Rv, inertial, damped, static = select_states(R, reduced[1], reduced[2], Mr, Cr, nr)
    rnames = [sets.coord_names[c] for c in indep]
    var = dae_variables(rnames, reduced, (inertial, damped, static), asm, sig_syms, sets.sig_names, sig.sig_loop)
    loop_eqs = [sig_syms[k] - asm.sig_def[k] for k in sig.sig_loop]
    if loop_eqs:
        loop_eqs = [apply_stages(e, stages) for e in loop_eqs]
    kin = [var.dq_in[i] - reduced[1][j] for i, j in enumerate(inertial)]
    Fsx = ca.SX(ca.vertcat(*(kin + [Rv[j] for j in range(nr)] + [eqs_s[j] for j in range(eqs_s.numel())]
                             + loop_eqs)))
    origins = ([f"kinematics of {rnames[j]}" for j in inertial]
               + [f"force balance at {rnames[j]}" for j in range(nr)] + asm.eq_origin
               + [f"algebraic loop through signal {sets.sig_names[k]}" for k in sig.sig_loop])
    xs, xds, zs = vc(var.X), vc(var.XD), vc(var.Z)
    for n, sym in zip(var.x_names + var.z_names, var.X + var.Z):
        asm.observables.setdefault(n, sym)
    us = vc(sig.u_syms)

    # -- checks: every symbol used must be known; as many equations as unknowns -------------------
    check_symbols(Fsx, ca.vertcat(xs, xds, zs, us, p_all))
    check_counts(Fsx.numel(), xs.numel() + zs.numel(), origins, var.x_names, var.z_names, leaves)

    # sparse structural part, in the balance rows (rows offset by len(kin))
    ni = len(inertial)
    sel = Selectors(inertial, damped, static)
    mech = MechanicalInfo(
        coordinate_names=rnames, coordinate_units=[sets.coord_units[c] for c in indep],
        full_coordinate_names=sets.coord_names, T=Tcsr, t0=t0, inertial=inertial, damped=damped, static=static,
        q_in_x=sel.q_in_x, q_in_z=sel.q_in_z, v_in_x=sel.v_in_x, v_in_xd=sel.v_in_xd, a_in_xd=sel.a_in_xd,
        balance_rows=list(range(ni, ni + nr)), M=Mr, C=Cr, K=Kr, Kt0=Kt0,
        has_internal_states=bool(asm.xint), port_coordinates=sets.port_coord)
    dae = Dae(
        name=system.name, xs=xs, xds=xds, zs=zs, us=us, ps=p_all, F_sx=Fsx, mech=mech,
        x_names=var.x_names, z_names=var.z_names, u_names=sig.u_names, u_units=sig.u_units, p_names=asm.p_names,
        p_units=asm.p_units, p0=p0,
        x_start=np.concatenate([np.zeros(2 * ni + len(damped)), np.asarray(asm.xint_start, float)]),
        z_start=np.concatenate([np.zeros(len(static)), np.asarray(asm.zint_start, float),
                                np.zeros(len(sig.sig_loop))]),
        eq_origin=origins, observables=asm.observables, substitutions=stages,
        structural_parameters=sorted(asm.structural), system=system, nonlinear_components=list(asm.nonlinear))

    # -- system damping, then the index-1 check ---------------------------------------------------
    if getattr(system, "damping", None) is not None:
        apply_system_damping(dae, system.damping)
    dae.stats["flatten_s"] = time.perf_counter() - t_start
    dae.stats["templates"] = sum(len(v) for v in asm.templates.values())   # templates (shared by instances)
    dae.stats["templates_built"] = asm.templates_built      # symbolic passes (the rest kept from an earlier flatten)
    if check:
        dae.check_index1()
    return dae
