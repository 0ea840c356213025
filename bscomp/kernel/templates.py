"""Component templates: the symbolic processing of one component class, done once (flattening step 2).

A Modelica tool instantiates each model's equations per component instance; here the equations of a
component *class* (with a given port layout, parameter shapes and configuration, see
:func:`template_key`) are built once with local CasADi symbols, and every instance calls the resulting
``Function`` with its own global symbols (inlined), so N identical components cost one symbolic pass,
not N.

While building a template, **explicit equations are solved locally** (:func:`eliminate_explicit`): an
equation affine in one unknown with a constant or parameter coefficient (``port.f - expr``,
``y - expr``, ``var - expr``) defines that unknown, which is substituted and never becomes a DAE
unknown -- the causalisation of trivially solvable equations a Modelica compiler does before tearing.
Port flows so defined enter the force balance of their coordinate (thesis Eq 3.44); flows a template
leaves undefined must be reactions of its ideal constraints (:mod:`bscomp.kernel.constraints`).
"""

from __future__ import annotations

import threading

import casadi as ca
import numpy as np

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import BUILDING, Constraint, _Context, _PortBinding
from bscomp.kernel.sharing import by_value, class_fingerprint, fingerprint, tracking_reads

__all__ = ["Template", "template_key", "shared_template", "clear_shared", "eliminate_explicit", "vc",
           "parameter_symbol"]


def vc(lst):
    """``vertcat`` of a list of SX, an empty column for an empty list."""
    return ca.vertcat(*lst) if lst else ca.SX(0, 1)


def parameter_symbol(name, value):
    """SX symbol shaped like a parameter value (scalar, vector as column, or matrix)."""
    shape = np.shape(value)
    return ca.SX.sym(name, *(shape if len(shape) == 2 else (shape[0], 1) if shape else (1, 1)))


def template_key(comp, ports, params, variables):
    """What decides whether two instances share a template: class, ports, parameter shapes, variables and
    the instance configuration that shapes equations/constraints beyond parameters (dof subsets,
    shape-function coefficients, attachment offsets: ``Component.template_key``)."""
    return (type(comp), tuple((n, s.kind.name, s.optional) for n, s in ports.items()),
            tuple((n, np.shape(comp._values[n])) for n in params), tuple(variables),
            getattr(comp, "template_key", lambda: None)())


#: Templates kept across flattenings in this process: (template key, parameter values or None) -> [Template]; at most
#: :data:`SHARED_MAX` keys, the least recently used dropped first.
_SHARED: dict = {}
SHARED_MAX = 512
_LOCK = threading.Lock()


def shared_template(key, comp, path, ports, params, variables):
    """``(template, built)``: the :class:`Template` of ``comp`` -- one built by an earlier flattening in this
    process for an instance of the same :func:`template_key` and the same values of what its equations read
    (instance attributes, :func:`~bscomp.kernel.sharing.fingerprint`; class attributes and methods,
    :func:`~bscomp.kernel.sharing.class_fingerprint`) -- and the same parameter values where the explicit-equation
    solving judged a coefficient at them (:func:`eliminate_explicit`), which is what a build from ``comp`` would
    give; else a new one, kept for later flattenings when those fingerprints hold values only. A repeated
    flattening of a drive -- a diagnose's candidate structures, a design sweep's variants -- then skips the
    symbolic pass (the FE test bed: 0.33 -> 0.13 s with :class:`ScrewNut`'s cached ``K_SN``)."""
    pv = tuple((n, np.asarray(comp._values[n], float).tobytes()) for n in params)
    for skey in ((key, None), (key, pv)):           # templates for any values, then those for these values
        with _LOCK:                                 # flattenings on threads (a thread-pool executor)
            variants = list(_SHARED.get(skey, ()))
        tpl = next((t for t in variants if t.matches(comp) and class_fingerprint(comp, t.reads) == t.class_fp),
                   None)
        if tpl is not None:
            with _LOCK:
                if skey in _SHARED:
                    _SHARED[skey] = _SHARED.pop(skey)   # the most recently used last
            return tpl, False
    tpl = Template(comp, path, ports, params, variables)
    tpl.class_fp = class_fingerprint(comp, tpl.reads)
    if by_value(tpl.read_fp) and by_value(tpl.class_fp):
        with _LOCK:
            _SHARED.setdefault((key, pv if tpl.uses_values else None), []).append(tpl)
            while len(_SHARED) > SHARED_MAX:
                _SHARED.pop(next(iter(_SHARED)))
    return tpl, True


