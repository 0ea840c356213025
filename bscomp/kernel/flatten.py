"""Flatten a connected :class:`~bscomp.System` into an index-1 :class:`~bscomp.kernel.dae.Dae`.

Algorithm (one pass, linear in the number of components):

1. **Connection sets.** Union-find over port potentials: connected potentials become one
   *coordinate* (alias elimination); connected signals one signal. Each connection set's flows sum to
   zero, which is imposed below as the generalised force balance of its coordinate.
2. **Components.** Every leaf component's methods are called once with CasADi symbols bound to its
   names. Explicit equations (``port.f - expr``, ``y - expr``, ``var - expr``) are solved locally, so
   flows, outputs and most internal variables never become DAE unknowns.
3. **Constraints.** The affine holonomic constraints ``A q + b = 0`` (rigid joints, ideal lead screw
   ``s = r_g phi``, fixed points) are eliminated by sparse Gauss-Jordan with partial pivoting:
   ``q = T q_r + t0``. Their reactions ``A^T lambda`` vanish in the projected balance
   ``T^T Q(q, q', q'') = 0`` (principle of virtual work), so no index reduction is needed.
4. **State selection.** A reduced coordinate with inertia gets states (q, v); one with damping but no
   inertia is a first-order state; one with neither is algebraic (quasi-static).
5. **Structural blocks** (``LinearStructure``) are assembled as sparse ``M, C, K`` and projected with
   ``T``: they enter the residual as sparse matrix products, never as scalar expressions.
6. **Checks.** Equation/unknown counts, structural rank of ``[dF/dx', dF/dz]`` (index 1), and a
   numeric LU at the start point; each failure raises a named error naming components.
"""

from __future__ import annotations

import time
from collections import defaultdict

import casadi as ca
import numpy as np
import scipy.sparse as sp

from bscomp.errors import (
    HighIndexError,
    ModelDefinitionError,
    OverdeterminedError,
    ParameterError,
    UnconnectedPortError,
    UnderdeterminedError,
)
from bscomp.kernel.component import Constraint, _Context, _PortBinding
from bscomp.kernel.dae import Dae, MechanicalInfo, dm_sparse
from bscomp.kernel.system import System
from bscomp.kernel.system_damping import apply_system_damping

__all__ = ["flatten"]


