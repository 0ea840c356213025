"""The flattened model: an implicit index-1 DAE ``F(x', x, z, u, p) = 0`` plus named outputs.

Mechanical structure is kept alongside (:class:`MechanicalInfo`): which DAE entries hold each reduced
coordinate's position, velocity and acceleration, the constraint map ``q = T q_r + t0`` and the
projected sparse structural matrices, so that linear analyses can use the second-order form directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import maximum_bipartite_matching

from bscomp.errors import (
    HighIndexError,
    SingularSystemError,
    UnderdeterminedError,
    UnknownNameError,
)
from bscomp.kernel.buffer_call import SparseCall

__all__ = ["Dae", "MechanicalInfo"]


@dataclass
class MechanicalInfo:
    """Second-order structure of the DAE.

    Attributes
    ----------
    coordinate_names : list of str
        Reduced (independent) coordinates ``q_r`` after alias and constraint elimination.
    T, t0 : sparse matrix, array
        All coordinates ``q = T q_r + t0``.
    inertial, damped, static : list of int
        Reduced coordinates with inertia (states q, v), with damping only (state q) and quasi-static
        (algebraic q).
    q_in_x, q_in_z, v_in_x, v_in_xd, a_in_xd : dict
        Reduced coordinate -> index of its position / velocity / acceleration in x, z or x'.
    balance_rows : list of int
        Rows of F holding the projected force balances ``T^T Q = 0``.
    M, C, K : sparse matrices
        Projected structural blocks (the scalar-equation part is added by differentiation).
    port_coordinates : dict
        ``"component.port.potential"`` -> index into ``full_coordinate_names`` (row of ``T``).
    """

    coordinate_names: list
    coordinate_units: list
    full_coordinate_names: list
    T: Any
    t0: Any
    inertial: list
    damped: list
    static: list
    q_in_x: dict
    q_in_z: dict
    v_in_x: dict
    v_in_xd: dict
    a_in_xd: dict
    balance_rows: list
    M: Any
    C: Any
    K: Any
    Kt0: Any
    has_internal_states: bool = False
    port_coordinates: dict = field(default_factory=dict)


@dataclass
class Dae:
    """Implicit DAE ``F(x', x, z, u, p) = 0`` with outputs ``y = g(x', x, z, u, p)``.

    Attributes
    ----------
    x_names, z_names, u_names, p_names : list of str
        Hierarchical names of differential states, algebraic variables, inputs and parameters.
    p0 : ndarray
        Parameter values.
    x0, xd0, z0 : ndarray
        Consistent initial values (computed by :meth:`initialize`).
    structural_parameters : list of str
        Parameters baked into matrices (constraint coefficients, FE blocks); changing one re-flattens.
    nonlinear_components : list of str
        ``"path (Class)"`` of the components whose own equations are nonlinear in their unknowns (friction,
        backlash, saturation...), recorded by flattening; a linear analysis names them when it linearizes.
    """

    name: str
    xs: Any
    xds: Any
    zs: Any
    us: Any
    ps: Any
    F_sx: Any
    mech: MechanicalInfo
    x_names: list
    z_names: list
    u_names: list
    u_units: list
    p_names: list
    p_units: list
    p0: np.ndarray
    x_start: np.ndarray
    z_start: np.ndarray
    eq_origin: list
    observables: dict
    substitutions: tuple
    structural_parameters: list
    system: Any = None
    nonlinear_components: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    x0: Any = None
    xd0: Any = None
    z0: Any = None
    _cache: dict = field(default_factory=dict, repr=False)

    # ---- sizes --------------------------------------------------------------------------------
    @property
    def nx(self):
        return self.xs.numel()

    @property
    def nz(self):
        return self.zs.numel()

    @property
    def nu(self):
        return self.us.numel()

    @property
    def np(self):
        return self.ps.numel()

    def __repr__(self):
        return (f"<Dae {self.name}: {self.nx} states, {self.nz} algebraic, {self.nu} inputs {self.u_names}, "
                f"{self.np} parameters>")

    # ---- functions ----------------------------------------------------------------------------
    def _mx(self):
        if "mx" not in self._cache:
            xd = ca.MX.sym("xd", self.nx)
            x = ca.MX.sym("x", self.nx)
            z = ca.MX.sym("z", self.nz)
            u = ca.MX.sym("u", self.nu)
            p = ca.MX.sym("p", self.np)
            self._cache["mx"] = (xd, x, z, u, p)
        return self._cache["mx"]

    def _structural_maps(self):
        """Sparse maps of the structural (matrix-form) part ``P (M a + C v + K q + K t0)``.

        ``q = Sq_x x + Sq_z z``, ``v = Sv_x x + Sv_xd xd``, ``a = Sa_xd xd``, ``P`` places the balance rows.
        Returns ``(Sq_x, Sq_z, Sv_x, Sv_xd, Sa_xd, P)`` as scipy csr matrices, or None without structure.
        """
        m = self.mech
        nr = len(m.coordinate_names)
        if not (nr and (m.M.nnz or m.C.nnz or m.K.nnz)):
            return None

        def sel(where, n):
            rows = list(where.keys())
            return sp.csr_matrix((np.ones(len(rows)), (rows, [where[r] for r in rows])), shape=(nr, n))

        nF = self.F_sx.numel()
        P = sp.csr_matrix((np.ones(nr), (m.balance_rows, np.arange(nr))), shape=(nF, nr))
        return (sel(m.q_in_x, self.nx), sel(m.q_in_z, self.nz), sel(m.v_in_x, self.nx), sel(m.v_in_xd, self.nx),
                sel(m.a_in_xd, self.nx), P)

    def _structural_jacobians(self):
        """Constant Jacobians ``(d/dxd, d/dx, d/dz)`` of the structural part (scipy csr), or None."""
        maps = self._structural_maps()
        if maps is None:
            return None
        Sqx, Sqz, Svx, Svxd, Saxd, P = maps
        m = self.mech
        M, C, K = sp.csr_matrix(m.M), sp.csr_matrix(m.C), sp.csr_matrix(m.K)
        return (P @ (M @ Saxd + C @ Svxd)).tocsr(), (P @ (C @ Svx + K @ Sqx)).tocsr(), (P @ (K @ Sqz)).tocsr()

    @property
    def F(self) -> ca.Function:
        """Residual function ``F(xd, x, z, u, p)`` (CasADi), structural blocks as sparse products."""
        if "F" not in self._cache:
            xd, x, z, u, p = self._mx()
            fsx = ca.Function("F_scalar", [self.xds, self.xs, self.zs, self.us, self.ps], [self.F_sx])
            res = fsx(xd, x, z, u, p)
            maps = self._structural_maps()
            if maps is not None:
                Sqx, Sqz, Svx, Svxd, Saxd, P = (dm_sparse(A) for A in maps)
                m = self.mech
                q = ca.mtimes(Sqx, x) + ca.mtimes(Sqz, z)
                v = ca.mtimes(Svx, x) + ca.mtimes(Svxd, xd)
                f = ca.mtimes(dm_sparse(m.M), ca.mtimes(Saxd, xd)) + ca.mtimes(dm_sparse(m.C), v) \
                    + ca.mtimes(dm_sparse(m.K), q) + ca.DM(m.Kt0)
                res = res + ca.mtimes(P, f)
            self._cache["F"] = ca.Function("F", [xd, x, z, u, p], [res], ["xd", "x", "z", "u", "p"], ["res"])
        return self._cache["F"]

    def _scalar_jacobian(self) -> ca.Function:
        """``dF_scalar/d[xd, x, z, u]`` of the scalar (component-equation) part, one SX pass, built once.

        It does not depend on the structural matrices, so it survives a change of ``mech.C`` (system damping).
        """
        if "jac_sx" not in self._cache:
            w = ca.vertcat(self.xds, self.xs, self.zs, self.us)
            self._cache["jac_sx"] = ca.Function("F_scalar_jac", [self.xds, self.xs, self.zs, self.us, self.ps],
                                                [ca.jacobian(self.F_sx, w)])
        return self._cache["jac_sx"]

    @property
    def jacobians(self) -> ca.Function:
        """``(xd, x, z, u, p) -> (F, dF/dxd, dF/dx, dF/dz, dF/du)``, sparse, built once.

        The scalar part's Jacobian comes from one SX pass (:meth:`_scalar_jacobian`), the structural
        part's is the constant ``P M Sa``, ``P C Sv``, ``P K Sq`` -- no MX differentiation of the
        composed residual.
        """
        if "jac" not in self._cache:
            xd, x, z, u, p = self._mx()
            res = self.F(xd, x, z, u, p)
            J = self._scalar_jacobian()(xd, x, z, u, p)
            nx, nz, nu = self.nx, self.nz, self.nu
            Jxd, Jx, Jz, Ju = ca.horzsplit(J, [0, nx, 2 * nx, 2 * nx + nz, 2 * nx + nz + nu])
            sj = self._structural_jacobians()
            if sj is not None:
                Jxd, Jx, Jz = (Jb + dm_sparse(S) for Jb, S in zip((Jxd, Jx, Jz), sj, strict=True))
            self._cache["jac"] = ca.Function("F_jac", [xd, x, z, u, p], [res, Jxd, Jx, Jz, Ju])
        return self._cache["jac"]

    def jacobians_at(self, xd, x, z, u, p):
        """:attr:`jacobians` at numeric values: ``(F (n,) ndarray, dF/dxd, dF/dx, dF/dz, dF/du)`` as scipy csc with
        the structural pattern, evaluated through the Function's buffer (:class:`~bscomp.kernel.buffer_call.
        SparseCall`: bit for bit the numbers of ``jacobians(...)``, without the DM round trip that cost the 6-DOF
        test bed 20 of its 30 ms)."""
        call = self._cache.get("jac_call")
        if call is None:
            call = self._cache["jac_call"] = SparseCall(self.jacobians, arrays=(0,))
        return tuple(call(xd, x, z, u, p))

    def jacobian_pattern(self, wrt: str) -> sp.csr_matrix:
        """Structural sparsity (0/1 csr) of ``dF/d(wrt)`` for ``wrt`` in ``"xd"``, ``"x"``, ``"z"``, ``"xd,z"``."""
        parts = wrt.split(",")
        syms = {"xd": self.xds, "x": self.xs, "z": self.zs}
        sj = self._structural_jacobians()
        blocks = []
        for name in parts:
            spx = ca.jacobian_sparsity(self.F_sx, syms[name])
            r, c = spx.get_triplet()
            A = sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(spx.size1(), spx.size2()))
            if sj is not None:
                S = sj[("xd", "x", "z").index(name)]
                A = A + abs(S).sign()
            blocks.append(A)
        A = sp.hstack(blocks).tocsr()
        A.data[:] = 1.0
        return A

    # ---- outputs ------------------------------------------------------------------------------
    def output_names(self):
        """All names usable as outputs."""
        return list(self.observables)

    def _near_outputs(self, name: str) -> str:
        """What to say about an unknown output: the outputs of its component, else the closest names."""
        import difflib

        comp = name.rpartition(".")[0]
        own = [k for k in self.observables if k.rpartition(".")[0] == comp and k not in self.p_names][:15]
        if comp and own:
            return f"outputs of '{comp}': {own}"
        close = difflib.get_close_matches(name, list(self.observables), n=5, cutoff=0.5)
        comps = sorted({k.split(".")[0] for k in self.observables if not k.startswith("der(")})
        return (f"no component '{comp}' has outputs" if comp else "an output is 'component.name'") + \
            (f"; closest: {close}" if close else f"; components: {comps[:20]}")

    def output_expr(self, names):
        """SX expressions of named outputs in terms of (xd, x, z, u, p)."""
        exprs = []
        for n in names:
            if n not in self.observables:
                raise UnknownNameError(f"no output named '{n}' in '{self.name}'; {self._near_outputs(n)}")
            exprs.append(self.observables[n])
        e = ca.vertcat(*exprs) if exprs else ca.SX(0, 1)
        subs = self._cache.get("output_substitutions")
        if subs is None:         # the substitution lists as vectors, once (vertcat of long lists is not free)
            subs = self._cache["output_substitutions"] = [(ca.vertcat(*sf), ca.densify(ca.vertcat(*st)))
                                                          for sf, st in self.substitutions if sf]
        for sf, st in subs:
            e = ca.substitute(e, sf, st)
        known = self._cache.get("known_symbols")
        if known is None:
            known = self._cache["known_symbols"] = {s.name() for s in ca.symvar(ca.vertcat(self.xs, self.xds, self.zs,
                                                                                          self.us, self.ps))}
        bad = [s.name() for s in ca.symvar(e) if s.name() not in known]
        if bad:
            raise UnknownNameError(f"outputs {list(names)} use {bad}, which are not available (the derivative of "
                                   "a quasi-static coordinate or a removed variable)")
        return e

    def is_signal(self, name: str) -> bool:
        """True if the output ``name`` depends on a state, a state derivative, an algebraic variable or an input;
        False for a parameter or a constant (cached per name). Raises :class:`UnknownNameError` for a name
        that is not an output."""
        key = ("is_signal", name)
        if key not in self._cache:
            signals = self._cache.get("signal_symbols")
            if signals is None:
                signals = self._cache["signal_symbols"] = ca.vertcat(self.xds, self.xs, self.zs, self.us)
            self._cache[key] = bool(ca.depends_on(self.output_expr([name]), signals))
        return self._cache[key]

    def require_signals(self, names, who: str = "") -> list:
        """``names`` (one name or a list) as a list of outputs that are signals, the check every response
        analysis (FRFs, sweeps, optimal-control outputs) makes on the outputs it is given.

        A parameter or a constant (``"rotor.J"``, a fixed flange's position) is an observable of the model, but
        its response to any input is 0 at every frequency: asking for it is a mistake, never a silent 0.

        Parameters
        ----------
        names : str or list of str
            Output names.
        who : str
            The calling function, put in front of the messages (``"frf"``, ``"stepped_sine"``...).

        Raises
        ------
        UnknownNameError
            A name that is not an output (with the outputs of its component or the closest names), or one that
            is a parameter or a constant (with the signals of its component).
        """
        pre = f"{who}: " if who else ""
        names = [names] if isinstance(names, str) else list(names)
        for name in names:
            if not isinstance(name, str):
                raise UnknownNameError(f"{pre}an output is a name (str) such as 'table.a', got {name!r}")
            if name not in self.observables:
                raise UnknownNameError(f"{pre}no output named '{name}' in '{self.name}'; {self._near_outputs(name)}")
            if self.is_signal(name):
                continue
            comp = name.rpartition(".")[0]
            others = [k for k in self.observables if k.rpartition(".")[0] == comp and k not in self.p_names
                      and self.is_signal(k)]
            what = "a parameter" if name in self.p_names else "a constant"
            raise UnknownNameError(
                f"{pre}output '{name}' of '{self.name}' is {what}, not a signal (it depends on no state or input, so "
                f"its response to any input is zero); " + (f"outputs of '{comp}': {others[:15]}" if others else
                                                             f"'{comp}' has no signal outputs"),
                hint="give a signal as the output, e.g. " + (repr(others[0]) if others else
                                                              "a position, velocity or force"))
        return names

    def output_function(self, names) -> ca.Function:
        """CasADi Function ``(xd, x, z, u, p) -> y`` for the named outputs."""
        key = ("out", tuple(names))
        if key not in self._cache:
            e = self.output_expr(names)
            self._cache[key] = ca.Function("y", [self.xds, self.xs, self.zs, self.us, self.ps], [e])
        return self._cache[key]

    # ---- parameters ---------------------------------------------------------------------------
    def parameter_vector(self, params: dict | None = None) -> np.ndarray:
        """Parameter vector ``p0`` with overrides by name; structural parameters cannot be changed here.

        Each override is checked against its parameter's bounds (and a ``"<number> <unit>"`` string is
        converted to the declared unit, :meth:`bscomp.Parameter.validate`); then every component with an
        override gets its cross-parameter conditions checked (:meth:`bscomp.Component.check`) on the run's
        values of all its parameters, so ``params={"sat.y_min": 5.0}`` with ``y_max = 1`` raises a
        :class:`~bscomp.errors.ParameterError` as ``system.set`` would.
        """
        p = self.p0.copy()
        touched = {}
        for k, v in (params or {}).items():
            if k in self.structural_parameters:
                raise UnknownNameError(
                    f"parameter '{k}' is structural in '{self.name}' (baked into constraint or FE matrices): change "
                    "it on the system (system.set) and flatten again, or pass the System to the analysis")
            if k not in self.p_names:
                raise UnknownNameError(f"'{self.name}' has no parameter '{k}'")
            idx = self.p_names.index(k)
            if self.system is not None:
                path, _, pname = k.rpartition(".")
                comp = self.system.component(path)
                v = comp.parameters()[pname.partition("[")[0]].validate(v, comp)
                touched[path] = comp
            p[idx] = float(v)
        for path, comp in touched.items():
            comp.check(self._component_values(path, comp, p))
        return p

    def _component_values(self, path: str, comp, p: np.ndarray) -> dict:
        """``{parameter: value}`` of one component in the parameter vector ``p`` (vector and matrix
        parameters reassembled from their ``name[j]`` entries, column-major as flattening stacks them)."""
        index = self._cache.get("p_index")
        if index is None:
            index = self._cache["p_index"] = {n: i for i, n in enumerate(self.p_names)}
        out = dict(comp._values)
        for n in comp.parameters():
            full = f"{path}.{n}"
            if full in index:
                out[n] = float(p[index[full]])
            elif f"{full}[0]" in index:
                entries, j = [], 0
                while f"{full}[{j}]" in index:
                    entries.append(p[index[f"{full}[{j}]"]])
                    j += 1
                arr, shape = np.asarray(entries, float), np.shape(out[n])
                out[n] = arr.reshape(shape, order="F") if int(np.prod(shape)) == arr.size else arr
        return out

    # ---- initial values -----------------------------------------------------------------------
    def initialize(self, x0=None, u0=None, p=None, z_guess=None, tol=1e-10, max_iter=20, xd_guess=None,
                   store=True):
        """Consistent initial values: given x0, solve ``F(xd, x0, z, u0, p) = 0`` for (xd, z) by Newton.

        Returns
        -------
        xd0, z0 : ndarray
        """
        x0 = self.x_start if x0 is None else np.asarray(x0, float)
        u0 = np.zeros(self.nu) if u0 is None else np.asarray(u0, float)
        p = self.p0 if p is None else np.asarray(p, float)
        z = (self.z_start if z_guess is None else np.asarray(z_guess, float)).copy()
        xd = np.zeros(self.nx) if xd_guess is None else np.asarray(xd_guess, float).copy()
        for it in range(max_iter):
            r, Jxd, _, Jz, _ = self.jacobians_at(xd, x0, z, u0, p)
            if np.linalg.norm(r, np.inf) < tol * (1 + np.linalg.norm(xd, np.inf)) and it > 0:
                break
            W = sp.hstack([Jxd, Jz]).tocsc()
            try:
                lu = spla.splu(W)
            except RuntimeError as exc:
                raise SingularSystemError(self._singular_message(W)) from exc
            step = lu.solve(-r)
            if not np.all(np.isfinite(step)):
                raise SingularSystemError(self._singular_message(W))
            xd = xd + step[: self.nx]
            z = z + step[self.nx:]
            if np.linalg.norm(step, np.inf) < tol * (1 + np.linalg.norm(np.r_[xd, z], np.inf)):
                break
        if store:
            self.x0, self.xd0, self.z0 = x0, xd, z
        return xd, z

    def _singular_message(self, W):
        W = W.toarray() if W.shape[0] <= 3000 else None
        names = [f"der({n})" if not n.startswith("der(") else f"der({n})" for n in self.x_names] + self.z_names
        if W is None:
            return f"'{self.name}': the index-1 Jacobian [dF/dx', dF/dz] is numerically singular"
        u, s, vt = np.linalg.svd(W)
        null = vt[-1]
        big = np.argsort(-np.abs(null))[:6]
        involved = [names[i].replace("der(der(", "acceleration of ").replace("der(", "rate of ").rstrip(")")
                    for i in big if abs(null[i]) > 1e-3]
        return (f"'{self.name}': the Jacobian [dF/dx', dF/dz] is numerically singular (smallest singular value "
                f"{s[-1]:.2e}); the unknowns involved: {involved}. Typically a mechanism without mass or stiffness "
                "in some direction (add a mass, a spring to ground, or a Fixed) or a zero parameter")

    # ---- checks -------------------------------------------------------------------------------
    def check_index1(self):
        """Structural (matching) and numeric check that ``[dF/dx', dF/dz]`` is non-singular."""
        A = self.jacobian_pattern("xd,z")
        n = A.shape[0]
        match = maximum_bipartite_matching(A, perm_type="column")
        unmatched_rows = [i for i in range(n) if match[i] < 0]
        if unmatched_rows:
            empty = [i for i in unmatched_rows if A.indptr[i + 1] == A.indptr[i]]
            if empty:
                names = [self.eq_origin[i] for i in empty[:10]]
                states = self._states_in_rows(empty[:10])
                raise HighIndexError(
                    f"'{self.name}': {len(empty)} equation(s) constrain differential states only, so the DAE has "
                    f"index > 1: {names}, acting on {states}. If this is a rigid joint between inertias, declare it "
                    "in the component's constraints() so it is eliminated (ideal constraint), or replace it with a "
                    "compliance (Spring/TorsionalSpring)")
            names = [self.eq_origin[i] for i in unmatched_rows[:10]]
            matched_cols = set(int(c) for c in match if c >= 0)
            allnames = [f"der({n})" for n in self.x_names] + self.z_names
            free = [allnames[j] for j in range(A.shape[1]) if j not in matched_cols][:10]
            raise UnderdeterminedError(
                f"'{self.name}' is structurally singular: equations {names} cannot be matched to unknowns; "
                f"unknowns left undetermined: {free}. A coordinate may have no mass, spring or damper acting on it "
                "(connect it or fix it), or a component gives too few equations")
        self.initialize()
        return True

    def _states_in_rows(self, rows):
        r, c = self.jacobian_pattern("x").nonzero()
        out = sorted({self.x_names[cc] for rr, cc in zip(r, c) if rr in rows})
        return out


def dm_sparse(A) -> ca.DM:
    """scipy sparse (or dense) matrix -> CasADi DM with the same sparsity, built from the CSC arrays
    (``ca.DM(scipy_matrix)`` converts entry by entry, ~10x slower for a few-hundred-row matrix)."""
    A = sp.csc_matrix(A)
    A.sort_indices()
    return ca.DM(ca.Sparsity(A.shape[0], A.shape[1], A.indptr.tolist(), A.indices.tolist()), A.data.tolist())


def _sp(m):
    """CasADi DM (sparse) -> scipy csc, from its CCS arrays (``DM.sparse()`` costs ~1 ms for a few-hundred-row
    Jacobian)."""
    m = ca.DM(m)
    if m.numel() == 0:
        return sp.csc_matrix(m.shape)
    colind, row = m.sparsity().get_ccs()
    return sp.csc_matrix((np.asarray(m.nonzeros(), float), np.asarray(row, np.int32), np.asarray(colind, np.int32)),
                         shape=m.shape)


def _dm_to_csc(m):
    spy = m.sparsity()
    r, c = spy.get_triplet()
    return sp.csc_matrix((np.array(m.nonzeros()), (r, c)), shape=m.shape)