def clear_shared() -> None:
    """Forget the templates kept across flattenings (:func:`shared_template`): after changing a module-level constant
    that a component's ``equations()`` read (attribute reads on the instance and its class are tracked; module
    globals are not)."""
    with _LOCK:
        _SHARED.clear()


def _batch_single_occurrence(remaining, usyms, U, deps):
    """Unknowns that occur in one equation only, with a constant non-zero coefficient, solved from it
    without touching any other equation (typically a port flow ``p.f - f(q) = 0``): one Jacobian and one
    substitution pass over the shared graph for all of them. Returns ``{equation: unknown}`` and the
    Jacobian."""
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
    return batch, J


def eliminate_explicit(eqs, unknowns, pvals, values_read=None):
    """Solve equations that are affine in one unknown with a constant (or parameter) coefficient.

    Returns (solutions {index: expr}, remaining equations, indices of equations used). A coefficient that depends on
    parameters is judged (non-zero, finite) at their values ``pvals[1]``; each time, ``True`` is appended to
    ``values_read`` (a list, if given): the result then depends on those values. Which equation
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
    batch, J = _batch_single_occurrence(remaining, usyms, U, deps)
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
                cnum = coef if coef.is_constant() else ca.substitute(coef, pvals[0], pvals[1])
                if values_read is not None and not coef.is_constant():
                    values_read.append(True)
                if not cnum.is_constant():   # depends on potentials or signals: not explicit
                    continue
                c = float(ca.evalf(cnum))
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


def _nonlinear(e, w) -> bool:
    """True if the Jacobian of the expressions ``e`` with respect to the unknowns ``w`` depends on them
    (friction, backlash, saturation, a moving contact); parameters alone do not count."""
    if e.numel() == 0 or w.numel() == 0:
        return False
    # the unknowns entering with order >= 2, by one dependency walk: no Jacobian of the Jacobian (that
    # one swells to minutes on a moving contact's shape-function equations, 294 equations x 882 unknowns)
    return any(ca.which_depends(e, w, 2, False))


def _as_list(value, method, path, comp) -> list:
    """What ``equations()`` / ``constraints()`` return, as a list (a tuple or one expression is accepted)."""
    if isinstance(value, list):
        return value
    if isinstance(value, tuple):
        return list(value)
    if isinstance(value, (ca.SX, ca.DM)):
        return [value]
    hint = " (a missing 'return'?)" if value is None else ""
    raise ModelDefinitionError(f"{method}() of component '{path}' ({type(comp).__name__}) must return a list of "
                               f"expressions, got {type(value).__name__}{hint}: e.g. return [self.flange.f - expr]")


def _as_sx(e, k, path, comp):
    """Equation ``k`` as SX, or an error naming it."""
    try:
        return ca.SX(e)
    except Exception as exc:
        raise ModelDefinitionError(
            f"equation {k} of component '{path}' ({type(comp).__name__}) is {type(e).__name__} {e!r}"[:300]
            + ": an equation is an expression of the component's ports, variables and parameters (CasADi SX, "
              "not MX) or a number") from exc


def _check_symbols(comp, path, allowed, ceqs, cons, obs) -> None:
    """Equations, constraints and observables may use only the component's own symbols (a ``ca.SX.sym``
    made in ``equations()`` or another component's symbol would be a free symbol of the template)."""
    exprs = list(ceqs) + [ca.SX(c.expr if isinstance(c, Constraint) else c) for c in cons]
    exprs += [ca.SX(e) for e in obs.values()]
    exprs = [e for e in exprs if e.nnz()]
    if not exprs:
        return
    known = {a.nz[j].element_hash() for a in allowed for j in range(a.nnz())}
    foreign = [x.name() for x in ca.symvar(ca.vertcat(*[ca.vec(e) for e in exprs])) if x.element_hash() not in known]
    if foreign:
        raise ModelDefinitionError(
            f"component '{path}' ({type(comp).__name__}) uses symbol(s) {foreign[:8]} that are not its own: "
            "equations, constraints and observables may use only the component's ports, variables and parameters "
            "(declare a Variable or Parameter, or connect another component through a port; never ca.SX.sym())")