class _UnionFind:
    def __init__(self):
        self.parent = {}

    def add(self, k):
        self.parent.setdefault(k, k)

    def find(self, k):
        p = self.parent
        root = k
        while p[root] != root:
            root = p[root]
        while p[k] != root:
            p[k], k = root, p[k]
        return root

    def union(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            # keep the earlier-declared key as root (stable names)
            if self._order[ra] <= self._order[rb]:
                self.parent[rb] = ra
            else:
                self.parent[ra] = rb


def _eliminate_explicit(eqs, unknowns, pvals):
    """Solve equations that are affine in one unknown with a constant (or parameter) coefficient.

    Returns (solutions {index: expr}, remaining equations, indices of equations used). Which equation
    depends on which unknown is tracked structurally (Jacobian sparsity, updated on substitution), so a
    solution is substituted only where it occurs: a component with hundreds of port flows over one big
    expression graph costs one pass per solved flow, not one per (flow, equation) pair.
    """
    solved = {}
    remaining = list(eqs)
    used = set()
    if not unknowns or not eqs:
        return solved, remaining, used
    usyms = list(unknowns)
    U = ca.vertcat(*usyms)
    pattern = ca.jacobian_sparsity(ca.vertcat(*remaining), U)
    deps = [set() for _ in remaining]
    for r, c in zip(*pattern.get_triplet(), strict=True):
        deps[r].add(c)
    sdeps = {}
    # batch: an unknown that occurs in one equation only, with a constant non-zero coefficient, is
    # solved from it without touching any other equation (typically a port flow: ``p.f - f(q) = 0``);
    # all such solutions cost one Jacobian and one substitution pass over the shared graph
    occurs = {}
    for k, dk in enumerate(deps):
        for i in dk:
            occurs.setdefault(i, []).append(k)
    J = ca.jacobian(ca.vertcat(*remaining), U)
    batch = {}
    for k, dk in enumerate(deps):
        for i in sorted(dk):
            if len(occurs[i]) != 1 or i in batch.values():
                continue
            coef = J[k, i]
            if not coef.is_constant():
                continue
            c = float(ca.evalf(coef))
            if c != 0.0 and np.isfinite(c):
                batch[k] = i
            break
    if batch:
        ks = sorted(batch)
        rest = ca.substitute(ca.vertcat(*[remaining[k] for k in ks]), ca.vertcat(*[usyms[batch[k]] for k in ks]),
                             ca.SX.zeros(len(ks)))
        for r, k in enumerate(ks):
            i = batch[k]
            solved[i] = -rest[r] / float(ca.evalf(J[k, i]))
            used.add(k)
            sdeps[i] = deps[k] - {i}
    progress = True
    while progress:
        progress = False
        for k, eq in enumerate(remaining):
            if k in used:
                continue
            for i in sorted(deps[k]):
                if i in solved:
                    continue
                u = usyms[i]
                coef = ca.jacobian(eq, u)
                if ca.depends_on(coef, U) or ca.depends_on(coef, pvals[2]):
                    continue
                if coef.is_constant():
                    c = float(ca.evalf(coef))
                else:
                    c = float(ca.evalf(ca.substitute(coef, pvals[0], pvals[1])))
                if c == 0.0 or not np.isfinite(c):
                    continue
                rest = ca.substitute(eq, u, ca.SX(0))
                expr = -rest / coef
                solved[i] = expr
                used.add(k)
                edeps = deps[k] - {i}
                sdeps[i] = edeps
                for j in range(len(remaining)):
                    if j not in used and i in deps[j]:
                        remaining[j] = ca.substitute(remaining[j], u, expr)
                        deps[j] = (deps[j] - {i}) | edeps
                for j in list(solved):
                    if j != i and i in sdeps[j]:
                        solved[j] = ca.substitute(solved[j], u, expr)
                        sdeps[j] = (sdeps[j] - {i}) | edeps
                progress = True
                break
    return solved, remaining, used


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

    # -- parameters must have values -----------------------------------------------------------
    for lf in leaves:
        for n, p in lf.comp.parameters().items():
            if lf.comp._values.get(n) is None:
                raise ParameterError(f"parameter {lf.path}.{n} [{p.unit}] has no value ({p.doc}); set it with "
                                     f"system.set('{lf.path}.{n}', value)")

    # -- 1. connection sets --------------------------------------------------------------------
    uf = _UnionFind()
    order = {}
    connected = set()
    for lf in leaves:
        for pname, spec in lf.comp.ports().items():
            for i in range(len(spec.kind.potentials)):
                key = (lf.path, pname, i)
                order[key] = len(order)
                uf.add(key)
    uf._order = order
    for a, b in system.connections():
        pa, _, na = a.rpartition(".")
        pb, _, nb = b.rpartition(".")
        spec = by_path[pa].comp.ports()[na]
        connected.add((pa, na))
        connected.add((pb, nb))
        for i in range(len(spec.kind.potentials)):
            uf.union((pa, na, i), (pb, nb, i))

    for lf in leaves:
        for pname, spec in lf.comp.ports().items():
            if not spec.kind.is_signal and not spec.optional and (lf.path, pname) not in connected:
                raise UnconnectedPortError(
                    f"port '{lf.path}.{pname}' ({spec.kind.name} of {type(lf.comp).__name__}) is not connected; "
                    f"connect it with system.connect('{lf.path}.{pname}', ...) or fix it to ground with a "
                    "Fixed/FixedRotational component")

    # physical coordinates and signal sets
    coord_of = {}          # root key -> coordinate index
    coord_names, coord_units = [], []
    port_coord = {}                        # "path.port.potential" -> full coordinate index
    named = set()                          # coordinates named after a body (``mass.s``)
    sig_of = {}            # root key -> signal index
    sig_names, sig_units, sig_out_owner, sig_inputs = [], [], {}, defaultdict(list)
    for lf in leaves:
        for pname, spec in lf.comp.ports().items():
            for i, (pot, unit) in enumerate(spec.kind.potentials):
                root = uf.find((lf.path, pname, i))
                if spec.kind.is_signal:
                    if root not in sig_of:
                        sig_of[root] = len(sig_names)
                        sig_names.append(f"{lf.path}.{pname}")
                        sig_units.append(spec.unit)
                    k = sig_of[root]
                    if spec.kind.signal == "out":
                        sig_out_owner[k] = f"{lf.path}.{pname}"
                        sig_names[k] = f"{lf.path}.{pname}"
                    else:
                        sig_inputs[k].append((lf.path, pname, spec))
                else:
                    if root not in coord_of:
                        coord_of[root] = len(coord_names)
                        rp, rn, _ = root
                        rpot = by_path[rp].comp.ports()[rn].kind.potentials[i][0]
                        coord_names.append(f"{rp}.{rn}.{rpot}")
                        coord_units.append(unit)
                    alias = getattr(lf.comp, "coordinate_names", {}).get(f"{pname}.{pot}")
                    c = coord_of[root]
                    port_coord[f"{lf.path}.{pname}.{pot}"] = c
                    if alias and c not in named:
                        named.add(c)
                        coord_names[c] = f"{lf.path}.{alias}"
    nq = len(coord_names)
    q_full = [ca.SX.sym(n) for n in coord_names]
    qd_full = [ca.SX.sym(f"der({n})") for n in coord_names]
    qdd_full = [ca.SX.sym(f"der(der({n}))") for n in coord_names]
    sig_syms = [ca.SX.sym(n) for n in sig_names]

    # -- 2. components -------------------------------------------------------------------------
    p_syms, p_vals, p_names, p_units = [], [], [], []
    Q = [[] for _ in range(nq)]            # explicit flow contributions per coordinate
    eqs, eq_origin = [], []                # global residual equations (internal)
    xint, xint_d, xint_names, xint_start = [], [], [], []
    zint, zint_names, zint_start = [], [], []
    sig_def = {}                           # signal index -> expression
    constraints = []                       # (coeff dict, const, solve_for coord, origin)
    observables = {}
    blocks = []                            # (coord indices, M, C, K)
    structural = set()
    templates = {}
    for lf in leaves:
        comp, path = lf.comp, lf.path
        ports = comp.ports()
        params = comp.parameters()
        variables = comp.variables()
        key = (type(comp), tuple((n, s.kind.name, s.optional) for n, s in ports.items()),
               tuple((n, np.shape(comp._values[n])) for n in params), tuple(variables),
               # instance configuration that shapes equations/constraints beyond parameters (dof
               # subsets, shape-function coefficients, attachment offsets): see Component docs
               getattr(comp, "template_key", lambda: None)())
        tpl = templates.get(key)
        if tpl is None:
            tpl = templates[key] = _Template(comp, path, ports, params, variables)
        # numeric/structural parts are per instance
        comp.__dict__["_read_params"] = set()
        struct = comp.structure()
        read_struct = set(comp.__dict__.pop("_read_params", set()))
        block = _block(struct, path, comp, {p: [coord_of[uf.find((path, p, i))]
                                                for i in range(len(sp_.kind.potentials))]
                                            for p, sp_ in ports.items() if not sp_.kind.is_signal}) \
            if struct is not None else None
        struct_coords = set(block[0]) if block is not None else set()  # flows given by M q'' + C q' + K q

        # global symbols of this instance
        pv = [np.asarray(comp._values[n], dtype=float) for n in params]
        psym = []
        for (n, p), vv in zip(params.items(), pv):
            shape = vv.shape
            sym = ca.SX.sym(f"{path}.{n}", *(shape if len(shape) == 2 else (shape[0], 1) if shape else (1, 1)))
            psym.append(sym)
            p_syms.append(ca.vec(sym))
            p_vals.append(vv.reshape(-1, order="F"))
            cnt = int(vv.size)
            p_names.extend([f"{path}.{n}"] if cnt == 1 else [f"{path}.{n}[{j}]" for j in range(cnt)])
            p_units.extend([p.unit] * cnt)
        loc_pv = np.concatenate([v.reshape(-1, order="F") for v in pv]) if pv else np.zeros(0)
        port_coords = {}
        for pname in tpl.phys_ports:
            port_coords[pname] = [coord_of[uf.find((path, pname, i))]
                                  for i in range(len(ports[pname].kind.potentials))]
        cidx = [c for pname in tpl.phys_ports for c in port_coords[pname]]
        sidx = [sig_of[uf.find((path, pname, 0))] for pname in tpl.sig_ports]
        vsym = [ca.SX.sym(f"{path}.{n}") for n in tpl.var_names]
        dsym = [ca.SX.sym(f"der({path}.{n})") for n in tpl.var_names]
        out = tpl.fun(_vc([q_full[c] for c in cidx]), _vc([qd_full[c] for c in cidx]),
                      _vc([qdd_full[c] for c in cidx]), _vc([sig_syms[k] for k in sidx]),
                      _vc([ca.vec(s) for s in psym]), _vc(vsym), _vc(dsym))
        flows_e, outs_e, rem_e, obs_e = out
        for j, c in enumerate(cidx):
            st = tpl.flow_status[j]
            if st == "solved":
                Q[c].append(flows_e[tpl.flow_pos[j]])
            elif st == "constrained" or c in struct_coords:
                pass
            else:  # undefined: fine only for an unconnected optional port
                pname = tpl.flow_port[j]
                if not (ports[pname].optional and (path, pname) not in connected):
                    raise ModelDefinitionError(
                        f"component '{path}' ({type(comp).__name__}) does not define the flow of port '{pname}': "
                        "give an equation 'port.f - expr', or a constraint on its potential (ideal joint)")
        for j, k in enumerate(tpl.out_sig_idx):
            sig_def[sidx[k]] = outs_e[j]
        for j, n in enumerate(tpl.var_names):
            if n in tpl.alg_unsolved:
                zint.append(vsym[j])
                zint_names.append(f"{path}.{n}")
                zint_start.append(variables[n].start)
            elif n in tpl.diff_vars:
                xint.append(vsym[j])
                xint_d.append(dsym[j])
                xint_names.append(f"{path}.{n}")
                xint_start.append(variables[n].start)
        for j, k in enumerate(tpl.rem_index):
            eqs.append(rem_e[j])
            eq_origin.append(f"equation {k} of component '{path}' ({type(comp).__name__})")
        for j, n in enumerate(tpl.obs_names):
            observables[f"{path}.{n}"] = obs_e[j]
        for pname, idx in port_coords.items():
            for (pot, _), c in zip(ports[pname].kind.potentials, idx):
                observables[f"{path}.{pname}.{pot}"] = q_full[c]
        for pname, k in zip(tpl.sig_ports, sidx):
            observables[f"{path}.{pname}"] = sig_syms[k]
        for n, s in zip(params, psym):
            observables[f"{path}.{n}"] = s
        # constraints: numeric coefficients per instance
        if tpl.n_cons:
            J, b = tpl.cons_fun(loc_pv)
            J = np.asarray(J, float).reshape(tpl.n_cons, len(cidx))
            b = np.asarray(b, float).ravel()
            for r in range(tpl.n_cons):
                coeffs = {}
                for j, a in enumerate(J[r]):
                    if a != 0.0:
                        coeffs[cidx[j]] = coeffs.get(cidx[j], 0.0) + float(a)
                sf = tpl.cons_solve_for[r]
                constraints.append((coeffs, float(b[r]), cidx[sf] if sf is not None else None,
                                    f"constraint of '{path}' ({type(comp).__name__})"))
            structural.update(f"{path}.{n}" for n in tpl.cons_params)
        if struct is not None:
            structural.update(f"{path}.{n}" for n in read_struct)
            blocks.append(block)
    p_all = ca.vertcat(*p_syms) if p_syms else ca.SX(0, 1)
    p0 = np.concatenate(p_vals) if p_vals else np.zeros(0)

    # -- signals: inputs, constants, definitions -----------------------------------------------
    u_syms, u_names, u_units = [], [], []
    const_from, const_to = [], []
    for k in range(len(sig_names)):
        if k in sig_def:
            continue
        ins = sig_inputs[k]
        defaults = [spec.default for _, _, spec in ins if spec.default is not None]
        if defaults:
            const_from.append(sig_syms[k])
            const_to.append(ca.SX(float(defaults[0])))
        else:
            u_syms.append(sig_syms[k])
            u_names.append(sig_names[k])
            u_units.append(sig_units[k])
    sig_from, sig_to, sig_loop = _order_signal_definitions(sig_def, sig_syms)
    sig_from += const_from
    sig_to += const_to

    # -- 3. constraint elimination --------------------------------------------------------------
    T, t0, indep, dep_of = _eliminate_constraints(constraints, nq, coord_names)
    nr = len(indep)
    Tcsr = T.tocsr()

    # substitution of dependent coordinates and defined signals
    dep_idx = [c for c in range(nq) if c not in dep_of]
    dep_idx = sorted(dep_of)
    qr = [q_full[c] for c in indep]
    qdr = [qd_full[c] for c in indep]
    qddr = [qdd_full[c] for c in indep]
    sub_from = []
    sub_to = []
    if dep_idx:
        Td = dm_sparse(Tcsr[dep_idx, :])
        qr_v, qdr_v, qddr_v = ca.vertcat(*qr), ca.vertcat(*qdr), ca.vertcat(*qddr)
        qdep = ca.mtimes(Td, qr_v) + ca.DM(t0[dep_idx])
        qddep = ca.mtimes(Td, qdr_v)
        qdddep = ca.mtimes(Td, qddr_v)
        for j, c in enumerate(dep_idx):
            sub_from += [q_full[c], qd_full[c], qdd_full[c]]
            sub_to += [qdep[j], qddep[j], qdddep[j]]
    # signals first (their definitions may use dependent coordinates), then coordinates
    stages = [(sig_from, sig_to), (sub_from, sub_to)]

    Qsum = [ca.sum1(ca.vertcat(*lst)) if lst else ca.SX(0) for lst in Q]
    # projected balance R = T^T Q (sparse, never dense)
    TT = Tcsr.T.tocsr()
    R = []
    for j in range(nr):
        row = slice(TT.indptr[j], TT.indptr[j + 1])
        terms = [float(a) * Qsum[c] if a != 1.0 else Qsum[c] for c, a in zip(TT.indices[row], TT.data[row])]
        R.append(ca.sum1(ca.vertcat(*terms)) if terms else ca.SX(0))
    big = _apply_stages(ca.vertcat(*(R + eqs)), stages)
    R = big[:nr]
    eqs_s = big[nr:]

    # structural blocks: project
    Ms, Cs, Ks = (sp.csr_matrix((nq, nq)) for _ in range(3))
    for idx, Mb, Cb, Kb in blocks:
        P = sp.csr_matrix((np.ones(len(idx)), (idx, np.arange(len(idx)))), shape=(nq, len(idx)))
        if Mb is not None:
            Ms = Ms + P @ sp.csr_matrix(Mb) @ P.T
        if Cb is not None:
            Cs = Cs + P @ sp.csr_matrix(Cb) @ P.T
        if Kb is not None:
            Ks = Ks + P @ sp.csr_matrix(Kb) @ P.T
    Mr = (TT @ Ms @ Tcsr).tocsc()
    Cr = (TT @ Cs @ Tcsr).tocsc()
    Kr = (TT @ Ks @ Tcsr).tocsc()
    # affine offset of dependent coordinates acting through structural stiffness
    Kt0 = TT @ (Ks @ t0) if np.any(t0) else np.zeros(nr)

    # -- 4. state selection ---------------------------------------------------------------------
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

    # -- 5. DAE symbols ---------------------------------------------------------------------------
    rnames = [coord_names[c] for c in indep]
    dq_in = [ca.SX.sym(f"dt({rnames[j]})") for j in inertial]
    X = [qr[j] for j in inertial] + [qdr[j] for j in inertial] + [qr[j] for j in damped] + xint
    XD = dq_in + [qddr[j] for j in inertial] + [qdr[j] for j in damped] + xint_d
    Z = [qr[j] for j in static] + zint + [sig_syms[k] for k in sig_loop]
    x_names = ([rnames[j] for j in inertial] + [f"der({rnames[j]})" for j in inertial]
               + [rnames[j] for j in damped] + xint_names)
    z_names = [rnames[j] for j in static] + zint_names + [sig_names[k] for k in sig_loop]
    loop_eqs = [sig_syms[k] - sig_def[k] for k in sig_loop]
    if loop_eqs:
        loop_eqs = [_apply_stages(e, stages) for e in loop_eqs]
    kin = [dq_in[i] - qdr[j] for i, j in enumerate(inertial)]
    Fsx = ca.SX(ca.vertcat(*(kin + [Rv[j] for j in range(nr)] + [eqs_s[j] for j in range(eqs_s.numel())] + loop_eqs)))
    origins = ([f"kinematics of {rnames[j]}" for j in inertial]
               + [f"force balance at {rnames[j]}" for j in range(nr)] + eq_origin
               + [f"algebraic loop through signal {sig_names[k]}" for k in sig_loop])
    xs, xds, zs = _vc(X), _vc(XD), _vc(Z)
    for n, sym in zip(x_names + z_names, X + Z):
        observables.setdefault(n, sym)
    us = _vc(u_syms)

    # every symbol used must be known
    known = ca.vertcat(xs, xds, zs, us, p_all)
    _check_symbols(Fsx, known, rnames, inertial, damped, static, qdr, qddr)

    n_eq, n_unk = Fsx.numel(), xs.numel() + zs.numel()
    if n_eq != n_unk:
        _count_error(n_eq, n_unk, origins, x_names, z_names, leaves)

    # sparse structural part, in the balance rows (rows offset by len(kin))
    n_x, n_z = xs.numel(), zs.numel()
    ni = len(inertial)
    sel = _Selectors(nr, n_x, n_z, inertial, damped, static)
    mech = MechanicalInfo(
        coordinate_names=rnames, coordinate_units=[coord_units[c] for c in indep],
        full_coordinate_names=coord_names, T=Tcsr, t0=t0, inertial=inertial, damped=damped, static=static,
        q_in_x=sel.q_in_x, q_in_z=sel.q_in_z, v_in_x=sel.v_in_x, v_in_xd=sel.v_in_xd, a_in_xd=sel.a_in_xd,
        balance_rows=list(range(ni, ni + nr)), M=Mr, C=Cr, K=Kr, Kt0=Kt0,
        has_internal_states=bool(xint), port_coordinates=port_coord)

    dae = Dae(
        name=system.name, xs=xs, xds=xds, zs=zs, us=us, ps=p_all, F_sx=Fsx, mech=mech,
        x_names=x_names, z_names=z_names, u_names=u_names, u_units=u_units, p_names=p_names, p_units=p_units,
        p0=p0, x_start=np.concatenate([np.zeros(2 * ni + len(damped)), np.asarray(xint_start, float)]),
        z_start=np.concatenate([np.zeros(len(static)), np.asarray(zint_start, float), np.zeros(len(sig_loop))]),
        eq_origin=origins, observables=observables, substitutions=stages,
        structural_parameters=sorted(structural), system=system)
    if getattr(system, "damping", None) is not None:
        apply_system_damping(dae, system.damping)
    dae.stats["flatten_s"] = time.perf_counter() - t_start
    if check:
        dae.check_index1()
    return dae


def _apply_stages(e, stages):
    """Apply substitution stages in order (each stage simultaneous)."""
    for frm, to in stages:
        if frm:
            e = ca.substitute(e, ca.vertcat(*frm), ca.densify(ca.vertcat(*to)))
    return e


class _Template:
    """Symbolic processing of one component class, done once and reused for every instance.

    The component's methods are called with local symbols; explicit equations are solved; the result
    is a CasADi Function of (q, q', q'', signals, p, vars, der(vars)) that each instance calls with its
    own global symbols (inlined), so N identical components cost one symbolic pass, not N.
    """

    def __init__(self, comp, path, ports, params, variables):
        self.phys_ports = [n for n, s in ports.items() if not s.kind.is_signal]
        self.sig_ports = [n for n, s in ports.items() if s.kind.is_signal]
        ctx = _Context()
        psyms = []
        for n in params:
            shape = np.shape(comp._values[n])
            sym = ca.SX.sym(n, *(shape if len(shape) == 2 else (shape[0], 1) if shape else (1, 1)))
            ctx.params[n] = sym
            psyms.append(ca.vec(sym))
        q, qd, qdd, flows, flow_port = [], [], [], [], []
        for pname in self.phys_ports:
            spec = ports[pname]
            pq = [ca.SX.sym(f"{pname}.{pot}") for pot, _ in spec.kind.potentials]
            pqd = [ca.SX.sym(f"der({pname}.{pot})") for pot, _ in spec.kind.potentials]
            pqdd = [ca.SX.sym(f"der(der({pname}.{pot}))") for pot, _ in spec.kind.potentials]
            fl = [ca.SX.sym(f"{pname}.{fn}") for fn, _ in spec.kind.flows]
            q += pq
            qd += pqd
            qdd += pqdd
            flows += fl
            flow_port += [pname] * len(fl)
            ctx.ports[pname] = _PortBinding(spec, pq, fl, None)
            for a, b_, c in zip(pq, pqd, pqdd):
                ctx.der_pairs += [(a, b_), (b_, c)]
        sig = []
        out_sig = []
        for k, pname in enumerate(self.sig_ports):
            spec = ports[pname]
            s = ca.SX.sym(pname)
            sig.append(s)
            ctx.ports[pname] = _PortBinding(spec, [s], [], None)
            if spec.kind.signal == "out":
                out_sig.append(k)
        self.var_names = list(variables)
        vs = [ca.SX.sym(n) for n in self.var_names]
        ds = [ca.SX.sym(f"der({n})") for n in self.var_names]
        for n, v, d in zip(self.var_names, vs, ds):
            ctx.vars[n] = v
            ctx.dvars[n] = d
            ctx.der_pairs.append((v, d))
        comp.__dict__["_ctx"] = ctx
        try:
            ceqs = [ca.SX(e) for e in comp.connector_equations() + comp.equations()]
            cons = comp.constraints()
            obs = comp.observables()
        except ModelDefinitionError:
            raise
        except Exception as exc:  # a bug in a component file: say which one
            raise ModelDefinitionError(f"component '{path}' ({type(comp).__name__}) failed while building its "
                                       f"equations: {type(exc).__name__}: {exc}") from exc
        finally:
            comp.__dict__["_ctx"] = None
        ceqs = [e[j] for e in ceqs for j in range(e.numel())]
        p_loc = _vc(psyms)
        pv = np.concatenate([np.asarray(comp._values[n], float).reshape(-1, order="F") for n in params]) \
            if params else np.zeros(0)
        self.diff_vars = {n for n, d in zip(self.var_names, ds) if any(ca.depends_on(e, d) for e in ceqs)}
        alg = [n for n in self.var_names if n not in self.diff_vars]
        unknowns = flows + [sig[k] for k in out_sig] + [ctx.vars[n] for n in alg]
        forbid = _vc([ctx.dvars[n] for n in self.var_names])
        solved, remaining, used = _eliminate_explicit(ceqs, unknowns, (p_loc, pv, forbid))
        nflow = len(flows)
        sub_from = [unknowns[i] for i in solved]
        sub_to = [solved[i] for i in solved]

        def _sub(e):
            if not sub_from:
                return e
            return ca.substitute(e, ca.vertcat(*sub_from), ca.densify(ca.vertcat(*sub_to)))

        # constraints (affine in q, numeric coefficients evaluated per instance)
        cexprs, self.cons_solve_for = [], []
        for cexpr in cons:
            solve_for = None
            if isinstance(cexpr, Constraint):
                solve_for, cexpr = cexpr.solve_for, cexpr.expr
            cexpr = ca.SX(cexpr)
            for j in range(cexpr.numel()):
                cexprs.append(cexpr[j])
                sf = None
                if solve_for is not None:
                    for i, qq in enumerate(q):
                        if ca.is_equal(qq, ca.SX(solve_for)):
                            sf = i
                self.cons_solve_for.append(sf)
        self.n_cons = len(cexprs)
        con_q = set()
        qv = _vc(q)
        if cexprs:
            C = ca.vertcat(*cexprs)
            for o in [_vc(qd), _vc(qdd)] + vs + flows:
                if o.numel() and ca.depends_on(C, o):
                    raise ModelDefinitionError(
                        f"constraint of '{path}' ({type(comp).__name__}) involves velocities, flows or variables: "
                        "constraints must be affine in port potentials (write other laws as equations)")
            J = ca.jacobian(C, qv)
            if ca.depends_on(J, qv):
                raise ModelDefinitionError(f"constraint of '{path}' ({type(comp).__name__}) is not affine in the "
                                           "port potentials; only linear holonomic constraints are eliminated")
            b = ca.substitute(C, qv, ca.DM.zeros(qv.shape))
            self.cons_fun = ca.Function("cons", [p_loc], [ca.densify(J), ca.densify(b)])
            spj = J.sparsity()
            con_q = set(int(c) for c in spj.get_col())
            self.cons_params = [n for n, s in ctx.params.items() if ca.depends_on(C, ca.vec(s))]
        else:
            self.cons_params = []
        self.flow_status, self.flow_pos, self.flow_port = [], [], flow_port
        fl_out = []
        for i, f in enumerate(flows):
            if i in solved:
                self.flow_status.append("solved")
                self.flow_pos.append(len(fl_out))
                fl_out.append(solved[i])
                continue
            self.flow_pos.append(None)
            if any(ca.depends_on(e, f) for k, e in enumerate(remaining) if k not in used):
                raise ModelDefinitionError(
                    f"component '{path}' ({type(comp).__name__}) defines flow '{f.name()}' implicitly; write it "
                    "explicitly as an equation 'port.f - expr' (or introduce a Variable)")
            self.flow_status.append("constrained" if i in con_q else "undefined")
        outs = []
        self.out_sig_idx = []
        for j, k in enumerate(out_sig):
            if nflow + j not in solved:
                raise ModelDefinitionError(
                    f"component '{path}' ({type(comp).__name__}) does not define its output '{self.sig_ports[k]}' "
                    "explicitly; add an equation 'port.y - expr'")
            outs.append(solved[nflow + j])
            self.out_sig_idx.append(k)
        self.alg_unsolved = {n for j, n in enumerate(alg) if nflow + len(out_sig) + j not in solved}
        self.rem_index = [k for k in range(len(remaining)) if k not in used]
        rem = [remaining[k] for k in self.rem_index]
        self.obs_names = list(self.var_names) + list(obs)
        obs_e = [_sub(v) for v in vs] + [_sub(ca.SX(e)) for e in obs.values()]
        obs_e = [e if e.numel() == 1 else e[0] for e in obs_e]
        self.fun = ca.Function(
            f"tpl_{type(comp).__name__}",
            [qv, _vc(qd), _vc(qdd), _vc(sig), p_loc, _vc(vs), _vc(ds)],
            [_vc(fl_out), _vc(outs), _vc(rem), _vc(obs_e)])


def _vc(lst):
    return ca.vertcat(*lst) if lst else ca.SX(0, 1)


class _Selectors:
    """Where each reduced coordinate's position/velocity/acceleration lives in (x, x', z)."""

    def __init__(self, nr, n_x, n_z, inertial, damped, static):
        ni = len(inertial)
        self.q_in_x = {j: i for i, j in enumerate(inertial)}
        self.q_in_x.update({j: 2 * ni + i for i, j in enumerate(damped)})
        self.q_in_z = {j: i for i, j in enumerate(static)}
        self.v_in_x = {j: ni + i for i, j in enumerate(inertial)}
        self.v_in_xd = {j: 2 * ni + i for i, j in enumerate(damped)}
        self.a_in_xd = {j: ni + i for i, j in enumerate(inertial)}


def _block(struct, path, comp, port_coords):
    idx = []
    for d in struct.dofs:
        pname, _, pot = d.partition(".")
        spec = comp.ports().get(pname)
        if spec is None or spec.kind.is_signal:
            raise ModelDefinitionError(f"structure() of '{path}' names dof '{d}': no physical port '{pname}'")
        names = [n for n, _ in spec.kind.potentials]
        if pot not in names:
            raise ModelDefinitionError(f"structure() of '{path}' names dof '{d}': port '{pname}' has {names}")
        idx.append(port_coords[pname][names.index(pot)])
    n = len(idx)
    mats = []
    for name, m in (("M", struct.M), ("C", struct.C), ("K", struct.K)):
        if m is None:
            mats.append(None)
            continue
        if m.shape != (n, n):
            raise ModelDefinitionError(f"structure() of '{path}': {name} is {m.shape}, expected ({n}, {n})")
        mats.append(m)
    return (idx, *mats)


def _eliminate_constraints(constraints, nq, coord_names):
    """Sparse Gauss-Jordan with partial pivoting: q = T q_r + t0."""
    dep = {}                      # coordinate -> (dict{coord: coef}, const)
    users = defaultdict(set)      # independent coordinate -> dependents that reference it
    origin_of = {}
    for coeffs, b, sf, origin in constraints:
        lin = defaultdict(float)
        const = b
        for c, a in coeffs.items():
            if c in dep:
                d, k = dep[c]
                for j, t in d.items():
                    lin[j] += a * t
                const += a * k
            else:
                lin[c] += a
        scale = max([abs(a) for a in coeffs.values()] + [1e-300])
        lin = {c: a for c, a in lin.items() if abs(a) > 1e-12 * scale}
        if not lin:
            names = ", ".join(coord_names[c] for c in coeffs)
            who = ", ".join(origin_of.get(c, "?") for c in coeffs if c in origin_of)
            if abs(const) > 1e-9 * max(1.0, abs(b)):
                raise OverdeterminedError(f"inconsistent constraints on {names}: {origin} contradicts {who}; "
                                          "remove one of them")
            raise OverdeterminedError(f"redundant constraint on {names}: {origin} repeats what {who} already "
                                      "imposes (a closed kinematic loop or a point fixed twice); remove one of them")
        if sf is not None and sf in lin:
            piv = sf
        else:
            piv = max(lin, key=lambda c: (abs(lin[c]) * (1 + 1e-9), c))
        ap = lin.pop(piv)
        expr = {j: -a / ap for j, a in lin.items()}
        kconst = -const / ap
        # substitute pivot into existing dependents
        for d_c in list(users.get(piv, ())):
            d, k = dep[d_c]
            t = d.pop(piv)
            for j, a in expr.items():
                d[j] = d.get(j, 0.0) + t * a
                users[j].add(d_c)
            dep[d_c] = (d, k + t * kconst)
        users.pop(piv, None)
        dep[piv] = (expr, kconst)
        origin_of[piv] = origin
        for j in expr:
            users[j].add(piv)
    indep = [c for c in range(nq) if c not in dep]
    col = {c: i for i, c in enumerate(indep)}
    rows, cols, vals = [], [], []
    for c in indep:
        rows.append(c)
        cols.append(col[c])
        vals.append(1.0)
    t0 = np.zeros(nq)
    for c, (d, k) in dep.items():
        t0[c] = k
        for j, a in d.items():
            if a != 0.0:
                rows.append(c)
                cols.append(col[j])
                vals.append(a)
    T = sp.coo_matrix((vals, (rows, cols)), shape=(nq, len(indep)))
    return T, t0, indep, dep


def _order_signal_definitions(sig_def, sig_syms):
    """Topologically order signal definitions; members of cycles become algebraic variables."""
    keys = list(sig_def)
    deps = {}
    for k in keys:
        e = sig_def[k]
        deps[k] = [j for j in keys if j != k and ca.depends_on(e, sig_syms[j])]
        if ca.depends_on(e, sig_syms[k]):
            deps[k].append(k)
    order, state = [], {}
    loop = set()

    def visit(k, stack):
        st = state.get(k)
        if st == 2:
            return
        if st == 1:
            loop.update(stack[stack.index(k):])
            return
        state[k] = 1
        stack.append(k)
        for j in deps[k]:
            visit(j, stack)
        stack.pop()
        state[k] = 2
        order.append(k)

    for k in keys:
        visit(k, [])
    # resolve in dependency order (dependencies first)
    resolved = {}
    for k in order:
        if k in loop:
            continue
        e = sig_def[k]
        dd = [j for j in deps[k] if j in resolved]
        if dd:
            e = ca.substitute(e, ca.vertcat(*[sig_syms[j] for j in dd]), ca.vertcat(*[resolved[j] for j in dd]))
        resolved[k] = e
    return [sig_syms[k] for k in resolved], [resolved[k] for k in resolved], sorted(loop)


def _check_symbols(F, known, rnames, inertial, damped, static, qdr, qddr):
    used = ca.symvar(F)
    kset = {s.name() for s in ca.symvar(known)}
    bad = [s.name() for s in used if s.name() not in kset]
    if not bad:
        return
    msgs = []
    for b in bad:
        if b.startswith("der(der("):
            msgs.append(f"the acceleration {b} of a coordinate without inertia is used (an acceleration sensor or "
                        "inertial force on a massless node): add a mass there")
        elif b.startswith("der("):
            msgs.append(f"the velocity {b} of a coordinate with neither inertia nor damping is used: add a mass "
                        "or a damper there")
        else:
            msgs.append(f"symbol {b} is not a variable of the system")
    raise HighIndexError("; ".join(msgs))


def _count_error(n_eq, n_unk, origins, x_names, z_names, leaves):
    comp_lines = []
    for lf in leaves:
        nv = len(lf.comp.variables())
        if nv:
            comp_lines.append(f"{lf.path} ({type(lf.comp).__name__}): {nv} variable(s)")
    detail = "; ".join(comp_lines[:20])
    if n_eq > n_unk:
        raise OverdeterminedError(
            f"{n_eq} equations for {n_unk} unknowns: {n_eq - n_unk} equation(s) too many. Internal equations: "
            f"{[o for o in origins if o.startswith('equation')][:20]}. Components with variables: {detail}. "
            "A component gives one equation per variable plus one per flow/output it defines")
    raise UnderdeterminedError(
        f"{n_eq} equations for {n_unk} unknowns: {n_unk - n_eq} equation(s) missing. Unknowns: "
        f"{(x_names + z_names)[:30]}. Components with variables: {detail}")


