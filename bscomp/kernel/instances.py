"""Component instances: each leaf calls its class template with its own global symbols (flattening step 2).

What every instance contributes is collected in one :class:`Assembly`: its parameters (global symbols
``path.name`` and values), the explicit flows of its ports per coordinate (summed to the generalised
force balance ``Q`` of each connection set, Modelica's zero-sum flow equation), its outputs (signal
definitions), its internal variables (differential or algebraic), its remaining equations, its
observables, the numeric coefficients of its ideal constraints and its linear structural block
(``LinearStructure``: sparse ``M, C, K`` on port potentials, thesis Eq 3.44, placed by a DOF->coordinate
map instead of being written as scalar equations).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from bscomp.errors import ModelDefinitionError, PortConnectionError
from bscomp.kernel.templates import parameter_symbol, shared_template, template_key, vc

__all__ = ["Assembly"]


def _block(struct, path, comp, port_coords):
    """``(coordinate indices, M, C, K)`` of a component's ``structure()``, its DOF names checked."""
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


class Assembly:
    """What the instances of a system contribute, in declaration order.

    Parameters
    ----------
    sets : ConnectionSets
    q_full, qd_full, qdd_full : list of SX
        Position, velocity and acceleration symbol of every coordinate.
    sig_syms : list of SX
        One symbol per signal.
    """

    def __init__(self, sets, q_full, qd_full, qdd_full, sig_syms):
        self.sets = sets
        self.q_full, self.qd_full, self.qdd_full, self.sig_syms = q_full, qd_full, qdd_full, sig_syms
        self.p_syms, self.p_vals, self.p_names, self.p_units = [], [], [], []
        self.Q = [[] for _ in range(len(q_full))]  # explicit flow contributions per coordinate
        self.eqs, self.eq_origin = [], []          # global residual equations (internal)
        self.xint, self.xint_d, self.xint_names, self.xint_start = [], [], [], []
        self.zint, self.zint_names, self.zint_start = [], [], []
        self.sig_def = {}                          # signal index -> expression
        self.sig_source = {}                       # signal index -> the output port that defines it
        self.constraints = []                      # (coeff dict, const, solve_for coord, origin)
        self.observables = {}
        self.blocks = []                           # (coord indices, M, C, K)
        self.structural = set()
        self.templates = {}                        # template_key -> [Template] (see bscomp.kernel.sharing)
        self.templates_built = 0                   # of those, built here (the others kept from an earlier flatten)
        self.nonlinear = []                        # "path (Class)" of the components with nonlinear equations

    def add(self, lf):
        """Instantiate one leaf component."""
        comp, path = lf.comp, lf.path
        ports = comp.ports()
        params = comp.parameters()
        variables = comp.variables()
        # one template per class layout and per value of the instance attributes its equations read
        key = template_key(comp, ports, params, variables)
        variants = self.templates.setdefault(key, [])
        tpl = next((t for t in variants if t.matches(comp)), None)
        if tpl is None:
            tpl, built = shared_template(key, comp, path, ports, params, variables)
            self.templates_built += built
            variants.append(tpl)
        # numeric/structural parts are per instance
        comp.__dict__["_read_params"] = set()
        struct = comp.structure()
        read_struct = set(comp.__dict__.pop("_read_params", set()))
        block = _block(struct, path, comp, {p: [self.sets.coordinate(path, p, i)
                                                for i in range(len(sp_.kind.potentials))]
                                            for p, sp_ in ports.items() if not sp_.kind.is_signal}) \
            if struct is not None else None
        struct_coords = set(block[0]) if block is not None else set()  # flows given by M q'' + C q' + K q
        psym, loc_pv = self._parameters(path, params, comp)
        port_coords = {pname: [self.sets.coordinate(path, pname, i) for i in range(len(ports[pname].kind.potentials))]
                       for pname in tpl.phys_ports}
        cidx = [c for pname in tpl.phys_ports for c in port_coords[pname]]
        sidx = [self.sets.signal(path, pname) for pname in tpl.sig_ports]
        vsym = [ca.SX.sym(f"{path}.{n}") for n in tpl.var_names]
        dsym = [ca.SX.sym(f"der({path}.{n})") for n in tpl.var_names]
        out = tpl.fun(vc([self.q_full[c] for c in cidx]), vc([self.qd_full[c] for c in cidx]),
                      vc([self.qdd_full[c] for c in cidx]), vc([self.sig_syms[k] for k in sidx]),
                      vc([ca.vec(s) for s in psym]), vc(vsym), vc(dsym))
        flows_e, outs_e, rem_e, obs_e = out
        if tpl.nonlinear:
            self.nonlinear.append(f"{path} ({type(comp).__name__})")
        self._flows(tpl, path, comp, ports, cidx, struct_coords, flows_e)
        for j, k in enumerate(tpl.out_sig_idx):
            if sidx[k] in self.sig_def:        # a second output on one signal would silently replace the first
                into = [f"{a}.{b}" for a, b, _ in self.sets.sig_inputs[sidx[k]]]
                raise PortConnectionError(f"two outputs '{self.sig_source[sidx[k]]}' and '{path}.{tpl.sig_ports[k]}' "
                                          f"drive one signal (into {into}): a signal has one source; disconnect one")
            self.sig_def[sidx[k]] = outs_e[j]
            self.sig_source[sidx[k]] = f"{path}.{tpl.sig_ports[k]}"
        self._variables(tpl, path, variables, vsym, dsym)
        for j, k in enumerate(tpl.rem_index):
            self.eqs.append(rem_e[j])
            self.eq_origin.append(f"equation {k} of component '{path}' ({type(comp).__name__})")
        self._observables(tpl, path, ports, params, port_coords, sidx, psym, obs_e)
        if tpl.n_cons:
            self._constraints(tpl, path, comp, cidx, loc_pv)
        if struct is not None:
            self.structural.update(f"{path}.{n}" for n in read_struct)
            self.blocks.append(block)

    def _parameters(self, path, params, comp):
        """Global parameter symbols ``path.name`` of an instance; returns them and the local value vector."""
        pv = [np.asarray(comp._values[n], dtype=float) for n in params]
        psym = []
        for (n, p), vv in zip(params.items(), pv):
            sym = parameter_symbol(f"{path}.{n}", vv)
            psym.append(sym)
            self.p_syms.append(ca.vec(sym))
            self.p_vals.append(vv.reshape(-1, order="F"))
            cnt = int(vv.size)
            self.p_names.extend([f"{path}.{n}"] if cnt == 1 else [f"{path}.{n}[{j}]" for j in range(cnt)])
            self.p_units.extend([p.unit] * cnt)
        loc_pv = np.concatenate([v.reshape(-1, order="F") for v in pv]) if pv else np.zeros(0)
        return psym, loc_pv

    def _flows(self, tpl, path, comp, ports, cidx, struct_coords, flows_e):
        """Explicit port flows into the balance of their coordinate; an undefined flow is an error unless
        it is a constraint reaction, given by a structural block, or on an unconnected optional port."""
        for j, c in enumerate(cidx):
            st = tpl.flow_status[j]
            if st == "solved":
                self.Q[c].append(flows_e[tpl.flow_pos[j]])
            elif st == "constrained" or c in struct_coords:
                pass
            else:  # undefined: fine only for an unconnected optional port
                pname = tpl.flow_port[j]
                if not (ports[pname].optional and (path, pname) not in self.sets.connected):
                    raise ModelDefinitionError(
                        f"component '{path}' ({type(comp).__name__}) does not define the flow of port '{pname}': "
                        "give an equation 'port.f - expr', or a constraint on its potential (ideal joint)")

    def _variables(self, tpl, path, variables, vsym, dsym):
        """Internal variables: unsolved algebraic ones and differential ones become DAE unknowns."""
        for j, n in enumerate(tpl.var_names):
            if n in tpl.alg_unsolved:
                self.zint.append(vsym[j])
                self.zint_names.append(f"{path}.{n}")
                self.zint_start.append(variables[n].start)
            elif n in tpl.diff_vars:
                self.xint.append(vsym[j])
                self.xint_d.append(dsym[j])
                self.xint_names.append(f"{path}.{n}")
                self.xint_start.append(variables[n].start)

    def _observables(self, tpl, path, ports, params, port_coords, sidx, psym, obs_e):
        """Variables, declared observables, port potentials, signals and parameters by hierarchical name."""
        for j, n in enumerate(tpl.obs_names):
            self.observables[f"{path}.{n}"] = obs_e[j]
        for pname, idx in port_coords.items():
            for (pot, _), c in zip(ports[pname].kind.potentials, idx):
                self.observables[f"{path}.{pname}.{pot}"] = self.q_full[c]
        for pname, k in zip(tpl.sig_ports, sidx):
            self.observables[f"{path}.{pname}"] = self.sig_syms[k]
        for n, s in zip(params, psym):
            self.observables[f"{path}.{n}"] = s

    def _constraints(self, tpl, path, comp, cidx, loc_pv):
        """Numeric constraint rows ``{coordinate: coefficient}, b`` of an instance."""
        J, b = tpl.cons_fun(loc_pv)
        J = np.asarray(J, float).reshape(tpl.n_cons, len(cidx))
        b = np.asarray(b, float).ravel()
        if not (np.all(np.isfinite(J)) and np.all(np.isfinite(b))):
            raise ModelDefinitionError(f"the constraints of '{path}' ({type(comp).__name__}) have NaN or inf "
                                       "coefficients: check the numbers its constraints() compute")
        for r in range(tpl.n_cons):
            coeffs = {}
            for j, a in enumerate(J[r]):
                if a != 0.0:
                    coeffs[cidx[j]] = coeffs.get(cidx[j], 0.0) + float(a)
            sf = tpl.cons_solve_for[r]
            self.constraints.append((coeffs, float(b[r]), cidx[sf] if sf is not None else None,
                                     f"constraint of '{path}' ({type(comp).__name__})"))
        self.structural.update(f"{path}.{n}" for n in tpl.cons_params)

    def parameters(self):
        """``(p, p0)``: all parameter symbols stacked, and their values."""
        p_all = ca.vertcat(*self.p_syms) if self.p_syms else ca.SX(0, 1)
        p0 = np.concatenate(self.p_vals) if self.p_vals else np.zeros(0)
        return p_all, p0