def _check_constants(fun, comp, path) -> None:
    """A NaN or inf constant in a component's equations (``float('nan') * s``) is a bug, not a model."""
    for i in range(fun.n_instructions()):
        if fun.instruction_id(i) == ca.OP_CONST and not np.isfinite(fun.instruction_constant(i)):
            raise ModelDefinitionError(
                f"the equations of component '{path}' ({type(comp).__name__}) contain the constant "
                f"{fun.instruction_constant(i)}: NaN and inf are not physical coefficients; check the numbers "
                "its equations() compute (a division by zero, an uninitialised attribute)")


class Template:
    """Symbolic processing of one component class, done once and reused for every instance.

    The component's methods are called with local symbols; explicit equations are solved; the result
    is a CasADi Function ``fun`` of (q, q', q'', signals, p, vars, der(vars)) returning (flows, outputs,
    remaining equations, observables) that each instance calls with its own global symbols.

    Attributes
    ----------
    phys_ports, sig_ports : list of str
    var_names : list of str
    diff_vars, alg_unsolved : set of str
        Variables whose derivative appears (differential states), algebraic ones left unsolved.
    flow_status : list of str
        Per flow: ``"solved"`` (explicit), ``"constrained"`` (a constraint reaction) or ``"undefined"``.
    n_cons, cons_fun, cons_solve_for, cons_params
        Ideal constraints: count, ``p -> (A, b)`` of ``A q + b = 0``, preferred pivots, parameters read.
    """

    def __init__(self, comp, path, ports, params, variables):
        self.phys_ports = [n for n, s in ports.items() if not s.kind.is_signal]
        self.sig_ports = [n for n, s in ports.items() if s.kind.is_signal]
        ctx, psyms, q, qd, qdd, flows, sig, out_sig, vs, ds = self._bind(comp, ports, params, variables)
        ctx.path = path
        ceqs, cons, obs = self._call(comp, path, ctx)
        _check_symbols(comp, path, psyms + q + qd + qdd + flows + sig + vs + ds, ceqs, cons, obs)
        p_loc = vc(psyms)
        pv = np.concatenate([np.asarray(comp._values[n], float).reshape(-1, order="F") for n in params]) \
            if params else np.zeros(0)
        self.diff_vars = {n for n, d in zip(self.var_names, ds) if any(ca.depends_on(e, d) for e in ceqs)}
        alg = [n for n in self.var_names if n not in self.diff_vars]
        unknowns = flows + [sig[k] for k in out_sig] + [ctx.vars[n] for n in alg]
        forbid = vc([ctx.dvars[n] for n in self.var_names])
        values_read = []
        solved, remaining, used = eliminate_explicit(ceqs, unknowns, (p_loc, pv, forbid), values_read)
        self.uses_values = bool(values_read)      # the template holds for these parameter values only
        sub_from = [unknowns[i] for i in solved]
        sub_to = [solved[i] for i in solved]

        def _sub(e):
            if not sub_from:
                return e
            return ca.substitute(e, ca.vertcat(*sub_from), ca.densify(ca.vertcat(*sub_to)))

        con_q = self._constraints(comp, path, ctx, cons, p_loc, q, qd, qdd, vs, flows)
        fl_out = self._flows(comp, path, flows, solved, remaining, used, con_q)
        outs = self._outputs(comp, path, out_sig, len(flows), solved)
        self.alg_unsolved = {n for j, n in enumerate(alg) if len(flows) + len(out_sig) + j not in solved}
        self.rem_index = [k for k in range(len(remaining)) if k not in used]
        rem = [remaining[k] for k in self.rem_index]
        self.obs_names = list(self.var_names) + list(obs)
        obs_e = [_sub(v) for v in vs] + [_sub(ca.SX(e)) for e in obs.values()]
        obs_e = [e if e.numel() == 1 else e[0] for e in obs_e]
        self.fun = ca.Function(
            f"tpl_{type(comp).__name__}",
            [vc(q), vc(qd), vc(qdd), vc(sig), p_loc, vc(vs), vc(ds)],
            [vc(fl_out), vc(outs), vc(rem), vc(obs_e)])
        _check_constants(self.fun, comp, path)
        self.nonlinear = _nonlinear(ca.vertcat(vc(fl_out), vc(outs), vc(rem)),
                                    ca.vertcat(vc(q), vc(qd), vc(qdd), vc(sig), vc(vs), vc(ds)))

    def _bind(self, comp, ports, params, variables):
        """Local symbols for parameters, port potentials (and their derivatives), flows, signals and
        variables, bound to the component's names in a fresh context."""
        ctx = _Context()
        psyms = []
        for n in params:
            sym = parameter_symbol(n, comp._values[n])
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
            ctx.no_der += [(x, f"{x.name()} (a flow)") for x in fl] + [(x, x.name()) for x in pqdd]
        self.flow_port = flow_port
        sig = []
        out_sig = []
        for k, pname in enumerate(self.sig_ports):
            spec = ports[pname]
            s = ca.SX.sym(pname)
            sig.append(s)
            ctx.no_der.append((s, f"{pname} (a signal)"))
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
            ctx.no_der.append((d, d.name()))
        return ctx, psyms, q, qd, qdd, flows, sig, out_sig, vs, ds

    def _call(self, comp, path, ctx):
        """The component's equations (scalarised), constraints and observables, built in ``ctx``; records
        the instance attributes they read (``reads``, ``read_fp``: which instances may share this template)."""
        comp.__dict__["_ctx"] = ctx
        token = BUILDING.set((comp, path))
        try:
            with tracking_reads(comp) as reads:
                ceqs = _as_list(comp.connector_equations(), "connector_equations", path, comp) \
                    + _as_list(comp.equations(), "equations", path, comp)
                cons = _as_list(comp.constraints(), "constraints", path, comp)
                obs = comp.observables()
            ceqs = [_as_sx(e, k, path, comp) for k, e in enumerate(ceqs)]
        except ModelDefinitionError:
            raise
        except Exception as exc:  # a bug in a component file: say which one
            raise ModelDefinitionError(f"component '{path}' ({type(comp).__name__}) failed while building its "
                                       f"equations: {type(exc).__name__}: {exc}") from exc
        finally:
            BUILDING.reset(token)
            comp.__dict__["_ctx"] = None
        if not isinstance(obs, dict):
            raise ModelDefinitionError(f"observables() of component '{path}' ({type(comp).__name__}) must return a "
                                       f"dict {{name: expression}}, got {type(obs).__name__}")
        self.reads = frozenset(reads)
        self.read_fp = fingerprint(comp, self.reads)
        return [e[j] for e in ceqs for j in range(e.numel())], cons, obs

    def matches(self, comp) -> bool:
        """True if ``comp`` (same :func:`template_key`) holds the same values in the instance attributes this
        template's equations read, so it may reuse the template."""
        return fingerprint(comp, self.reads) == self.read_fp

    def _constraints(self, comp, path, ctx, cons, p_loc, q, qd, qdd, vs, flows):
        """Affine constraints ``A(p) q + b(p) = 0`` as a Function of the parameters (numeric coefficients
        are evaluated per instance). Returns the local potentials they involve."""
        cexprs, self.cons_solve_for = [], []
        q_index = {qq.element_hash(): i for i, qq in enumerate(q)}   # q are distinct scalar symbols
        for cexpr in cons:
            solve_for = None
            if isinstance(cexpr, Constraint):
                solve_for, cexpr = cexpr.solve_for, cexpr.expr
            cexpr = ca.SX(cexpr)
            sf = None
            if solve_for is not None:
                sfx = ca.SX(solve_for)
                sf = q_index.get(sfx.element_hash()) if sfx.is_scalar() and sfx.is_symbolic() else None
            for j in range(cexpr.numel()):
                cexprs.append(cexpr[j])
                self.cons_solve_for.append(sf)
        self.n_cons = len(cexprs)
        con_q = set()
        qv = vc(q)
        if cexprs:
            C = ca.vertcat(*cexprs)
            for o in [vc(qd), vc(qdd)] + vs + flows:
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
        return con_q

    def _flows(self, comp, path, flows, solved, remaining, used, con_q):
        """Classify each port flow (solved / constrained / undefined); returns the solved expressions."""
        self.flow_status, self.flow_pos = [], []
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
        return fl_out

    def _outputs(self, comp, path, out_sig, nflow, solved):
        """Signal outputs must be explicit (``port.y - expr``); returns their expressions."""
        outs = []
        self.out_sig_idx = []
        for j, k in enumerate(out_sig):
            if nflow + j not in solved:
                raise ModelDefinitionError(
                    f"component '{path}' ({type(comp).__name__}) does not define its output '{self.sig_ports[k]}' "
                    "explicitly; add an equation 'port.y - expr'")
            outs.append(solved[nflow + j])
            self.out_sig_idx.append(k)
        return outs
